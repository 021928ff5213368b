//! How much longer than configured the hand-set clutch is taken to be (the controller's
//! and the supervisor's clutch tolerance, [`model::control::Limits::clutch_tolerance`]):
//! the configured tolerance, but never less than what the board knows of the clutch
//! (docs/calibration.md, "Until the clutch is confirmed").
//!
//! A clutch slid by hand may sit longer than configured; its beams are then weaker than
//! the supervisor believes. Until a calibration has measured the stiffness at this
//! setting, the board takes the clutch to be up to [`UNCONFIRMED_TOLERANCE_UM`] longer. A
//! calibration that resolved the clutch length L_c with a stiffness uncertainty u
//! bounds it instead: k ∝ 1/L³ (eq. 1), so a stiffness up to u lower is a clutch up to
//! (1 − u)^(−1/3) longer, which is at most 1 + u/(3·(1 − u)) (the series of the first has
//! the coefficients 1/3, 2/9, 14/81, … ≤ 1/3, those of the second).

/// The tolerance in force until a calibration confirms the clutch, µm: a clutch set by
/// hand up to 1 mm long. Measured (`cargo test -p host-tests --release --test
/// clutch_monitor`): with it, configured 1…5 mm and actual up to 1 mm longer keep the
/// beams below σ_allow in every motion; with 0.6 mm a clutch 1 mm long at 3 mm reached
/// 1.035 σ_allow under a static load and a move (docs/calibration.md).
pub const UNCONFIRMED_TOLERANCE_UM: u32 = 1000;

/// Largest stiffness uncertainty, ‰, for which a calibration bounds the clutch (beyond,
/// the bound is more than 6 % above the exact cube root).
const MAX_UNCERTAINTY_PERMILLE: u32 = 500;

/// The longest clutch, µm, that a calibration which resolved `length_um` with a stiffness
/// uncertainty of `uncertainty_permille` leaves possible: L_c·(1 + u/(3·(1 − u))), rounded
/// up.
/// `None` when it resolved no length or is too uncertain to bound it.
#[must_use]
pub fn calibrated_longest_um(length_um: Option<u32>, uncertainty_permille: u16) -> Option<u32> {
    let l = u64::from(length_um?);
    let u = u64::from(uncertainty_permille);
    if u > u64::from(MAX_UNCERTAINTY_PERMILLE) {
        return None;
    }
    // L·(1 + u/(3·(1 − u))) = L·(3000 − 2u)/(3000 − 3u) (u in ‰), rounded up.
    u32::try_from((l * (3_000 - 2 * u)).div_ceil(3_000 - 3 * u)).ok()
}

/// The clutch tolerance in force, µm: the `configured` one, and at least
/// - the distance from the configured clutch length `clutch_um` to the longest clutch the
///   calibration leaves (`calibrated_longest_um`), when that is not shorter than
///   configured;
/// - [`UNCONFIRMED_TOLERANCE_UM`] otherwise: no calibration, one that could not resolve
///   the clutch, or a clutch configured longer than the calibration found it (moved since:
///   nothing measured it there).
#[must_use]
pub fn tolerance_in_force_um(
    configured: u32,
    clutch_um: u32,
    calibrated_longest: Option<u32>,
) -> u32 {
    let known = match calibrated_longest {
        Some(longest) if longest >= clutch_um => longest - clutch_um,
        _ => UNCONFIRMED_TOLERANCE_UM,
    };
    configured.max(known)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_longest_clutch_bounds_the_cube_root() {
        // Against (1 − u)^(−1/3) in f64: never below it; above by at most 0.6 % up to
        // u = 20 %, 6 % up to 50 %.
        for u in (0..=500).step_by(5) {
            let exact = 5_000.0 * (1.0 - f64::from(u) / 1_000.0).powf(-1.0 / 3.0);
            let got = f64::from(calibrated_longest_um(Some(5_000), u as u16).unwrap());
            let slack = if u <= 200 { 0.006 } else { 0.06 };
            assert!(
                got >= exact && got <= exact * (1.0 + slack),
                "u {u}‰: {got} vs {exact}"
            );
        }
        assert_eq!(calibrated_longest_um(Some(3_000), 0), Some(3_000));
        assert_eq!(calibrated_longest_um(Some(3_000), 501), None);
        assert_eq!(calibrated_longest_um(None, 10), None);
    }

    #[test]
    fn unconfirmed_until_calibrated_at_this_setting() {
        // Nothing known: the floor, or more if configured.
        assert_eq!(tolerance_in_force_um(0, 3_000, None), 1_000);
        assert_eq!(tolerance_in_force_um(1_500, 3_000, None), 1_500);
        // Calibrated at 3 mm ± 6 % (longest 3000·2880/2820 = 3063.8, rounded up).
        let longest = calibrated_longest_um(Some(3_000), 60);
        assert_eq!(longest, Some(3_064));
        assert_eq!(tolerance_in_force_um(0, 3_000, longest), 64);
        // The calibration found the clutch 1 mm longer than configured: all of it.
        assert_eq!(tolerance_in_force_um(0, 2_000, longest), 1_064);
        // Configured at the longest the calibration allows: nothing more.
        assert_eq!(tolerance_in_force_um(0, 3_064, longest), 0);
        // Configured longer than measured: the clutch was moved since, unconfirmed again.
        assert_eq!(tolerance_in_force_um(0, 3_065, longest), 1_000);
        assert_eq!(tolerance_in_force_um(0, 5_000, longest), 1_000);
    }
}
