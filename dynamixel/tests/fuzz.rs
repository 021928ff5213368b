//! Property tests of both codecs and of the device under hostile input.
//!
//! Each property runs 10 000 cases by default; the long run is
//! `PROPTEST_CASES=1000000 cargo test -p vsa-dynamixel --release --test fuzz`.
//!
//! * Round trips: any packet encodes and decodes back to itself, behind noise.
//! * Random bytes (with idle gaps anywhere) never panic a decoder or a device and never
//!   change a device's registers.
//! * A state-changing WRITE cut short (then an idle line) changes nothing, and a valid
//!   request right after it is still answered.
//! * A state-changing WRITE with one bit flipped anywhere but its length field, sent twice,
//!   changes nothing. The length field is left out because a checksum cannot protect the
//!   packet boundary it depends on: a shortened 1.0 packet whose new last byte happens to
//!   equal its checksum (1 in 256) is a different valid packet (2.0: 1 in 65 536).

mod common;

use common::*;
use dynamixel::instruction as ins;
use dynamixel::{v1, v2, Device, MemoryBackend, Protocol};
use proptest::prelude::*;
use proptest::test_runner::Config;

/// 10 000 cases unless `PROPTEST_CASES` is set.
fn config() -> Config {
    let mut c = Config {
        failure_persistence: None,
        max_shrink_iters: 10_000,
        ..Config::default()
    };
    if std::env::var_os("PROPTEST_CASES").is_none() {
        c.cases = 10_000;
    }
    c
}

/// Bytes with the framing values (FF, FD, FE, 00) frequent.
fn wire_byte() -> impl Strategy<Value = u8> {
    prop_oneof![any::<u8>(), Just(0xFF), Just(0xFD), Just(0xFE), Just(0x00)]
}

fn id1() -> impl Strategy<Value = u8> {
    prop_oneof![0..=v1::MAX_ID, Just(v1::BROADCAST_ID)]
}

fn id2() -> impl Strategy<Value = u8> {
    prop_oneof![0..=v2::MAX_ID, Just(v2::BROADCAST_ID)]
}

/// Noise that cannot start a header (no 0xFF).
fn noise() -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(0u8..0xFF, 0..8)
}

/// Random bytes, each with a chance of an idle gap after it.
fn bursts() -> impl Strategy<Value = Vec<(u8, bool)>> {
    proptest::collection::vec((wire_byte(), proptest::bool::weighted(0.05)), 0..300)
}

/// The device's whole state as the bus could change it.
fn state(d: &Device<MemoryBackend>) -> (MemoryBackend, bool, Protocol) {
    (d.backend().clone(), d.locked(), d.protocol())
}

/// A WRITE to ID 1 that the device accepts and that changes its state: 1.0 goal position
/// and moving speed; 2.0 goal position and profile velocity.
fn good_write(protocol: Protocol) -> impl Strategy<Value = Vec<u8>> {
    (0u16..=1023, 1u16..=1023, 0u32..=4095, 1u32..=32_767).prop_filter_map(
        "goal at its start value",
        move |(g1, s1, g2, s2)| match protocol {
            Protocol::V1 if g1 != 512 => {
                let [a, b] = g1.to_le_bytes();
                let [c, d] = s1.to_le_bytes();
                Some(p1(1, ins::WRITE, &[30, a, b, c, d]))
            }
            Protocol::V2 if g2 != 2048 => {
                let mut params = vec![112, 0];
                params.extend_from_slice(&s2.to_le_bytes());
                params.extend_from_slice(&g2.to_le_bytes());
                Some(p2(1, ins::WRITE, &params))
            }
            _ => None,
        },
    )
}

fn protocol() -> impl Strategy<Value = Protocol> {
    prop_oneof![Just(Protocol::V1), Just(Protocol::V2)]
}

