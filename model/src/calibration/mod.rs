//! Bring-up of a real build (docs/calibration.md, docs/design.md §9): the sensor-correction
//! layer between the raw readings and the servo ([`correction`]) and the calibration
//! sequence that finds what it needs ([`sequence`]).

pub mod correction;
pub mod pipeline;
pub mod pot_error;
pub mod sequence;
