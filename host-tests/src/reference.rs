//! The reference numbers printed in `docs/design.md`, and how to compare against a printed number.

/// docs/design.md §2.2 table, as printed: L (mm), k, k_T (N·m/rad), θ at 2 N·m (°),
/// σ at 2 N·m (MPa), τ_cap (N·m).
pub const TABLE_2_2: [(i32, &str, &str, &str, &str, &str); 5] = [
    (1, "7167.5", "4680.8", "0.0160", "653", "4.59"),
    (2, "895.9", "790.9", "0.128", "1306", "2.30"),
    (3, "265.5", "250.7", "0.432", "1959", "1.53"),
    (4, "112.0", "108.4", "1.02", "2612", "1.15"),
    (5, "57.3", "56.1", "2.00", "3265", "0.92"),
];

/// Asserts that `value` rounds to `printed` at the number of decimals printed: the tolerance
/// is half a unit in the last printed digit (plus a hair for the f64 of the decimal itself).
#[track_caller]
pub fn assert_printed(what: &str, value: f64, printed: &str) {
    let expected: f64 = printed.parse().expect("printed value parses");
    let decimals = printed.split('.').nth(1).map_or(0, str::len);
    let decimals = i32::try_from(decimals).expect("few decimals");
    let tol = 0.5 * 10f64.powi(-decimals) * (1.0 + 1e-9);
    assert!(
        (value - expected).abs() <= tol,
        "{what}: {value} does not round to docs/design.md's {printed} (±{tol})"
    );
}
