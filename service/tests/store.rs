//! The settings store through the protocol, on the host: a RAM flash shared between two
//! "boots" of a service, as the emulated boards keep it in a host file.

use std::sync::{Arc, Mutex, MutexGuard};

use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use model::control::Config;
use model::servo::Servo;
use model::supervisor::SupervisorConfig;
use model::{Design, Length};
use protocol::{ErrorCode, FaultCode, Frame, Handler, LoggedFault, Reply, Request, State, Status};
use service::{Actuator, Service};
use store::{
    BusSettings, Clutch, Outcome, RamFlash, RangeChecks, RecordSet, Rejection, Report, Store, PAGES,
};

mod common;
use common::Cell;

/// One flash, shared by the test and the store it lent to a service.
#[derive(Clone, Default)]
struct SharedFlash(Arc<Mutex<RamFlash<PAGES>>>);

impl SharedFlash {
    fn get(&self) -> MutexGuard<'_, RamFlash<PAGES>> {
        self.0.lock().unwrap()
    }
}

impl ErrorType for SharedFlash {
    type Error = store::RamFlashError;
}

impl ReadNorFlash for SharedFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.get().read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        self.get().capacity()
    }
}

impl NorFlash for SharedFlash {
    const WRITE_SIZE: usize = store::WORD_SIZE;
    const ERASE_SIZE: usize = store::PAGE_SIZE;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.get().erase(from, to)
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.get().write(offset, bytes)
    }
}

struct Board {
    actuator: Cell,
    service: Service,
    handler: Handler,
    report: Report,
    seq: u16,
}

impl Board {
    /// Boots the paper design at L = 3 mm (the defaults) over `flash`.
    fn boot(flash: &SharedFlash) -> Board {
        let design = Design::paper();
        let config = Config::paper(Length::from_int(3));
        let sup = SupervisorConfig::DEFAULT;
        let servo = Servo::new(&design, &config, &sup).unwrap();
        let mut actuator = Cell(Actuator::aligned(servo));
        let mut service = Service::new(design, config, sup);
        let (store, _) = Store::open(flash.clone(), &RangeChecks).unwrap();
        let (report, _) = service.attach_store(Box::leak(Box::new(store)), &mut actuator, true);
        Board {
            actuator,
            service,
            handler: Handler::new(),
            report,
            seq: 0,
        }
    }

    fn ask(&mut self, req: Request) -> Reply {
        self.seq += 1;
        let mut dev = self.service.device(&mut self.actuator);
        self.handler
            .handle_request(Frame::new(self.seq, req), &mut dev)
            .body
    }

    fn status(&mut self) -> Status {
        match self.ask(Request::GetStatus) {
            Reply::Status(s) => s,
            other => panic!("status answered with {other:?}"),
        }
    }

    fn log(&mut self, index: u8) -> (u8, Option<LoggedFault>) {
        match self.ask(Request::FaultsLog { index }) {
            Reply::FaultsLog { count, entry } => (count, entry),
            other => panic!("faults-log answered with {other:?}"),
        }
    }
}

#[test]
fn a_saved_configuration_comes_back_after_a_power_cycle() {
    let flash = SharedFlash::default();
    let mut b = Board::boot(&flash);
    assert_eq!(b.report.config, Outcome::Default);
    assert!(!b.status().differs_from_stored, "defaults, nothing stored");
    assert_eq!(
        b.ask(Request::SetClutchLength { length_um: 5_000 }),
        Reply::Ok
    );
    assert_eq!(
        b.ask(Request::SetLimits(protocol::Limits {
            current_ma: 1_200,
            ..protocol::Limits::DEFAULT
        })),
        Reply::Ok
    );
    assert!(b.status().differs_from_stored);
    assert_eq!(b.ask(Request::Save), Reply::Ok);
    assert!(!b.status().differs_from_stored);

    let mut again = Board::boot(&flash);
    assert_eq!(again.report.config, Outcome::Loaded);
    assert_eq!(again.report.generation, Some(1));
    let s = again.status();
    assert_eq!((s.clutch_length_um, s.state), (5_000, State::Disabled));
    assert!(!s.differs_from_stored);
    let Reply::Limits(l) = again.ask(Request::GetLimits) else {
        panic!("no limits")
    };
    assert_eq!(l.current_ma, 1_200);
}

#[test]
fn save_and_factory_reset_are_refused_while_enabled() {
    let flash = SharedFlash::default();
    let mut b = Board::boot(&flash);
    let words = flash.get().words_written();
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    assert_eq!(b.ask(Request::Save), Reply::Error(ErrorCode::NotAllowed));
    assert_eq!(
        b.ask(Request::FactoryReset),
        Reply::Error(ErrorCode::NotAllowed)
    );
    assert_eq!(flash.get().words_written(), words, "nothing written");
    assert_eq!(b.ask(Request::Disable), Reply::Ok);
    assert_eq!(b.ask(Request::Save), Reply::Ok);
}

