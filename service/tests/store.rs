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

/// The link task with the Dynamixel bus over a board booted from `flash` (factory ID 1),
/// and a way to feed it bytes: what it sent comes back.
mod bus_link {
    use super::*;
    use dynamixel::instruction as ins;
    use dynamixel::{v1, v2};
    use heapless::spsc::{Producer, Queue};
    use service::dynamixel::Bus;
    use service::link::{Link, Sample, RX_QUEUE, TELEMETRY_QUEUE};

    /// Every write the link made.
    #[derive(Default)]
    pub struct Wire(pub Vec<Vec<u8>>);

    impl embedded_io::ErrorType for Wire {
        type Error = embedded_io::ErrorKind;
    }

    impl embedded_io::Write for Wire {
        fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
            self.0.push(buf.to_vec());
            Ok(buf.len())
        }
        fn flush(&mut self) -> Result<(), Self::Error> {
            Ok(())
        }
    }

    /// A clock that runs 1 ms per reading: every status is due at once, every line idle.
    fn clock() -> u64 {
        use std::sync::atomic::{AtomicU64, Ordering};
        static NOW: AtomicU64 = AtomicU64::new(0);
        NOW.fetch_add(1_000, Ordering::Relaxed)
    }

    pub struct BusBoard {
        pub link: Link<'static, Wire>,
        pub rx: Producer<'static, u8>,
        pub actuator: Cell,
        seq: u16,
    }

    impl BusBoard {
        pub fn boot(flash: &SharedFlash) -> BusBoard {
            let b = Board::boot(flash);
            let rxq = Box::leak(Box::new(Queue::<u8, RX_QUEUE>::new()));
            let tq = Box::leak(Box::new(Queue::<Sample, TELEMETRY_QUEUE>::new()));
            let (rx, rx_out) = rxq.split();
            let (_, t_out) = tq.split();
            let bus = Bus::from_settings(&b.service.boot_bus_settings(1));
            let link =
                Link::new(b.service, rx_out, t_out, Wire::default()).with_dynamixel(bus, clock, 0);
            BusBoard {
                link,
                rx,
                actuator: b.actuator,
                seq: 0,
            }
        }

        /// `bytes` on the line; what the board sent meanwhile.
        pub fn line(&mut self, bytes: &[u8]) -> Vec<Vec<u8>> {
            let before = self.link.tx().0.len();
            for &b in bytes {
                self.rx.enqueue(b).unwrap();
            }
            self.link.poll(&mut self.actuator);
            // Once more: the idle line after the last byte.
            self.link.poll(&mut self.actuator);
            self.link.tx().0[before..].to_vec()
        }

        /// A Protocol 1.0 instruction; the status's error byte, if answered.
        pub fn v1(&mut self, id: u8, code: u8, params: &[u8]) -> Option<u8> {
            let mut buf = [0u8; v1::MAX_PACKET];
            let n = v1::encode(id, code, params, &mut buf).unwrap();
            let sent = self.line(&buf[..n]);
            sent.iter()
                .find(|s| s.starts_with(&[0xFF, 0xFF]))
                .map(|s| s[4])
        }

        /// A Protocol 2.0 PING: the model number it answers with, if answered.
        pub fn v2_ping(&mut self, id: u8) -> Option<u16> {
            let mut buf = [0u8; 32];
            let n = v2::encode(id, ins::PING, &[], &mut buf).unwrap();
            let sent = self.line(&buf[..n]);
            sent.iter()
                .find(|s| s.starts_with(&[0xFF, 0xFF, 0xFD, 0x00, id]) && s.len() >= 14)
                .map(|s| u16::from_le_bytes([s[9], s[10]]))
        }

        /// One of our requests; its reply.
        pub fn ask(&mut self, req: Request) -> Reply {
            self.seq += 1;
            let mut buf = [0u8; protocol::MAX_FRAME];
            let n = protocol::encode(&Frame::new(self.seq, req), &mut buf).unwrap();
            let sent = self.line(&buf[..n]);
            let mut d = protocol::Decoder::<Reply>::new();
            sent.iter()
                .flatten()
                .find_map(|b| d.feed(*b).ok().flatten())
                .map(|f| f.body)
                .expect("a reply")
        }
    }
}

