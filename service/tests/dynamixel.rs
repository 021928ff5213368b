//! The actuator on the Dynamixel bus, on the host: AX-12A packets drive the servo that runs
//! the simulated actuator of a serving board (`plant::served`), tick by tick. The expected
//! values come from the AX-12A's units (1024 counts over 300°, 0.1 % of full scale) and
//! the plant's load, computed here, not read from the backend.

use dynamixel::instruction as ins;
use dynamixel::v1::{self, error};
use dynamixel::{Field, Protocol};
use service::dynamixel::{move_duration_ms, Bus};

// This binary drives the bench's ticks through the bus, not its own protocol requests.
#[allow(dead_code)]
mod closed_loop;
mod common;

/// One AX position count, rad.
const COUNT_RAD: f64 = 300.0 / 1024.0 * std::f64::consts::PI / 180.0;

/// The closed loop of a serving board with the Dynamixel bus in front of it.
struct Bench {
    lp: closed_loop::Bench,
    bus: Bus,
}

/// A status packet: (ID, error byte, parameters).
type Status = (u8, u8, Vec<u8>);

impl Bench {
    fn new(load_nm: f32) -> Bench {
        Bench {
            lp: closed_loop::Bench::new(load_nm),
            bus: Bus::new(1, Protocol::V1),
        }
    }

    /// Bytes on the line, then an idle line: every status the bus answers.
    fn line(&mut self, bytes: &[u8]) -> Vec<Status> {
        for &b in bytes {
            self.bus.push(b);
        }
        self.bus.idle();
        let mut out = Vec::new();
        while let Some(o) = self.bus.poll(&mut self.lp.service, &mut self.lp.actuator) {
            if let Some(r) = o.reply {
                let b = r.bytes;
                assert_eq!(&b[..2], &[0xFF, 0xFF]);
                let n = usize::from(b[3]);
                out.push((b[2], b[4], b[5..3 + n].to_vec()));
            }
        }
        out
    }

    /// One instruction packet; the single status it gets, if any.
    fn ask(&mut self, id: u8, code: u8, params: &[u8]) -> Option<Status> {
        let mut buf = [0u8; v1::MAX_PACKET];
        let n = v1::encode(id, code, params, &mut buf).unwrap();
        let mut st = self.line(&buf[..n]);
        assert!(st.len() <= 1, "{st:?}");
        st.pop()
    }

    fn read16(&mut self, address: u8) -> u16 {
        let (_, err, p) = self.ask(1, ins::READ, &[address, 2]).expect("a status");
        assert_eq!(err, 0, "READ {address}");
        u16::from_le_bytes([p[0], p[1]])
    }

    fn write16(&mut self, address: u8, v: u16) -> u8 {
        let [lo, hi] = v.to_le_bytes();
        self.ask(1, ins::WRITE, &[address, lo, hi])
            .expect("a status")
            .1
    }

    fn run(&mut self, ticks: u32) {
        for _ in 0..ticks {
            self.lp.step();
        }
    }
}

/// Present Voltage is the supply the board measures: a battery at 11.1 V reads 111 once a
/// window of the supply sense has passed (256 ticks), the configured 12 V before.
#[test]
fn present_voltage_is_the_supply_the_board_measures() {
    let mut b = Bench::new(0.0);
    b.lp.plant().set_supply(11.1);
    b.run(20);
    let (_, _, v) = b.ask(1, ins::READ, &[42, 1]).unwrap();
    assert_eq!(v, [120], "no full window yet: the configured supply");
    b.run(300);
    let (_, _, v) = b.ask(1, ins::READ, &[42, 1]).unwrap();
    assert_eq!(v, [111]);
    // A window that saw both supplies is a mean of them; the next one is 12.6 V alone.
    b.lp.plant().set_supply(12.6);
    b.run(600);
    let (_, _, v) = b.ask(1, ins::READ, &[42, 1]).unwrap();
    assert_eq!(v, [126]);
}