#[test]
fn factory_reset_forgets_the_records_and_restores_the_defaults() {
    let flash = SharedFlash::default();
    let mut b = Board::boot(&flash);
    b.ask(Request::SetClutchLength { length_um: 2_000 });
    assert_eq!(b.ask(Request::Save), Reply::Ok);
    assert_eq!(b.ask(Request::FactoryReset), Reply::Ok);
    assert_eq!(b.status().clutch_length_um, 3_000);
    assert!(!b.status().differs_from_stored);
    let again = Board::boot(&flash);
    assert_eq!(again.report.config, Outcome::Default);
}

#[test]
fn load_rereads_the_store_and_drops_unsaved_changes() {
    let flash = SharedFlash::default();
    let mut b = Board::boot(&flash);
    b.ask(Request::SetClutchLength { length_um: 4_000 });
    b.ask(Request::Save);
    b.ask(Request::SetClutchLength { length_um: 6_000 });
    assert!(b.status().differs_from_stored);
    assert_eq!(b.ask(Request::Load), Reply::Ok);
    assert_eq!(b.status().clutch_length_um, 4_000);
    assert!(!b.status().differs_from_stored);
}

#[test]
fn a_stored_config_the_design_cannot_reach_is_rejected_and_defaults_apply() {
    let flash = SharedFlash::default();
    // Within the protocol's ranges (k ≥ 1 mN·m/rad), but L(k) is far beyond the paper
    // design's beams: the same refusal as `SetStiffness` over the wire.
    let too_soft = store::Config {
        clutch: Clutch::StiffnessMnmPerRad(1),
        link_inertia_kg_mm2: 1_000,
        gains: None,
        limits: protocol::Limits::DEFAULT,
        command_timeout_ms: 100,
    };
    let mut b = Board::boot(&flash);
    assert_eq!(
        b.ask(Request::SetStiffness {
            stiffness_mnm_per_rad: 1
        }),
        Reply::Error(ErrorCode::OutOfRange)
    );
    let (mut s, _) = Store::open(flash.clone(), &RangeChecks).unwrap();
    s.save(
        &RecordSet {
            config: Some(too_soft),
            ..RecordSet::default()
        },
        &RangeChecks,
    )
    .unwrap();
    let mut again = Board::boot(&flash);
    assert_eq!(
        again.report.config,
        Outcome::Rejected(Rejection::Invalid(
            "the design cannot reach this configuration"
        ))
    );
    assert_eq!(again.status().clutch_length_um, 3_000);
}

#[test]
fn a_latched_fault_is_logged_once_and_survives_a_power_cycle() {
    let flash = SharedFlash::default();
    let mut b = Board::boot(&flash);
    assert_eq!(b.log(0), (0, None));
    b.ask(Request::Enable);
    let fault = b.actuator.0.servo.deadline_missed(1_000_000);
    assert!(fault.is_some(), "a missed deadline latches");
    b.service.log_latched_fault(&mut b.actuator);
    b.service.log_latched_fault(&mut b.actuator);
    let (count, entry) = b.log(0);
    assert_eq!(count, 1, "logged once");
    let entry = entry.unwrap();
    assert_eq!(
        (entry.seq, entry.fault.code),
        (0, FaultCode::DeadlineMissed)
    );
    assert_eq!(b.log(1), (1, None));
    let mut again = Board::boot(&flash);
    assert_eq!(again.log(0), (1, Some(entry)));
    assert_eq!(again.ask(Request::FactoryReset), Reply::Ok);
    assert_eq!(again.log(0), (0, None));
}

#[test]
fn bus_settings_persist_through_the_service_api() {
    let flash = SharedFlash::default();
    let mut b = Board::boot(&flash);
    assert_eq!(b.service.bus_settings(), BusSettings::ax12a_default());
    let bus = BusSettings {
        id: 7,
        ..BusSettings::ax12a_default()
    };
    b.service.persist_bus(bus, &mut b.actuator).unwrap();
    let bad = BusSettings { id: 254, ..bus };
    assert_eq!(
        b.service.persist_bus(bad, &mut b.actuator),
        Err(ErrorCode::OutOfRange)
    );
    // An unsaved config change is not stored with it.
    b.ask(Request::SetClutchLength { length_um: 6_000 });
    b.service.persist_bus(bus, &mut b.actuator).unwrap();
    let again = Board::boot(&flash);
    assert_eq!(again.service.bus_settings(), bus);
    assert_eq!(again.report.config, Outcome::Default);
}

#[test]
fn without_a_store_the_requests_say_so() {
    let design = Design::paper();
    let config = Config::paper(Length::from_int(3));
    let sup = SupervisorConfig::DEFAULT;
    let mut actuator = Cell(Actuator::aligned(
        Servo::new(&design, &config, &sup).unwrap(),
    ));
    let mut service = Service::new(design, config, sup);
    let mut handler = Handler::new();
    for req in [
        Request::Save,
        Request::Load,
        Request::FactoryReset,
        Request::FaultsLog { index: 0 },
    ] {
        let mut dev = service.device(&mut actuator);
        let reply = handler.handle_request(Frame::new(1, req), &mut dev).body;
        assert_eq!(reply, Reply::Error(ErrorCode::Storage), "{req:?}");
    }
}
