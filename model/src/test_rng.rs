//! Reproducible pseudo-random draws for the unit tests, without a dependency: xorshift64
//! (Marsaglia's shifts 13, 7, 17).

/// A xorshift64 generator from `seed` (≠ 0).
pub(crate) fn xorshift(mut state: u64) -> impl FnMut() -> u64 {
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    }
}
