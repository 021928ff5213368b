//! Stack high-water mark: the stack is painted with a pattern at boot ([`paint`]) and the
//! deepest word no longer holding it is found later ([`high_water`]).
//!
//! `init` builds the whole application state on the stack before RTIC moves it into its
//! statics, so the boot peak and the running peak differ: [`repaint_after_init`] (first
//! thing in `idle`) records the boot peak and paints again, and [`high_water`] reports
//! both.
//!
//! The stack is cortex-m-rt's: from `_stack_start` (the top of RAM; the initial SP) down
//! to `_stack_end` (the end of the static RAM: `.data`, `.bss`, `.uninit`). Every task and
//! interrupt handler runs on it (one main stack).

use core::ptr::{addr_of, read_volatile, write_volatile};
use core::sync::atomic::{AtomicU32, Ordering};

/// Stack used by the time `idle` started (boot, `init` included), bytes.
static BOOT_PEAK: AtomicU32 = AtomicU32::new(0);

extern "C" {
    // Linker symbols of cortex-m-rt's `link.x`: their addresses are the stack's ends.
    static _stack_start: u32;
    static _stack_end: u32;
}

/// The paint, a word unlikely to be a real stack value.
const PAINT: u32 = 0x5AC3_5AC3;

/// Words below the current stack pointer left unpainted: [`paint`]'s own frame is above
/// the stack pointer, this is a margin for anything the call itself pushes.
const MARGIN_WORDS: usize = 16;

/// Lowest address of the stack (taking an extern static's address is safe).
fn bottom() -> usize {
    addr_of!(_stack_end) as usize
}

/// The stack's top: the initial stack pointer.
fn top() -> usize {
    addr_of!(_stack_start) as usize
}

/// Paints the unused stack, from its end up to just below the current stack pointer.
/// Call it first thing in `init`, with interrupts still masked.
pub fn paint() {
    paint_below_sp();
}

/// Records the boot peak and paints the stack again below `idle`'s frame, with interrupts
/// masked while it paints (the tasks run on the same stack). Call it first thing in
/// `idle`.
///
/// Only what `init` dirtied is painted again (below that the paint is intact), so the
/// interrupts stay masked for a fraction of a control period (0.3 ms on the emulated
/// boards at icount shift 3).
pub fn repaint_after_init() {
    // The scan may see a task's frame too (interrupts are on): it only makes the repainted
    // region larger.
    let boot = used();
    BOOT_PEAK.store(boot, Ordering::Relaxed);
    cortex_m::interrupt::free(|_| paint_from(top().saturating_sub(boot as usize)));
}

fn paint_below_sp() {
    paint_from(bottom());
}

/// Paints from `from` up to just below the current stack pointer.
#[inline(always)]
fn paint_from(from: usize) {
    let sp = cortex_m::register::msp::read() as usize;
    let mut p = from.max(bottom()) & !3;
    let end = sp.saturating_sub(MARGIN_WORDS * 4);
    while p + 4 <= end {
        // SAFETY: [_stack_end, SP − margin) is RAM that nothing uses yet (below the stack
        // pointer, interrupts masked); word-aligned (cortex-m-rt aligns _stack_end to 4).
        unsafe { write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// Bytes between the stack's top and the deepest word no longer painted.
fn used() -> u32 {
    let (bottom, top) = (bottom(), top());
    let mut p = bottom;
    // SAFETY: reads words of the stack region, which is RAM, word-aligned.
    while p < top && unsafe { read_volatile(p as *const u32) } == PAINT {
        p += 4;
    }
    (top - p) as u32
}

/// Stack high-water marks, bytes.
pub struct HighWater {
    /// The deepest the stack has been since boot.
    pub peak: u32,
    /// The deepest it was during boot (`init`).
    pub boot: u32,
    /// The deepest it has been since `idle` started (the tasks).
    pub running: u32,
    /// The stack's size.
    pub size: u32,
}

/// The high-water marks so far.
pub fn high_water() -> HighWater {
    let boot = BOOT_PEAK.load(Ordering::Relaxed);
    let running = used();
    HighWater {
        peak: boot.max(running),
        boot,
        running,
        size: (top() - bottom()) as u32,
    }
}

/// Logs the high-water marks so far as one `RESULT stack` line (see `report`).
pub fn log_high_water() {
    let st = high_water();
    defmt::println!(
        "RESULT stack peak={=u32} size={=u32} boot={=u32} running={=u32}",
        st.peak,
        st.size,
        st.boot,
        st.running
    );
}
