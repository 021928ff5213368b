//! The settings store at boot: the board's store handed to the command service, what is
//! stored and valid applied, one log line per record. The motor boots disabled whatever
//! is stored (the servo starts disabled; nothing here enables it).

use rtic::Mutex;
use service::store::Storage;
use service::{Actuator, Service};

/// The actuator before RTIC shares it: `lock` is plain access (init runs alone).
struct Alone<'a>(&'a mut Actuator);

impl Mutex for Alone<'_> {
    type T = Actuator;
    fn lock<R>(&mut self, f: impl FnOnce(&mut Actuator) -> R) -> R {
        f(self.0)
    }
}

/// Attaches `storage` (if the board has one for this run) to `service`, applies the stored
/// records if `apply` (not in a scripted scenario, which sets its own configuration), and
/// logs what became of each record.
// Not inlined: loading and preparing the stored settings needs frames init need not keep.
#[inline(never)]
pub fn boot(
    service: &mut Service,
    actuator: &mut Actuator,
    storage: Option<&'static mut (dyn Storage + Send)>,
    apply: bool,
) {
    let Some(storage) = storage else {
        return;
    };
    let (report, faults) = service.attach_store(storage, &mut Alone(actuator), apply);
    match report.generation {
        Some(g) => defmt::info!("store: record set generation {=u32}", g),
        None => defmt::info!("store: no record set stored"),
    }
    for (record, outcome) in report.lines() {
        defmt::info!(
            "store: {=str}: {}{=str}",
            record,
            defmt::Display2Format(&outcome),
            if apply || record == "faults" {
                ""
            } else {
                " (not applied: the scenario sets its own)"
            }
        );
    }
    if let Some(last) = faults.latest() {
        defmt::info!(
            "store: fault log: {=usize} entries, latest #{=u32} {=str} value {=i32} at {=u32} ms",
            faults.len(),
            last.seq,
            last.fault.code.name(),
            last.fault.value,
            last.fault.tick
        );
    }
}
