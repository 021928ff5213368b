//! Power cuts: a save, a factory reset or a fault-log write cut after every one of its word
//! writes (and in each of its erases) leaves a store that opens with the complete old or the
//! complete new state, never a mix, never a rejected value; random sequences of saves, cuts,
//! resets and faults never lose the last completed save.
//!
//! `PROPTEST_CASES` sets the number of random sequences (default 64);
//! `STORE_SWEEP_ERASING` the number of page-reclaiming saves swept (default 2).

mod common;

use common::*;
use proptest::prelude::*;
use store::{PowerCut, RangeChecks, RecordSet, Store, StoreError};

/// Which side of the cut a reboot found.
#[derive(Debug, Default)]
struct Sweep {
    cuts: u32,
    old: u32,
    new: u32,
}

/// The flash after `saves` saves from empty, with a fault logged every 7th.
fn history(saves: u32) -> Flash {
    let (mut s, _) = Store::open(Flash::new(), &RangeChecks).unwrap();
    for i in 0..saves {
        s.save(&sample_set(i), &RangeChecks).unwrap();
        if i % 7 == 3 {
            s.log_fault(sample_fault(i)).unwrap();
        }
    }
    s.into_flash()
}

/// Words written and erases done by `op` on the store opened on `pre` (no cut).
fn measure(pre: &Flash, op: &dyn Fn(&mut FlashStore)) -> (u64, u32) {
    let (mut s, _) = reboot(pre);
    let (w, e) = (s.flash().words_written(), erases(s.flash()));
    op(&mut s);
    (s.flash().words_written() - w, erases(s.flash()) - e)
}

fn erases(f: &Flash) -> u32 {
    f.erase_counts().iter().sum()
}

/// Runs `op` on `pre` with the power cut after every possible word write (0 to all of
/// them: the last cut lets the operation complete and cuts right after) and in every
/// erase; after each cut, reboots and hands the boot to `check` (which says old or new),
/// then checks the store still saves and loads.
fn sweep(
    pre: &Flash,
    op: &dyn Fn(&mut FlashStore) -> Result<(), StoreError>,
    check: &dyn Fn(&store::Boot) -> bool,
) -> Sweep {
    let (words, erase_ops) = measure(pre, &|s| op(s).unwrap());
    let cuts = (0..=words)
        .map(|n| PowerCut::AfterWrites(n as u32))
        .chain((0..erase_ops).map(PowerCut::InErase));
    let mut out = Sweep::default();
    for cut in cuts {
        let (mut s, _) = reboot(pre);
        s.flash().arm(cut);
        let completed = op(&mut s).is_ok();
        assert_eq!(
            completed,
            cut == PowerCut::AfterWrites(words as u32),
            "{cut:?}"
        );
        assert!(s.flash().power_lost());
        let (mut s, boot) = reboot(s.flash());
        assert_nothing_rejected(&boot);
        if check(&boot) {
            out.new += 1;
        } else {
            out.old += 1;
        }
        out.cuts += 1;
        // The store works after the cut: a save lands and loads.
        let after = sample_set(9_999);
        s.save(&after, &RangeChecks).unwrap();
        let (_, boot) = reboot(s.flash());
        assert_eq!(boot.set, after, "{cut:?}: save after the cut");
    }
    out
}

/// Sweeps one save on `pre`: the boot after each cut has the old set or the new one whole,
/// with its own generation, and the fault log untouched.
fn sweep_save(pre: &Flash, new: &RecordSet) -> Sweep {
    let (_, before) = reboot(pre);
    let old = before.set;
    let old_faults = faults(&before);
    let old_gen = before.report.generation;
    let new_gen = Some(old_gen.map_or(1, |g| g + 1));
    sweep(pre, &|s| s.save(new, &RangeChecks).map(|_| ()), &|boot| {
        assert_eq!(faults(boot), old_faults, "fault log changed by a save");
        if boot.set == *new && boot.report.generation == new_gen {
            true
        } else {
            assert_eq!(
                (boot.set, boot.report.generation),
                (old, old_gen),
                "neither old nor new"
            );
            false
        }
    })
}