/// A measured supply outside the voltage limits (6.0–14.0 V by default, registers 12 and
/// 13) shows as the input-voltage bit in every status, as on the servo; back inside, it
/// goes.
#[test]
fn a_supply_outside_the_voltage_limits_raises_the_input_voltage_bit() {
    let mut b = Bench::new(0.0);
    b.run(300);
    let ping = |b: &mut Bench| b.ask(1, ins::PING, &[]).map(|(_, err, _)| err);
    assert_eq!(ping(&mut b), Some(0), "12 V is within 6.0–14.0 V");
    b.lp.plant().set_supply(14.6);
    b.run(600);
    assert_eq!(ping(&mut b), Some(error::INPUT_VOLTAGE));
    // A limit lowered below the supply (torque off: an EEPROM write) raises it as well.
    b.lp.plant().set_supply(12.0);
    b.run(600);
    assert_eq!(ping(&mut b), Some(0));
    let (_, err, _) = b.ask(1, ins::WRITE, &[13, 115]).expect("a status");
    assert_eq!(
        err,
        error::INPUT_VOLTAGE,
        "Max Voltage Limit 11.5 V under 12 V"
    );
    let (_, err, v) = b.ask(1, ins::READ, &[42, 1]).expect("a status");
    assert_eq!((err, v), (error::INPUT_VOLTAGE, vec![120]));
}

#[test]
fn it_answers_as_an_ax12a_with_the_defaults() {
    let mut b = Bench::new(0.0);
    b.run(20);
    assert_eq!(b.ask(1, ins::PING, &[]), Some((1, 0, vec![])));
    assert_eq!(b.read16(0), 12, "model number");
    assert_eq!(
        b.ask(2, ins::PING, &[]),
        None,
        "another ID is never answered"
    );
    // At rest at 0 rad: the middle count.
    assert_eq!(b.read16(36), 512);
    // Torque limit: the default margin 0.85 of the beams' capacity, in 1/1023.
    assert_eq!(b.read16(34), (0.85f64 * 1023.0).round() as u16);
    // Present voltage: the 12 V supply the board measures.
    let (_, _, v) = b.ask(1, ins::READ, &[42, 1]).unwrap();
    assert_eq!(v, [120]);
    // Clutch length 3 mm, and its stiffness and capacity agree with our own protocol.
    assert_eq!(b.read16(50), 3000);
    let status = b.lp.actuator.0.status();
    let (_, _, k) = b.ask(1, ins::READ, &[52, 4]).unwrap();
    assert_eq!(
        u32::from_le_bytes(k.try_into().unwrap()),
        status.stiffness_mnm_per_rad
    );
}

#[test]
fn a_goal_is_reached_within_the_controller_tolerance_at_the_speed_limit() {
    let mut b = Bench::new(0.0);
    b.run(20);
    // Speed 200 × 0.111 rpm; goal 700 counts: 188 counts = 0.96 rad away.
    assert_eq!(b.write16(32, 200), 0);
    assert_eq!(b.ask(1, ins::WRITE, &[24, 1]).unwrap().1, 0, "torque on");
    assert_eq!(b.write16(30, 700), 0);
    let distance = 188.0 * COUNT_RAD;
    let speed = 200.0 * 0.111 * 2.0 * std::f64::consts::PI / 60.0;
    let expected_ms = (1.875 * distance / speed * 1000.0) as u32;
    let got_ms = move_duration_ms((distance * 1e6) as i64, 200 * 11_624);
    assert!(
        got_ms.abs_diff(expected_ms) <= 2,
        "{got_ms} vs {expected_ms}"
    );
    let (_, _, moving) = b.ask(1, ins::READ, &[46, 1]).unwrap();
    assert_eq!(moving, [1]);
    b.run(got_ms + 500);
    let pos = b.read16(36);
    assert!(pos.abs_diff(700) <= 1, "present position {pos}");
    let (_, _, moving) = b.ask(1, ins::READ, &[46, 1]).unwrap();
    assert_eq!(moving, [0]);
}

#[test]
fn present_load_carries_the_direction_of_the_torque_that_holds_the_load() {
    // A load of +0.3 N·m pushes the link positive (CCW): the actuator holds it by pushing
    // CW, so the AX direction bit (10) is set and the magnitude is 0.3 N·m of τ_cap.
    let mut b = Bench::new(0.3);
    b.run(20);
    assert_eq!(
        b.ask(0xFE, ins::WRITE, &[24, 1]),
        None,
        "broadcast: no status"
    );
    b.run(1500);
    let load = b.read16(40);
    assert_ne!(load & 1024, 0, "CW bit in {load}");
    let cap_unm = {
        let (_, _, c) = b.ask(1, ins::READ, &[56, 4]).unwrap();
        f64::from(u32::from_le_bytes(c.try_into().unwrap()))
    };
    let expected = 0.3e6 / cap_unm * 1023.0;
    let got = f64::from(load & 1023);
    assert!(
        (got - expected).abs() <= 0.1 * expected,
        "load {got} vs {expected:.0}"
    );
    // With the load the other way, the bit is clear.
    let mut b = Bench::new(-0.3);
    b.run(20);
    b.ask(1, ins::WRITE, &[24, 1]);
    b.run(1500);
    assert_eq!(b.read16(40) & 1024, 0);
}

