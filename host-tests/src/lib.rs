//! Host-side test support for vsa: an f64 oracle written from `docs/design.md`, independent of
//! the fixed-point code in `model`.
#![forbid(unsafe_code)]

pub mod calibrate;
pub mod convert;
pub mod grid;
pub mod oracle;
pub mod reference;
pub mod sim;
