//! Instruction-count benchmarks of the vsa control code (issue 7).
//!
//! The library holds what the benchmark binaries share and what the host must be able to
//! test:
//!
//! * [`float`]: an f32 port of the control step (controller, supervisor, servo) and of
//!   k(L) / L(k), kept only for the fixed-vs-float comparison;
//! * [`io`]: the control step's I/O glue (driver traits → servo → H-bridge), as in the
//!   firmware;
//! * `board` (thumb targets only): the emulated boards' device crate, clock, exit and
//!   panic handler.
//!
//! The binaries (thumb only): `vsa-bench` measures, `vsa-control-only` is the control loop
//! alone for the footprint. `cargo xtask bench` builds and runs them.
#![no_std]
#![deny(missing_docs)]

#[cfg(target_os = "none")]
pub mod board;
pub mod float;
pub mod io;