#[test]
fn bus_settings_written_on_the_bus_or_with_set_bus_survive_a_power_cycle() {
    use bus_link::BusBoard;
    use dynamixel::instruction as ins;
    let flash = SharedFlash::default();
    let stored = |flash: &SharedFlash| Board::boot(flash).service.boot_bus_settings(1);
    let mut b = BusBoard::boot(&flash);
    assert_eq!(stored(&flash), BusSettings::ax12a_default());

    // Torque on: an EEPROM write (Return Delay Time, address 5) is in force at once and
    // stored only once the motor is off.
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    assert_eq!(b.v1(1, ins::WRITE, &[5, 10]), Some(0));
    assert!(b.link.service().bus_unsaved());
    assert_eq!(stored(&flash).return_delay_2us, 250, "not while enabled");
    assert_eq!(b.ask(Request::Disable), Reply::Ok);
    assert_eq!(stored(&flash).return_delay_2us, 10);

    // A new ID on the bus: answered at it, stored.
    assert_eq!(b.v1(1, ins::WRITE, &[3, 7]), Some(0));
    assert_eq!(b.v1(7, ins::PING, &[]), Some(0));
    assert_eq!(b.v1(1, ins::PING, &[]), None);
    assert_eq!(stored(&flash).id, 7);
    // The rest of the EEPROM area too: Max Torque (14, two bytes).
    assert_eq!(b.v1(7, ins::WRITE, &[14, 0x00, 0x02]), Some(0));
    assert_eq!(stored(&flash).limits.max_torque, 512);

    // Protocol 2.0 from our protocol: the bus speaks it after the reply; stored.
    let to_v2 = Request::SetBus(protocol::BusChange {
        protocol_version: Some(2),
        ..Default::default()
    });
    assert_eq!(b.ask(to_v2), Reply::Ok);
    assert_eq!(b.v2_ping(7), Some(1060));
    // A rate Protocol 2.0's Baud Rate register cannot select: refused, nothing changed.
    let odd_rate = Request::SetBus(protocol::BusChange {
        baud_bps: Some(400_000),
        ..Default::default()
    });
    assert_eq!(b.ask(odd_rate), Reply::Error(ErrorCode::OutOfRange));
    // ID 253 is an AX-12A ID, not an X-series one.
    let x_id = Request::SetBus(protocol::BusChange {
        id: Some(253),
        ..Default::default()
    });
    assert_eq!(b.ask(x_id), Reply::Error(ErrorCode::OutOfRange));

    // Power cycle on the same flash: ID 7, Protocol 2.0, return delay 10.
    let want = BusSettings {
        id: 7,
        protocol_version: 2,
        return_delay_2us: 10,
        limits: store::BusLimits {
            max_torque: 512,
            ..BusSettings::ax12a_default().limits
        },
        ..BusSettings::ax12a_default()
    };
    assert_eq!(stored(&flash), want);
    let mut again = BusBoard::boot(&flash);
    assert_eq!(again.v2_ping(7), Some(1060));
    // Back to 1.0 from Protocol 2.0 itself (Protocol Type, address 13), then Lock.
    let mut buf = [0u8; 32];
    let n = dynamixel::v2::encode(7, ins::WRITE, &[13, 0, 1], &mut buf).unwrap();
    again.line(&buf[..n]);
    assert_eq!(again.v1(7, ins::PING, &[]), Some(0));
    assert_eq!(again.v1(7, ins::WRITE, &[47, 1]), Some(0), "Lock = 1");
    let range = dynamixel::v1::error::RANGE;
    assert_eq!(
        again.v1(7, ins::WRITE, &[3, 9]),
        Some(range),
        "ID while locked"
    );
    assert_eq!(again.v1(7, ins::WRITE, &[47, 0]), Some(range), "unlock");
    assert_eq!(stored(&flash).id, 7);
    assert_eq!(stored(&flash).protocol_version, 1);
    // The power cycle ends the lock.
    let mut third = BusBoard::boot(&flash);
    assert_eq!(
        third.v1(7, ins::WRITE, &[3, 9]),
        Some(0),
        "unlocked after a power cycle"
    );
    assert_eq!(third.v1(9, ins::PING, &[]), Some(0));
}

