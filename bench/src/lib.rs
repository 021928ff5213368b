//! The f32 port of the vsa control step (controller, supervisor, servo) and of k(L) / L(k),
//! kept only as the reference of the fixed-vs-float instruction counts: the firmware's
//! `vsa-bench` program times both on the emulated boards, and host-tests checks that the
//! port computes what the fixed-point model does.
#![no_std]
#![deny(missing_docs)]

pub mod float;
