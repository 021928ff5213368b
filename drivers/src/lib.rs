//! Driver traits (stub).
#![no_std]
