//! The bus device, instruction by instruction, over the in-memory backend: what it answers,
//! when, with which error, and what it changes.

mod common;

use common::*;
use dynamixel::device::{hardware, BROADCAST_PING_GAP_US};
use dynamixel::instruction as ins;
use dynamixel::v1::error as e1;
use dynamixel::{After, Field, Protocol};

const B: u8 = 0xFE;

// ---- Protocol 1.0 ----

#[test]
fn v1_ping_is_answered_after_the_return_delay() {
    let mut d = device(1, Protocol::V1);
    let out = exchange(&mut d, &p1(1, ins::PING, &[]));
    assert_eq!(out.len(), 1);
    let r = out[0].reply.as_ref().unwrap();
    assert_eq!(r.bytes.as_slice(), [0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC]);
    assert_eq!(r.delay_us, 500); // default 250 × 2 µs
    exchange(&mut d, &p1(1, ins::WRITE, &[5, 10]));
    let out = exchange(&mut d, &p1(1, ins::PING, &[]));
    assert_eq!(out[0].reply.as_ref().unwrap().delay_us, 20);
}

#[test]
fn v1_other_ids_and_broadcast_are_never_answered() {
    let mut d = device(1, Protocol::V1);
    assert!(exchange(&mut d, &p1(2, ins::WRITE, &[25, 1])).is_empty());
    assert_eq!(d.backend().get(Field::Led), 0);
    assert!(exchange(&mut d, &p1(B, ins::WRITE, &[25, 1])).is_empty());
    assert_eq!(d.backend().get(Field::Led), 1, "broadcast executed");
    assert!(exchange(&mut d, &p1(B, ins::PING, &[])).is_empty());
}

#[test]
fn v1_read_spans_registers_and_gaps() {
    let mut d = device(7, Protocol::V1);
    let s = status1(&exchange(&mut d, &p1(7, ins::READ, &[0, 12])));
    // Model 12, firmware 1, ID 7, baud 1, delay 250, CW 0, CCW 1023, reserved 10 = 0, temp 70.
    assert_eq!(
        s,
        [(7, 0, vec![12, 0, 1, 7, 1, 250, 0, 0, 0xFF, 0x03, 0, 70])]
    );
    let s = status1(&exchange(&mut d, &p1(7, ins::READ, &[60, 10])));
    assert_eq!(s[0].1, e1::RANGE, "read beyond the table (ends at 63)");
    assert!(s[0].2.is_empty());
}

#[test]
fn v1_refusals_set_their_bit_and_change_nothing() {
    let mut d = device(1, Protocol::V1);
    let before = d.backend().clone();
    let cases: &[(&[u8], u8)] = &[
        (&[30, 0x00, 0x04], e1::ANGLE_LIMIT), // goal 1024 > CCW limit 1023
        (&[36, 5, 0], e1::RANGE),             // Present Position is read-only
        (&[10, 1], e1::RANGE),                // reserved address
        (&[30, 5], e1::RANGE),                // half of Goal Position
        (&[16, 3], e1::RANGE),                // Status Return Level 0–2
        (&[50, 0x28, 0x23], e1::RANGE),       // clutch 9000 µm > 8000
        (&[60, 1, 0], e1::RANGE),             // latched faults: only 0 may be written
        (&[25, 1, 0, 0, 0, 0, 0x00, 0x04], e1::ANGLE_LIMIT), // LED ok, goal bad: all refused
    ];
    for (params, bit) in cases {
        let s = status1(&exchange(&mut d, &p1(1, ins::WRITE, params)));
        assert_eq!(s, [(1, *bit, vec![])], "WRITE {params:?}");
        assert_eq!(d.backend(), &before, "WRITE {params:?} changed nothing");
    }
    let s = status1(&exchange(&mut d, &p1(1, 0x42, &[])));
    assert_eq!(s[0].1, e1::INSTRUCTION);
}

#[test]
fn v1_goal_is_checked_against_the_angle_limits() {
    let mut d = device(1, Protocol::V1);
    // CCW limit 600.
    exchange(&mut d, &p1(1, ins::WRITE, &[8, 0x58, 0x02]));
    let s = status1(&exchange(&mut d, &p1(1, ins::WRITE, &[30, 0x59, 0x02])));
    assert_eq!(s[0].1, e1::ANGLE_LIMIT, "goal 601 over CCW 600");
    let s = status1(&exchange(&mut d, &p1(1, ins::WRITE, &[30, 0x58, 0x02])));
    assert_eq!(s[0].1, 0);
    assert_eq!(d.backend().get(Field::GoalPosition), 600);
    // Wheel mode (both limits 0): the goal is not limited by them.
    exchange(&mut d, &p1(1, ins::WRITE, &[6, 0, 0, 0, 0]));
    let s = status1(&exchange(&mut d, &p1(1, ins::WRITE, &[30, 0xE8, 0x03])));
    assert_eq!(s[0].1, 0);
}

