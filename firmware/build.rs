//! Links the programs with cortex-m-rt's `link.x` and defmt's `defmt.x`, with the
//! workspace root (where the one `memory.x` lives) on the linker search path. Also encodes
//! the control-only image's scripted host requests (`$OUT_DIR/script.bin`) with the
//! protocol crate on the host, so that the image carries no request encoder (the real
//! firmware only decodes requests).
use std::{env, path::PathBuf};

use protocol::{encode_to_vec, Frame, Gains, Limits, Request};

/// The requests `vsa-control-only` handles from its tenth tick on.
const SCRIPT: [Request; 7] = [
    Request::SetStiffness {
        stiffness_mnm_per_rad: 895_900,
    },
    Request::SetLimits(Limits::DEFAULT),
    Request::SetGains(Gains {
        kp: 2_000_000,
        ki: 0,
        kd: 10_000,
    }),
    Request::AutoGains,
    Request::Enable,
    Request::Move {
        target_urad: 0,
        duration_ms: 200,
    },
    Request::StreamTelemetry { rate_hz: 500 },
];

fn main() {
    let manifest_dir = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let root = manifest_dir
        .parent()
        .expect("firmware/ lives inside the workspace");
    println!("cargo:rustc-link-search={}", root.display());
    println!("cargo:rerun-if-changed={}", root.join("memory.x").display());
    println!("cargo:rerun-if-changed=build.rs");

    let mut script = Vec::new();
    for (seq, req) in (1..).zip(SCRIPT) {
        let frame = encode_to_vec(&Frame::new(seq, req)).expect("the script's requests encode");
        script.extend_from_slice(&frame);
    }
    // The count first, then the frames.
    script.insert(0, SCRIPT.len() as u8);
    let out = PathBuf::from(env::var("OUT_DIR").expect("set by cargo"));
    std::fs::write(out.join("script.bin"), script).expect("writing script.bin");

    // Only the thumb targets link the programs (the host never builds this crate).
    let target = env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumb") {
        println!("cargo:rustc-link-arg=--nmagic");
        println!("cargo:rustc-link-arg=-Tlink.x");
        println!("cargo:rustc-link-arg=-Tdefmt.x");
    }
}
