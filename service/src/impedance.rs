//! [`protocol::Request::Impedance`] over the servo: wire units to the model's
//! [`ImpedanceCommand`] (µrad → rad, mN·m/rad → N·m/rad, µN·m·s/rad → N·m·s/rad,
//! µN·m → N·m, exact integer scalings), the target checked against the position window,
//! then [`model::servo::Servo::impedance`], which refuses a virtual stiffness above the
//! beams' at the clutch setting.

use fixed::types::I32F32;
use model::control::ImpedanceCommand;
use model::servo::ServoState;
use model::{Stiffness, Torque};
use protocol::ErrorCode;
use rtic_core::Mutex;

use crate::{micro_to_q32, refused, Actuator, ServiceDevice};

/// Carries out the request on `dev` (see the module docs); only while enabled.
pub(crate) fn apply<M: Mutex<T = Actuator>>(
    dev: &mut ServiceDevice<'_, M>,
    target_urad: i32,
    stiffness_mnm_per_rad: u32,
    damping_unms_per_rad: u32,
    torque_unm: i32,
) -> Result<(), ErrorCode> {
    let cmd = ImpedanceCommand {
        target: dev.target(target_urad)?,
        // mN·m/rad = 1000 µN·m/rad.
        stiffness: Stiffness::from_micro(i64::from(stiffness_mnm_per_rad) * 1_000),
        damping: I32F32::from_bits(micro_to_q32(damping_unms_per_rad.into())),
        torque: Torque::from_bits(micro_to_q32(torque_unm.into())),
    };
    dev.actuator.lock(|a| {
        if a.servo.state() != ServoState::Enabled {
            return Err(ErrorCode::NotAllowed);
        }
        a.servo.impedance(&cmd).map_err(refused)
    })
}