/// Which bytes hold the length field.
fn length_bytes(protocol: Protocol) -> std::ops::Range<usize> {
    match protocol {
        Protocol::V1 => 3..4,
        Protocol::V2 => 5..7,
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn v1_round_trip(
        pre in noise(),
        id in id1(),
        code in any::<u8>(),
        params in proptest::collection::vec(wire_byte(), 0..=v1::MAX_PARAMS),
    ) {
        let packet = p1(id, code, &params);
        let mut d = v1::Decoder::new();
        for &b in pre.iter().chain(&packet) {
            d.push(b);
        }
        let p = d.next().expect("a packet").expect("valid");
        prop_assert_eq!((p.id, p.code, p.params), (id, code, params.as_slice()));
        prop_assert!(d.next().is_none());
    }

    #[test]
    fn v2_round_trip(
        pre in noise(),
        id in id2(),
        instruction in any::<u8>(),
        params in proptest::collection::vec(wire_byte(), 0..600),
        status in any::<bool>(),
    ) {
        let mut wire = vec![0; v2::MAX_PACKET];
        let n = if status {
            v2::encode_status(id, instruction, &params, &mut wire)
        } else {
            v2::encode(id, instruction, &params, &mut wire)
        };
        let n = n.expect("fits");
        let mut d = v2::Decoder::new();
        for &b in pre.iter().chain(&wire[..n]) {
            d.push(b);
        }
        let p = d.next().expect("a packet").expect("valid");
        prop_assert_eq!(p.id, id);
        if status {
            prop_assert_eq!(p.instruction, v2::STATUS);
            prop_assert_eq!(p.params[0], instruction);
            prop_assert_eq!(&p.params[1..], params.as_slice());
        } else {
            prop_assert_eq!(p.instruction, instruction);
            prop_assert_eq!(p.params, params.as_slice());
        }
        prop_assert!(d.next().is_none());
    }

    #[test]
    fn random_bytes_never_change_a_device(proto in protocol(), bytes in bursts()) {
        let mut d = device(1, proto);
        let before = state(&d);
        for (b, idle) in bytes {
            d.push(b);
            while d.poll().is_some() {}
            if idle {
                d.idle();
                while d.poll().is_some() {}
            }
        }
        d.idle();
        while d.poll().is_some() {}
        prop_assert_eq!(state(&d), before);
    }

    #[test]
    fn truncated_writes_change_nothing(
        (proto, write, cut) in protocol().prop_flat_map(|p| good_write(p).prop_flat_map(move |w| {
            let n = w.len();
            (Just(p), Just(w), 1..n)
        })),
    ) {
        // The whole packet does change the device (so the property below means something).
        let mut whole = device(1, proto);
        exchange(&mut whole, &write);
        let mut d = device(1, proto);
        prop_assert_ne!(state(&whole), state(&d));

        let before = state(&d);
        prop_assert!(exchange(&mut d, &write[..cut]).is_empty());
        prop_assert_eq!(state(&d), before);
        let ping = match proto {
            Protocol::V1 => p1(1, ins::PING, &[]),
            Protocol::V2 => p2(1, ins::PING, &[]),
        };
        prop_assert_eq!(exchange(&mut d, &ping).len(), 1, "the next request is answered");
    }

    #[test]
    fn a_flipped_bit_changes_nothing_even_twice(
        (proto, write, at, bit) in protocol().prop_flat_map(|p| good_write(p).prop_flat_map(move |w| {
            let n = w.len() - length_bytes(p).len();
            (Just(p), Just(w), 0..n, 0u8..8)
        })),
    ) {
        // Every byte but the length field.
        let len = length_bytes(proto);
        let at = if at >= len.start { at + len.len() } else { at };
        let mut bad = write.clone();
        bad[at] ^= 1 << bit;
        let mut d = device(1, proto);
        let before = state(&d);
        for _ in 0..2 {
            exchange(&mut d, &bad);
            prop_assert_eq!(&state(&d), &before);
        }
    }
}

#[test]
fn fuzz_case_count() {
    println!("fuzz cases per property: {}", config().cases);
}