/// The beams' capacity the supervisor checks, as a fraction of τ_cap at the configured
/// clutch length.
fn checked_fraction(b: &Board) -> f64 {
    let servo = &b.actuator.0.servo;
    let cap = servo.controller().schedule().setting().torque_capacity();
    servo.supervisor().checked_capacity().get().to_num::<f64>() / cap.get().to_num::<f64>()
}

#[test]
fn until_a_calibration_confirms_the_clutch_it_is_taken_1_mm_longer() {
    // τ_cap ∝ 1/L (eq. 2): a clutch ΔL longer than L carries L/(L + ΔL) of τ_cap.
    let close = |got: f64, want: f64| assert!((got - want).abs() < 1e-6, "{got} vs {want}");
    let flash = SharedFlash::default();
    let mut b = Board::boot(&flash);
    close(checked_fraction(&b), 3.0 / 4.0);
    assert_eq!(b.status().clutch_tolerance_um, 1_000);
    // The tolerance on the wire stays the configured one.
    let Reply::Limits(l) = b.ask(Request::GetLimits) else {
        panic!("no limits")
    };
    assert_eq!(l.clutch_tolerance_um, 0);
    // A calibration that measured 3 mm with 6 % stiffness uncertainty: longest
    // 3·(3000 − 120)/(3000 − 180) = 3.0638 mm, rounded up to 3.064 mm.
    let cal = store::Calibration {
        wire: protocol::Calibration {
            motor_polarity: 1,
            encoder_direction: 1,
            pot_direction: 1,
            current_offset_counts: 0,
            pot_offset_counts: 0,
            resistance_mohm: 8_000,
            back_emf_uv_s_per_rad: 1_940_000,
            gear_friction_unm: 10_000,
            link_inertia_kg_mm2: 1_000,
            stiffness_mnm_per_rad: Some(265_500),
            clutch_length_um: Some(3_000),
            stiffness_uncertainty_permille: 60,
        },
        encoder_counts_per_turn: 4096,
        pot_gain_ppm: 1_000_000,
        current_gain_ppm: 1_000_000,
        pot_error_centi: None,
    };
    b.service.persist_calibration(cal, &mut b.actuator).unwrap();
    assert_eq!(b.ask(Request::Load), Reply::Ok);
    close(checked_fraction(&b), 3.0 / 3.064);
    assert_eq!(b.status().clutch_tolerance_um, 64);
    // The same after a power cycle.
    let mut b = Board::boot(&flash);
    close(checked_fraction(&b), 3.0 / 3.064);
    // A clutch moved beyond what the calibration measured: unconfirmed again.
    assert_eq!(
        b.ask(Request::SetClutchLength { length_um: 5_000 }),
        Reply::Ok
    );
    close(checked_fraction(&b), 5.0 / 6.0);
    // A larger configured tolerance wins.
    assert_eq!(
        b.ask(Request::SetClutchLength { length_um: 3_000 }),
        Reply::Ok
    );
    let limits = protocol::Limits {
        clutch_tolerance_um: 1_500,
        ..protocol::Limits::DEFAULT
    };
    assert_eq!(b.ask(Request::SetLimits(limits)), Reply::Ok);
    close(checked_fraction(&b), 3.0 / 4.5);
    // A factory reset forgets the calibration.
    assert_eq!(b.ask(Request::FactoryReset), Reply::Ok);
    close(checked_fraction(&b), 3.0 / 4.0);
}
