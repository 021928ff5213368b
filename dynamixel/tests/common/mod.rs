//! Shared test support: devices over the in-memory backend, and driving them with bytes.
#![allow(dead_code)] // each test binary uses a part of this module

use dynamixel::{v1, v2, Device, MemoryBackend, Output, Protocol};

/// A device with `id` in `protocol`, every register at its default.
pub fn device(id: u8, protocol: Protocol) -> Device<MemoryBackend> {
    Device::new(MemoryBackend::new(id, protocol))
}

/// Feed `bytes` as one burst followed by an idle line; every output, in order.
pub fn exchange(d: &mut Device<MemoryBackend>, bytes: &[u8]) -> Vec<Output> {
    let mut out = Vec::new();
    for &b in bytes {
        d.push(b);
        while let Some(o) = d.poll() {
            out.push(o);
        }
    }
    d.idle();
    while let Some(o) = d.poll() {
        out.push(o);
    }
    out
}

/// A Protocol 1.0 packet.
pub fn p1(id: u8, code: u8, params: &[u8]) -> Vec<u8> {
    let mut b = vec![0; v1::MAX_PACKET];
    let n = v1::encode(id, code, params, &mut b).expect("encodable");
    b.truncate(n);
    b
}

/// A Protocol 2.0 instruction packet.
pub fn p2(id: u8, instruction: u8, params: &[u8]) -> Vec<u8> {
    let mut b = vec![0; v2::MAX_PACKET];
    let n = v2::encode(id, instruction, params, &mut b).expect("encodable");
    b.truncate(n);
    b
}

/// The status packets among `out`, decoded: (id, error byte, data), in 1.0.
pub fn status1(out: &[Output]) -> Vec<(u8, u8, Vec<u8>)> {
    let mut d = v1::Decoder::new();
    let mut r = Vec::new();
    for o in out {
        for &b in o.reply.iter().flat_map(|r| r.bytes.iter()) {
            d.push(b);
        }
        while let Some(p) = d.next() {
            let p = p.expect("a well-formed status");
            r.push((p.id, p.code, p.params.to_vec()));
        }
    }
    r
}

/// The status packets among `out`, decoded: (id, error byte, data), in 2.0.
pub fn status2(out: &[Output]) -> Vec<(u8, u8, Vec<u8>)> {
    let mut d = v2::Decoder::new();
    let mut r = Vec::new();
    for o in out {
        for &b in o.reply.iter().flat_map(|r| r.bytes.iter()) {
            d.push(b);
        }
        while let Some(p) = d.next() {
            let p = p.expect("a well-formed status");
            assert_eq!(p.instruction, v2::STATUS);
            r.push((p.id, p.params[0], p.params[1..].to_vec()));
        }
    }
    r
}
