//! Fixed-point maths of the vsa variable-stiffness actuator (see `design.md` §2).
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
