//! The wire-unit conversions against a plain i128 reference (round half up for the
//! Q32 → integer direction, half away from zero for the other), over the whole ranges.

use proptest::prelude::*;
use service::{micro_to_q32, milli_to_q32, q32_to_micro, q32_to_milli};

fn reference_from_q32(bits: i64, scale: i128) -> i32 {
    let v = (i128::from(bits) * scale + (1 << 31)).div_euclid(1 << 32);
    v.clamp(i32::MIN.into(), i32::MAX.into()) as i32
}

fn reference_to_q32(v: i64, per: i128) -> i64 {
    let n = i128::from(v) << 32;
    let q = if n >= 0 {
        (n + per / 2) / per
    } else {
        (n - per / 2) / per
    };
    q.clamp(i64::MIN.into(), i64::MAX.into()) as i64
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(20_000))]

    #[test]
    fn q32_to_integer_units(bits in any::<i64>(), small in -(1i64 << 44)..(1i64 << 44)) {
        for b in [bits, small] {
            prop_assert_eq!(q32_to_micro(b), reference_from_q32(b, 1_000_000));
            prop_assert_eq!(q32_to_milli(b), reference_from_q32(b, 1_000));
        }
    }

    #[test]
    fn integer_units_to_q32(v in any::<i64>(), small in any::<i32>()) {
        for x in [v, i64::from(small)] {
            prop_assert_eq!(micro_to_q32(x), reference_to_q32(x, 1_000_000));
            prop_assert_eq!(milli_to_q32(x), reference_to_q32(x, 1_000));
        }
    }
}