#[test]
fn a_save_cut_at_every_word_and_erase_is_old_or_new_whole() {
    // Sweep the first save, one in the middle of a page, and the first saves that have to
    // erase a page (reclaiming it: live items copied forward first): 2 by default,
    // `STORE_SWEEP_ERASING` for more (each takes seconds).
    let erasing_wanted: u32 = std::env::var("STORE_SWEEP_ERASING")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2);
    let mut total = Sweep::default();
    let (mut erasing, mut swept) = (0, 0);
    let (mut s, _) = Store::open(Flash::new(), &RangeChecks).unwrap();
    let mut i = 0;
    while erasing < erasing_wanted {
        let pre = Flash::from_bytes(s.flash().as_bytes()).unwrap();
        let new = sample_set(i + 100);
        let e = erases(s.flash());
        s.save(&new, &RangeChecks).unwrap();
        let erased = erases(s.flash()) > e;
        if i == 0 || i == 40 || erased {
            let r = sweep_save(&pre, &new);
            eprintln!("save {i}: {r:?}");
            assert!(r.old > 0 && r.new == 1, "save {i}: {r:?}");
            total.cuts += r.cuts;
            total.old += r.old;
            total.new += r.new;
            erasing += u32::from(erased);
            swept += 1;
        }
        if i % 7 == 3 {
            s.log_fault(sample_fault(i)).unwrap();
        }
        i += 1;
    }
    eprintln!(
        "save sweep: {} cuts over {swept} saves swept of {i} ({erasing} of them erasing), {} booted old, {} new",
        total.cuts,
        total.old,
        total.new
    );
    assert!(total.old > 0 && total.new > 0);
}

#[test]
fn a_factory_reset_cut_at_every_word_is_old_or_empty_whole() {
    for saves in [1, 30] {
        let pre = history(saves);
        let (_, before) = reboot(&pre);
        let old = before.set;
        let old_faults = faults(&before);
        assert!(old.config.is_some() && (saves < 4 || !old_faults.is_empty()));
        let r = sweep(&pre, &|s| s.factory_reset(), &|boot| {
            if boot.set == RecordSet::default() && boot.faults.is_empty() {
                true
            } else {
                assert_eq!((boot.set, faults(boot)), (old, old_faults.clone()), "a mix");
                false
            }
        });
        eprintln!("factory-reset sweep after {saves} saves: {r:?}");
        assert!(r.old > 0 && r.new > 0, "{r:?}");
    }
}

#[test]
fn a_fault_write_cut_at_every_word_loses_at_most_that_fault() {
    let pre = history(20);
    let (_, before) = reboot(&pre);
    let old_faults = faults(&before);
    let r = sweep(
        &pre,
        &|s| s.log_fault(sample_fault(77)).map(|_| ()),
        &|boot| {
            assert_eq!(boot.set, before.set);
            let now = faults(boot);
            if now == old_faults {
                false
            } else {
                assert_eq!(
                    &now[..now.len() - 1],
                    &old_faults[..],
                    "older entries changed"
                );
                assert_eq!(now.last().map(|e| e.fault), Some(sample_fault(77)));
                true
            }
        },
    );
    eprintln!("fault-log sweep: {r:?}");
    assert!(r.old > 0 && r.new > 0);
}

#[test]
fn the_fault_log_keeps_the_last_16_in_order_across_boots_and_resets() {
    let (mut s, _) = Store::open(Flash::new(), &RangeChecks).unwrap();
    for i in 0..20 {
        assert_eq!(s.log_fault(sample_fault(i)).unwrap(), i);
    }
    let (mut s, boot) = reboot(s.flash());
    let got: Vec<_> = boot.faults.iter().map(|e| (e.seq, e.fault)).collect();
    let want: Vec<_> = (4..20).map(|i| (i, sample_fault(i))).collect();
    assert_eq!(got, want);
    assert_eq!(boot.report.faults, store::Outcome::Loaded);
    s.factory_reset().unwrap();
    let (mut s, boot) = reboot(s.flash());
    assert!(boot.faults.is_empty());
    assert_eq!(boot.report.faults, store::Outcome::Default);
    assert_eq!(
        s.log_fault(sample_fault(1)).unwrap(),
        20,
        "numbering goes on after a reset"
    );
    let (_, boot) = reboot(s.flash());
    assert_eq!(boot.faults.iter().map(|e| e.seq).collect::<Vec<_>>(), [20]);
}

