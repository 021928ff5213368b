//! Host-side test support for vsa: an f64 oracle written from `docs/design.md`, independent of
//! the fixed-point code in `model`.
#![forbid(unsafe_code)]

pub mod calibrate;
pub mod convert;
pub mod grid;
pub mod grid_tally;
pub mod oracle;
pub mod reference;
pub mod sim;

/// The number in environment variable `name`, or `default` when it is unset or not a
/// number (the long runs' sizes and seeds).
#[must_use]
pub fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}
