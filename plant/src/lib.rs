//! Simulated actuator standing in for the real servo (see `design.md` §3).
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