#[test]
fn v1_bad_checksum_is_answered_and_changes_nothing_however_often() {
    let mut d = device(1, Protocol::V1);
    let before = d.backend().clone();
    let mut bad = p1(1, ins::WRITE, &[25, 1]);
    *bad.last_mut().unwrap() ^= 0xFF;
    for _ in 0..3 {
        let s = status1(&exchange(&mut d, &bad));
        assert_eq!(s, [(1, e1::CHECKSUM, vec![])]);
    }
    assert_eq!(d.backend(), &before);
    assert_eq!(d.counters().checksum_errors, 3);
    // For another ID: counted, not answered.
    let mut other = p1(2, ins::WRITE, &[25, 1]);
    *other.last_mut().unwrap() ^= 1;
    assert!(exchange(&mut d, &other).is_empty());
}

#[test]
fn v1_reg_write_waits_for_action() {
    let mut d = device(1, Protocol::V1);
    let s = status1(&exchange(&mut d, &p1(1, ins::ACTION, &[])));
    assert_eq!(s[0].1, e1::INSTRUCTION, "nothing registered");
    let s = status1(&exchange(&mut d, &p1(1, ins::REG_WRITE, &[30, 0x2C, 0x01])));
    assert_eq!(s[0].1, 0);
    assert_eq!(d.backend().get(Field::GoalPosition), 512);
    let s = status1(&exchange(&mut d, &p1(1, ins::READ, &[44, 1])));
    assert_eq!(s[0].2, [1], "Registered");
    let s = status1(&exchange(&mut d, &p1(1, ins::REG_WRITE, &[36, 1, 0])));
    assert_eq!(s[0].1, e1::RANGE, "a bad REG_WRITE is refused at once");
    assert!(exchange(&mut d, &p1(B, ins::ACTION, &[])).is_empty());
    assert_eq!(d.backend().get(Field::GoalPosition), 300);
    let s = status1(&exchange(&mut d, &p1(1, ins::READ, &[44, 1])));
    assert_eq!(s[0].2, [0]);
}

#[test]
fn v1_status_return_level() {
    let mut d = device(1, Protocol::V1);
    exchange(&mut d, &p1(1, ins::WRITE, &[16, 0]));
    assert_eq!(exchange(&mut d, &p1(1, ins::PING, &[])).len(), 1);
    assert!(exchange(&mut d, &p1(1, ins::READ, &[0, 2])).is_empty());
    assert!(exchange(&mut d, &p1(1, ins::WRITE, &[25, 1])).is_empty());
    assert_eq!(d.backend().get(Field::Led), 1, "executed, not answered");
    exchange(&mut d, &p1(1, ins::WRITE, &[16, 1]));
    assert_eq!(exchange(&mut d, &p1(1, ins::READ, &[0, 2])).len(), 1);
    assert!(exchange(&mut d, &p1(1, ins::WRITE, &[25, 0])).is_empty());
}

#[test]
fn v1_lock_holds_the_eeprom() {
    let mut d = device(1, Protocol::V1);
    assert_eq!(
        status1(&exchange(&mut d, &p1(1, ins::WRITE, &[47, 1])))[0].1,
        0
    );
    assert!(d.locked());
    for params in [&[5u8, 0][..], &[47, 0], &[50, 0xB8, 0x0B]] {
        let s = status1(&exchange(&mut d, &p1(1, ins::WRITE, params)));
        assert_eq!(s[0].1, e1::RANGE, "WRITE {params:?} while locked");
    }
    assert_eq!(
        status1(&exchange(&mut d, &p1(1, ins::FACTORY_RESET, &[])))[0].1,
        e1::RANGE
    );
    assert_eq!(
        status1(&exchange(&mut d, &p1(1, ins::WRITE, &[25, 1])))[0].1,
        0,
        "RAM stays writable"
    );
    assert_eq!(d.backend().get(Field::ReturnDelayTime), 250);
}

#[test]
fn v1_sync_write_takes_each_devices_entry() {
    let mut ds: Vec<_> = (1..=3).map(|i| device(i, Protocol::V1)).collect();
    let packet = p1(
        B,
        ins::SYNC_WRITE,
        &[30, 2, 1, 100, 0, 2, 200, 0, 3, 0x2C, 0x01],
    );
    for d in &mut ds {
        assert!(exchange(d, &packet).is_empty());
    }
    let goals: Vec<_> = ds
        .iter()
        .map(|d| d.backend().get(Field::GoalPosition))
        .collect();
    assert_eq!(goals, [100, 200, 300]);
}

