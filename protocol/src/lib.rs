//! Command and telemetry protocol (stub, being written).
#![no_std]