#[test]
fn refused_writes_change_nothing() {
    let mut b = Bench::new(0.0);
    b.run(20);
    b.ask(1, ins::WRITE, &[24, 1]);
    let before = b.read16(30);
    // 1023 counts = +2.61 rad: outside the ±2.5 rad position window.
    assert_eq!(b.write16(30, 1023), error::ANGLE_LIMIT);
    // Read-only: Present Position.
    assert_eq!(b.write16(36, 5), error::RANGE);
    // A clutch length our protocol refuses.
    assert_eq!(b.write16(50, 9000), error::RANGE);
    assert_eq!(b.read16(30), before);
    assert_eq!(b.read16(50), 3000);
    // A bad checksum: the checksum bit, nothing written.
    let mut bad = vec![0xFF, 0xFF, 1, 4, ins::WRITE, 25, 1];
    bad.push(!(1u8 + 4 + 3 + 25 + 1) ^ 0xFF);
    let st = b.line(&bad);
    assert_eq!(st, vec![(1, error::CHECKSUM, vec![])]);
    assert_eq!(b.bus.setting(Field::Led), 0);
}

#[test]
fn extra_registers_reconfigure_the_controller_like_our_protocol() {
    let mut b = Bench::new(0.0);
    b.run(20);
    assert_eq!(b.write16(50, 5000), 0, "clutch length 5 mm");
    let status = b.lp.actuator.0.status();
    assert_eq!(status.clutch_length_um, 5000);
    // Torque limit 512/1023 → margin 500 ‰ of τ_cap in force.
    assert_eq!(b.write16(34, 512), 0);
    assert_eq!(
        b.lp.service.config().limits.torque_margin,
        model::Ratio::from_bits(service::milli_to_q32(500))
    );
    assert_eq!(b.read16(34), 512);
    // Stiffness: configures L(k) (read back as the clutch length to set).
    let k: u32 = 200_000;
    let st = b.ask(
        1,
        ins::WRITE,
        &[52, k as u8, (k >> 8) as u8, (k >> 16) as u8, 0],
    );
    assert_eq!(st.unwrap().1, 0);
    let length = b.read16(50);
    assert!((1000..5000).contains(&length), "L(k) = {length} µm");
    // Protocol Type marks the settings for the store.
    let _ = b.bus.settings_changed();
    b.ask(1, ins::WRITE, &[5, 10]);
    assert!(
        b.bus.settings_changed(),
        "return delay is an EEPROM setting"
    );
    assert!(!b.bus.settings_changed());
}

#[test]
fn bus_settings_round_trip_through_the_bus_device() {
    use store::{BusLimits, BusSettings, Record};
    let ax = BusSettings::ax12a_default();
    let cases = [
        ax,
        BusSettings {
            id: 253,
            baud_bps: 250_000,
            return_delay_2us: 0,
            status_return_level: 1,
            cw_angle_limit: 100,
            ccw_angle_limit: 900,
            ..ax
        },
        BusSettings {
            id: 7,
            baud_bps: 57_600,
            protocol_version: 2,
            limits: BusLimits {
                max_torque: 512,
                temperature_limit: 60,
                velocity_limit: 100,
                min_position_limit: 1000,
                max_position_limit: 3000,
                ..ax.limits
            },
            ..ax
        },
    ];
    for s in cases {
        assert_eq!(s.check(), Ok(()), "{s:?}");
        let bus = Bus::from_settings(&s);
        assert_eq!(bus.settings(), s);
        assert_eq!(bus.id(), s.id);
        assert_eq!(bus.baud_bps(), Some(s.baud_bps));
        assert_eq!(bus.protocol().number(), i32::from(s.protocol_version));
    }
}
