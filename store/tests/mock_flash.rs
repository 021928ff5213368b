//! The store on sequential-storage's own mock flash (`MockFlashBase`), a second flash model
//! written independently of ours (`RamFlash`): its power is cut after a given number of
//! *bytes* (inside a word's program and inside a page's erase, torn anywhere), and it refuses
//! a word programmed twice between erases, across power cycles too. Random histories of
//! saves, factory resets and fault-log writes, each possibly cut, never lose the last
//! completed save and never boot a mix of two sets.
//!
//! `PROPTEST_CASES` sets the number of random histories (default 64).

mod common;

use common::*;
use embassy_futures::block_on;
use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use embedded_storage_async::nor_flash as nor_async;
use proptest::prelude::*;
use sequential_storage::mock_flash::{MockFlashBase, MockFlashError, WriteCountCheck};
use store::{RangeChecks, RecordSet, Store, StoreError, PAGES, PAGE_SIZE, WORD_SIZE};

/// sequential-storage's mock with the store's geometry: 2 pages of 16 KiB, 4-byte words.
type Base = MockFlashBase<PAGES, WORD_SIZE, { PAGE_SIZE / WORD_SIZE }>;

/// The mock (async traits) seen through the blocking traits the store takes; every mock
/// operation completes in its first poll. The mock's power comes back by itself after a
/// cut; here it stays off (`dead`) until [`power_on`], as on a board.
#[derive(Clone)]
struct Mock {
    base: Base,
    dead: Option<MockFlashError>,
    /// Page erases begun since the flash was new.
    erases: u32,
}

impl Mock {
    /// Runs `op` unless the power is off; a cut turns it off.
    fn live<T>(
        &mut self,
        op: impl FnOnce(&mut Base) -> Result<T, MockFlashError>,
    ) -> Result<T, MockFlashError> {
        if let Some(e) = &self.dead {
            return Err(e.clone());
        }
        let r = op(&mut self.base);
        if let Err(e @ MockFlashError::EarlyShutoff(..)) = &r {
            self.dead = Some(e.clone());
        }
        r
    }
}

impl ErrorType for Mock {
    type Error = MockFlashError;
}

impl ReadNorFlash for Mock {
    const READ_SIZE: usize = WORD_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.live(|b| block_on(nor_async::ReadNorFlash::read(b, offset, bytes)))
    }

    fn capacity(&self) -> usize {
        nor_async::ReadNorFlash::capacity(&self.base)
    }
}

impl NorFlash for Mock {
    const WRITE_SIZE: usize = WORD_SIZE;
    const ERASE_SIZE: usize = PAGE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.erases += 1;
        self.live(|b| block_on(nor_async::NorFlash::erase(b, from, to)))
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.live(|b| block_on(nor_async::NorFlash::write(b, offset, bytes)))
    }
}

/// Power on: the flash as the cut (or the last operation) left it, bytes and the
/// programmed-once state of every word, with no cut armed; the store opened on it.
fn power_on(flash: &Mock) -> (Store<Mock>, store::Boot) {
    let mut fresh = flash.clone();
    fresh.base.bytes_until_shutoff = None;
    fresh.dead = None;
    Store::open(fresh, &RangeChecks).expect("the store opens whatever the flash holds")
}

fn empty() -> Mock {
    Mock {
        base: Base::new(WriteCountCheck::OnceOnly, None, true),
        dead: None,
        erases: 0,
    }
}

/// One step of a random history; `Some(n)` cuts the power after n more bytes.
#[derive(Clone, Debug)]
enum Op {
    Save(RecordSet, Option<u32>),
    Reset(Option<u32>),
    Fault(u32, Option<u32>),
    Reboot,
}