#[test]
fn v1_factory_reset_and_hardware_bits() {
    let mut d = device(9, Protocol::V1);
    exchange(&mut d, &p1(9, ins::WRITE, &[5, 0]));
    let out = exchange(&mut d, &p1(9, ins::FACTORY_RESET, &[]));
    assert_eq!(out[0].after, After::ApplyBusSettings);
    assert_eq!(d.backend().get(Field::Id), 1, "AX factory reset sets ID 1");
    assert_eq!(d.backend().get(Field::ReturnDelayTime), 250);
    d.backend_mut().hardware_errors = hardware::OVERLOAD | hardware::SENSOR;
    let s = status1(&exchange(&mut d, &p1(1, ins::PING, &[])));
    assert_eq!(s[0].1, e1::OVERLOAD, "2.0-only bits do not leak into 1.0");
}

#[test]
fn a_new_id_answers_from_the_old_one_then_the_new() {
    let mut d = device(1, Protocol::V1);
    let out = exchange(&mut d, &p1(1, ins::WRITE, &[3, 5]));
    assert_eq!(status1(&out), [(1, 0, vec![])], "the SDK waits for ID 1");
    assert_eq!(out[0].after, After::ApplyBusSettings);
    assert!(exchange(&mut d, &p1(1, ins::PING, &[])).is_empty());
    assert_eq!(
        status1(&exchange(&mut d, &p1(5, ins::PING, &[]))),
        [(5, 0, vec![])]
    );
    let mut d = device(1, Protocol::V2);
    let out = exchange(&mut d, &p2(1, ins::WRITE, &[7, 0, 5]));
    assert_eq!(status2(&out), [(1, 0, vec![])]);
    assert_eq!(status2(&exchange(&mut d, &p2(5, ins::PING, &[])))[0].0, 5);
}

#[test]
fn switching_protocols_from_either_side() {
    let mut d = device(1, Protocol::V1);
    let out = exchange(&mut d, &p1(1, ins::WRITE, &[63, 2]));
    assert_eq!(status1(&out)[0].1, 0, "answered in 1.0");
    assert_eq!(out[0].after, After::ApplyBusSettings);
    assert_eq!(d.protocol(), Protocol::V2);
    assert!(exchange(&mut d, &p1(1, ins::PING, &[])).is_empty());
    let s = status2(&exchange(&mut d, &p2(1, ins::PING, &[])));
    assert_eq!(s, [(1, 0, vec![0x24, 0x04, 1])], "model 1060, firmware 1");
    exchange(&mut d, &p2(B, ins::WRITE, &[13, 0, 1]));
    assert_eq!(d.protocol(), Protocol::V1);
}

// ---- Protocol 2.0 ----

#[test]
fn v2_broadcast_ping_slots_follow_the_ids() {
    let delays: Vec<u32> = (1..=3)
        .map(|i| {
            let mut d = device(i, Protocol::V2);
            let out = exchange(&mut d, &p2(B, ins::PING, &[]));
            out[0].reply.as_ref().unwrap().delay_us
        })
        .collect();
    // 14 bytes × 10 bits at 57 600 bit/s = 2430.6 µs, rounded up.
    let slot = BROADCAST_PING_GAP_US + 2431;
    assert_eq!(delays, [500 + slot, 500 + 2 * slot, 500 + 3 * slot]);
}

#[test]
fn v2_sync_read_answers_after_the_previous_id() {
    let mut ds: Vec<_> = (1..=3).map(|i| device(i, Protocol::V2)).collect();
    for (d, g) in ds.iter_mut().zip([1000, 2000, 3000]) {
        d.backend_mut().set(Field::PresentPositionX, g);
    }
    let req = p2(B, ins::SYNC_READ, &[132, 0, 4, 0, 1, 2, 3]);
    let outs: Vec<_> = ds.iter_mut().map(|d| exchange(d, &req)).collect();
    assert_eq!(outs[0].len(), 1, "first in the list answers");
    assert!(outs[1].is_empty() && outs[2].is_empty(), "the others wait");
    // Device 1's status on the line cues device 2, whose status cues device 3.
    let s1 = outs[0][0].reply.clone().unwrap();
    assert!(
        exchange(&mut ds[2], &s1.bytes).is_empty(),
        "3 waits for 2, not 1"
    );
    let o2 = exchange(&mut ds[1], &s1.bytes);
    let o3 = exchange(&mut ds[2], &o2[0].reply.as_ref().unwrap().bytes);
    let all: Vec<_> = [&outs[0], &o2, &o3]
        .iter()
        .flat_map(|o| status2(o))
        .collect();
    let want: Vec<_> = [(1u8, 1000i32), (2, 2000), (3, 3000)]
        .iter()
        .map(|&(i, v)| (i, 0u8, v.to_le_bytes().to_vec()))
        .collect();
    assert_eq!(all, want);
    assert_eq!(o2[0].reply.as_ref().unwrap().delay_us, 500);
}

