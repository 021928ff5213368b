//! `cargo xtask`: set-up, build, run and test automation for vsa.
fn main() {}