/// Where a cut falls: mostly inside an item's words (an item is ~50–200 bytes), sometimes
/// in a page reclaim (copying live items forward, then a 16 KiB erase).
fn cut() -> impl Strategy<Value = Option<u32>> {
    prop_oneof![
        2 => Just(None),
        3 => (0u32..300).prop_map(Some),
        1 => (0u32..(2 * PAGE_SIZE as u32)).prop_map(Some),
    ]
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        8 => (record_set(), cut()).prop_map(|(s, c)| Op::Save(s, c)),
        1 => cut().prop_map(Op::Reset),
        2 => (any::<u32>(), cut()).prop_map(|(v, c)| Op::Fault(v, c)),
        1 => Just(Op::Reboot),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn random_histories_cut_at_any_byte_never_lose_the_last_completed_save(
        prefill in 0u32..400,
        ops in proptest::collection::vec(op(), 1..40),
    ) {
        // Start anywhere in the page cycle: `prefill` completed saves, a fault every 7th.
        let (mut s, _) = Store::open(empty(), &RangeChecks).unwrap();
        for i in 0..prefill {
            s.save(&sample_set(i), &RangeChecks).unwrap();
            if i % 7 == 3 {
                s.log_fault(sample_fault(i)).unwrap();
            }
        }
        let mut flash = s.into_flash();
        let (_, boot) = power_on(&flash);
        let mut want = Expected::booted(&boot);
        for op in ops {
            let (mut s, boot) = power_on(&flash);
            assert_nothing_rejected(&boot);
            prop_assert!(want.matches(&boot), "{:?}: expected {:?}, booted {:?}", op, want, boot);
            let (cut, candidate) = match &op {
                Op::Save(set, c) => (*c, want.saved(*set)),
                Op::Reset(c) => (*c, want.reset()),
                Op::Fault(v, c) => (*c, want.logged(sample_fault(*v % 1000))),
                Op::Reboot => (None, want.clone()),
            };
            s.flash().base.bytes_until_shutoff = cut;
            let result: Result<(), StoreError> = match &op {
                Op::Save(set, _) => s.save(set, &RangeChecks).map(|_| ()),
                Op::Reset(_) => s.factory_reset(),
                Op::Fault(v, _) => s.log_fault(sample_fault(*v % 1000)).map(|seq| {
                    assert_eq!(seq, want.next_seq, "fault numbering");
                }),
                Op::Reboot => Ok(()),
            };
            let cut_fired = s.flash().dead.is_some();
            flash = s.into_flash();
            let (_, boot) = power_on(&flash);
            assert_nothing_rejected(&boot);
            match result {
                Ok(()) => {
                    prop_assert!(candidate.matches(&boot), "{:?} completed, but booted {:?}", op, boot);
                    want = candidate;
                }
                Err(e) => {
                    prop_assert!(cut_fired, "{:?} failed without a power cut: {}", op, e);
                    if candidate.matches(&boot) {
                        want = candidate; // the cut came after the item was whole
                    } else {
                        // A fault cut short is lost and its number used again.
                        prop_assert!(want.matches(&boot), "{:?}: neither old {:?} nor new {:?}: {:?}", op, want, candidate, boot);
                    }
                }
            }
        }
    }
}

/// Bytes programmed and erased (the mock counts both toward a cut) by a save of `set` on
/// `pre`.
fn bytes_of_save(pre: &Mock, set: &RecordSet) -> u32 {
    let (mut s, _) = power_on(pre);
    s.flash().base.bytes_until_shutoff = Some(u32::MAX);
    s.save(set, &RangeChecks).unwrap();
    u32::MAX - s.flash().base.bytes_until_shutoff.unwrap()
}

/// Cuts one save of `new` on `pre` after every `step`-th byte; every boot after a cut must
/// find the old set or the new one whole, and the store must save again. Returns (cuts,
/// booted old, booted new).
fn sweep_save(pre: &Mock, new: &RecordSet, step: usize) -> (u32, u32, u32) {
    let (_, before) = power_on(pre);
    let old = (before.set, before.report.generation);
    let fresh = (*new, Some(old.1.map_or(1, |g| g + 1)));
    let (mut cuts, mut olds, mut news) = (0, 0, 0);
    for n in (0..bytes_of_save(pre, new)).step_by(step) {
        let (mut s, _) = power_on(pre);
        s.flash().base.bytes_until_shutoff = Some(n);
        assert!(s.save(new, &RangeChecks).is_err(), "cut after {n} bytes");
        let (mut s, boot) = power_on(s.flash());
        assert_nothing_rejected(&boot);
        let got = (boot.set, boot.report.generation);
        if got == fresh {
            news += 1;
        } else {
            assert_eq!(got, old, "cut after {n} bytes: neither old nor new");
            olds += 1;
        }
        cuts += 1;
        let after = sample_set(9_999);
        s.save(&after, &RangeChecks).unwrap();
        assert_eq!(
            power_on(s.flash()).1.set,
            after,
            "cut after {n} bytes: save after"
        );
    }
    (cuts, olds, news)
}

#[test]
fn a_save_cut_at_every_byte_is_old_or_new_whole() {
    let (mut s, _) = Store::open(empty(), &RangeChecks).unwrap();
    // The first save, then the first that reclaims a page (cut every 7th byte in it: the
    // 16 KiB erase alone is 16 384 bytes).
    let first = sample_set(1);
    let r = sweep_save(s.flash(), &first, 1);
    eprintln!("first save: {r:?} (cuts, booted old, booted new)");
    assert!(r.1 > 0 && r.2 > 0, "{r:?}");
    let mut i = 2;
    loop {
        let pre = s.flash().clone();
        let erases = pre.erases;
        let set = sample_set(i);
        s.save(&set, &RangeChecks).unwrap();
        if s.flash().erases > erases {
            let r = sweep_save(&pre, &set, 7);
            eprintln!("save {i}, which reclaims a page: {r:?}");
            assert!(r.1 > 0 && r.2 > 0, "{r:?}");
            break;
        }
        i += 1;
    }
}