#[test]
fn v2_bulk_read_and_bulk_write() {
    let mut ds: Vec<_> = (1..=2).map(|i| device(i, Protocol::V2)).collect();
    let w = p2(B, ins::BULK_WRITE, &[1, 65, 0, 1, 0, 1, 2, 9, 0, 1, 0, 20]);
    for d in &mut ds {
        assert!(exchange(d, &w).is_empty());
    }
    assert_eq!(ds[0].backend().get(Field::Led), 1);
    assert_eq!(ds[1].backend().get(Field::ReturnDelayTime), 20);
    let r = p2(B, ins::BULK_READ, &[2, 9, 0, 1, 0, 1, 65, 0, 1, 0]);
    let o2 = exchange(&mut ds[1], &r);
    let o1 = exchange(&mut ds[0], &r);
    assert!(o1.is_empty(), "1 is listed second");
    let o1 = exchange(&mut ds[0], &o2[0].reply.as_ref().unwrap().bytes);
    assert_eq!(status2(&o2), [(2, 0, vec![20])]);
    assert_eq!(status2(&o1), [(1, 0, vec![1])]);
}

#[test]
fn v2_error_codes() {
    let mut d = device(1, Protocol::V2);
    let before = d.backend().clone();
    let cases: &[(u8, &[u8], u8)] = &[
        (ins::WRITE, &[116, 0, 0x88, 0x13, 0, 0], 6), // goal 5000 beyond Max Position Limit
        (ins::WRITE, &[132, 0, 1, 0, 0, 0], 7),       // read-only
        (ins::WRITE, &[116, 0, 1, 0], 5),             // half of Goal Position
        (ins::WRITE, &[100, 0, 1, 0], 7),             // undefined (Goal PWM not served)
        (ins::WRITE, &[11, 0, 1], 4),                 // operating mode 1 (only 3)
        (ins::READ, &[0, 2, 4, 0], 7),                // beyond the table
        (ins::ACTION, &[], 2),                        // nothing registered
        (ins::CLEAR, &[1, 0x44, 0x58, 0x4C, 0x22], 2),
    ];
    for (inst, params, code) in cases {
        let s = status2(&exchange(&mut d, &p2(1, *inst, params)));
        assert_eq!(s, [(1, *code, vec![])], "0x{inst:02x} {params:?}");
    }
    exchange(&mut d, &p2(1, ins::WRITE, &[64, 0, 1]));
    let s = status2(&exchange(&mut d, &p2(1, ins::WRITE, &[9, 0, 0])));
    assert_eq!(s[0].1, 7, "EEPROM write with torque on");
    exchange(&mut d, &p2(1, ins::WRITE, &[64, 0, 0]));
    let mut torque_only = before.clone();
    torque_only.set(Field::TorqueEnable, 0);
    assert_eq!(d.backend(), &torque_only);
    d.backend_mut().hardware_errors = hardware::SENSOR;
    let s = status2(&exchange(&mut d, &p2(1, ins::PING, &[])));
    assert_eq!(s[0].1, 0x80, "alert bit");
}

#[test]
fn v2_reboot_and_factory_reset_options() {
    let mut d = device(5, Protocol::V2);
    let out = exchange(&mut d, &p2(5, ins::REBOOT, &[]));
    assert_eq!(out[0].after, After::Reboot);
    assert_eq!(status2(&out), [(5, 0, vec![])]);
    exchange(&mut d, &p2(5, ins::WRITE, &[8, 0, 3]));
    exchange(&mut d, &p2(5, ins::FACTORY_RESET, &[0x02]));
    assert_eq!(
        (
            d.backend().get(Field::Id),
            d.backend().get(Field::BaudRateX)
        ),
        (5, 3)
    );
    exchange(&mut d, &p2(5, ins::FACTORY_RESET, &[0x01]));
    assert_eq!(
        (
            d.backend().get(Field::Id),
            d.backend().get(Field::BaudRateX)
        ),
        (5, 1)
    );
    assert!(exchange(&mut d, &p2(B, ins::FACTORY_RESET, &[0xFF])).is_empty());
    assert_eq!(
        d.backend().get(Field::Id),
        5,
        "broadcast reset-all is ignored"
    );
    exchange(&mut d, &p2(5, ins::FACTORY_RESET, &[0xFF]));
    assert_eq!(d.backend().get(Field::Id), 1);
    assert_eq!(d.protocol(), Protocol::V2, "a reset keeps the protocol");
}

#[test]
fn footprint() {
    // What the firmware pays in RAM for one device (the backend aside).
    let size = std::mem::size_of::<dynamixel::Device<()>>();
    println!("Device<()>: {size} bytes");
    assert!(size < 2_200, "{size} bytes");
}
