//! `vsa impedance 0.3rad --stiffness 20Nm/rad --damping 0.2Nms/rad [--torque 0.1Nm]`: the
//! board holds the link at the target as a spring-damper softer than the clutch setting
//! (`protocol::Request::Impedance`). A stiffness above the joint's is refused by the board;
//! the refusal is explained with the board's stiffness and position window.

use clap::Args;
use client::{urad_text, ErrorCode};

use super::quantities::{self, show};
use super::{out, Session};
use crate::error::{CliError, CliResult};

/// Arguments of `impedance`.
#[derive(Args, Debug, Clone)]
pub struct ImpedanceArgs {
    /// Target link angle (rad, mrad, urad or deg), |·| ≤ 2.54 rad and inside the board's
    /// position window
    #[arg(value_name = "ANGLE", allow_hyphen_values = true)]
    pub target: String,
    /// Virtual stiffness, e.g. 20Nm/rad: at least 0.1 N·m/rad, at most the joint's at the
    /// clutch setting
    #[arg(long, value_name = "STIFFNESS", allow_hyphen_values = true)]
    pub stiffness: String,
    /// Virtual damping, e.g. 0.2Nms/rad, 0–100 N·m·s/rad
    #[arg(long, value_name = "DAMPING", allow_hyphen_values = true)]
    pub damping: String,
    /// Feed-forward torque, e.g. 0.1Nm, |·| ≤ 100 N·m
    #[arg(
        long,
        value_name = "TORQUE",
        default_value = "0Nm",
        allow_hyphen_values = true
    )]
    pub torque: String,
}

/// The checked arguments, in wire units.
#[derive(Debug, Clone, Copy)]
pub struct Plan {
    target_urad: i32,
    stiffness_mnm_per_rad: u32,
    damping_unms_per_rad: u32,
    torque_unm: i32,
}

/// Checks the arguments (errors name the argument).
pub fn plan(a: &ImpedanceArgs) -> CliResult<Plan> {
    Ok(Plan {
        target_urad: quantities::angle_urad("impedance", &a.target)?,
        stiffness_mnm_per_rad: quantities::virtual_stiffness_mnm_per_rad(
            "impedance --stiffness",
            &a.stiffness,
        )?,
        damping_unms_per_rad: quantities::damping_unms_per_rad("impedance --damping", &a.damping)?,
        torque_unm: quantities::feed_forward_unm("impedance --torque", &a.torque)?,
    })
}

/// Sends the command and prints what the board now does.
pub fn run(s: &mut Session, p: &Plan) -> CliResult<()> {
    let sent = s.client.impedance(
        p.target_urad,
        p.stiffness_mnm_per_rad,
        p.damping_unms_per_rad,
        p.torque_unm,
    );
    match sent {
        Ok(()) => {
            out(&format!(
                "holding {} rad with k = {} N·m/rad, d = {} N·m·s/rad, τ_ff = {} N·m\n",
                show(p.target_urad.into(), 6),
                show(p.stiffness_mnm_per_rad.into(), 3),
                show(p.damping_unms_per_rad.into(), 6),
                show(p.torque_unm.into(), 6)
            ));
            Ok(())
        }
        Err(client::Error::Refused {
            code: ErrorCode::OutOfRange,
            ..
        }) => Err(refusal(s, p)),
        Err(e) => Err(s.fail(&e)),
    }
}

/// Why the board answered out of range: the stiffness above the joint's, or the target
/// outside the position window (both asked from the board).
fn refusal(s: &mut Session, p: &Plan) -> CliError {
    let status = match s.client.status() {
        Ok(st) => st,
        Err(e) => return s.fail(&e),
    };
    if p.stiffness_mnm_per_rad > status.stiffness_mnm_per_rad {
        return CliError::runtime(format!(
            "the board refused impedance: virtual stiffness {} N·m/rad is above the joint's \
             k = {} N·m/rad at the clutch length {} mm (a shorter clutch length makes the \
             joint stiffer)",
            show(p.stiffness_mnm_per_rad.into(), 3),
            show(status.stiffness_mnm_per_rad.into(), 3),
            show(status.clutch_length_um.into(), 3)
        ));
    }
    match s.client.limits() {
        Ok(l) => CliError::runtime(format!(
            "the board refused impedance: target {} is outside the position window [{}, {}] \
             rad",
            urad_text(p.target_urad.into()),
            show(l.position_min_urad.into(), 6),
            show(l.position_max_urad.into(), 6)
        )),
        Err(e) => s.fail(&e),
    }
}