/// One step of a random history.
#[derive(Clone, Debug)]
enum Op {
    Save(RecordSet),
    /// Save with the power cut after this many word writes.
    CutSave(RecordSet, u8),
    /// Save with the power cut in the n-th erase (if it erases that often).
    CutEraseSave(RecordSet, u8),
    Reset,
    CutReset(u8),
    Fault(u32),
    Reboot,
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        6 => record_set().prop_map(Op::Save),
        6 => (record_set(), 0u8..80).prop_map(|(s, n)| Op::CutSave(s, n)),
        1 => (record_set(), 0u8..2).prop_map(|(s, n)| Op::CutEraseSave(s, n)),
        1 => Just(Op::Reset),
        1 => (0u8..40).prop_map(Op::CutReset),
        2 => any::<u32>().prop_map(Op::Fault),
        1 => Just(Op::Reboot),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn random_saves_and_cuts_never_lose_the_last_completed_save(
        prefill in 0u32..300,
        ops in proptest::collection::vec(op(), 1..60),
    ) {
        // Start anywhere in the page cycle: `prefill` saves and some faults first.
        let mut flash = history(prefill);
        let (_, boot) = reboot(&flash);
        let mut want = Expected::booted(&boot);
        for op in ops {
            let (mut s, boot) = reboot(&flash);
            assert_nothing_rejected(&boot);
            prop_assert!(want.matches(&boot), "{op:?}: expected {want:?}, booted {boot:?}");
            let (cut, candidate) = match &op {
                Op::Save(set) => (None, want.saved(*set)),
                Op::CutSave(set, n) => (Some(PowerCut::AfterWrites(u32::from(*n))), want.saved(*set)),
                Op::CutEraseSave(set, n) => (Some(PowerCut::InErase(u32::from(*n))), want.saved(*set)),
                Op::Reset => (None, want.reset()),
                Op::CutReset(n) => (Some(PowerCut::AfterWrites(u32::from(*n))), want.reset()),
                Op::Fault(_) | Op::Reboot => (None, want.clone()),
            };
            if let Some(cut) = cut {
                s.flash().arm(cut);
            }
            let result = match &op {
                Op::Save(set) | Op::CutSave(set, _) | Op::CutEraseSave(set, _) => {
                    s.save(set, &RangeChecks).map(|_| ())
                }
                Op::Reset | Op::CutReset(_) => s.factory_reset(),
                Op::Fault(v) => {
                    let fault = sample_fault(*v % 1000);
                    let seq = s.log_fault(fault).unwrap();
                    prop_assert_eq!(seq, want.next_seq);
                    want = want.logged(fault);
                    Ok(())
                }
                Op::Reboot => Ok(()),
            };
            match result {
                Ok(()) => {
                    // Completed (the cut, if armed, came after its last write or never).
                    if !matches!(op, Op::Fault(_)) {
                        want = candidate;
                    }
                }
                Err(e) => {
                    prop_assert!(cut.is_some() && s.flash().power_lost(), "{op:?}: {e}");
                    let (_, boot) = reboot(s.flash());
                    assert_nothing_rejected(&boot);
                    if candidate.matches(&boot) {
                        want = candidate; // the cut came after the item was whole
                    } else {
                        prop_assert!(want.matches(&boot), "{op:?}: neither old {want:?} nor new {candidate:?}: {boot:?}");
                    }
                }
            }
            flash = Flash::from_bytes(s.flash().as_bytes()).unwrap();
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    /// Whatever the flash holds (random bytes, all zeros), the store opens, loads without
    /// applying anything it cannot decode and check, and a factory reset makes it usable.
    #[test]
    fn any_flash_contents_boot_and_a_factory_reset_recovers(
        seed in any::<u64>(),
        zeros in any::<bool>(),
    ) {
        let mut bytes = vec![0u8; Flash::SIZE];
        if !zeros {
            let mut x = seed | 1;
            for b in &mut bytes {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                *b = x as u8;
            }
        }
        let flash = Flash::from_bytes(&bytes).unwrap();
        let (mut s, boot) = Store::open(flash, &RangeChecks).unwrap();
        // Nothing in random bytes passes the items' CRCs: nothing is applied.
        for (name, outcome) in boot.report.lines() {
            prop_assert!(outcome != store::Outcome::Loaded, "{}", name);
        }
        prop_assert_eq!(boot.set, RecordSet::default());
        s.factory_reset().unwrap();
        let set = sample_set(5);
        s.save(&set, &RangeChecks).unwrap();
        let (_, boot) = reboot(s.flash());
        assert_nothing_rejected(&boot);
        prop_assert_eq!(boot.set, set);
    }
}
