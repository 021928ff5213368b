//! 1 000 saves in a row do not exhaust the store, and the erases spread over its pages.

mod common;

use common::*;
use store::{RangeChecks, Store, PAGES, PAGE_SIZE};

#[test]
fn a_thousand_saves_fit_and_wear_both_pages_evenly() {
    let (mut s, _) = Store::open(Flash::new(), &RangeChecks).unwrap();
    let mut first_erase_at = None;
    for i in 0..1_000 {
        let generation = s.save(&sample_set(i), &RangeChecks).unwrap();
        assert_eq!(generation, i + 1);
        if i % 50 == 0 {
            s.log_fault(sample_fault(i)).unwrap();
        }
        if first_erase_at.is_none() && s.flash().erase_counts().iter().any(|&n| n > 0) {
            first_erase_at = Some(i + 1);
        }
    }
    let counts = *s.flash().erase_counts();
    let words = s.flash().words_written();
    eprintln!(
        "1000 saves (+20 faults logged) on {PAGES} × {PAGE_SIZE} B: page erase counts {counts:?}, \
         first erase at save {first_erase_at:?}, {words} words written ({} B per save on average)",
        words * 4 / 1_000
    );
    // Every page was erased, and none more than once more than another.
    let (min, max) = (counts.iter().min().unwrap(), counts.iter().max().unwrap());
    assert!(*min > 0 && max - min <= 1, "{counts:?}");
    // The last save is what boots, with the fault log's last 16.
    let (_, boot) = reboot(s.flash());
    assert_nothing_rejected(&boot);
    assert_eq!(boot.set, sample_set(999));
    assert_eq!(boot.report.generation, Some(1_000));
    let seqs: Vec<u32> = boot.faults.iter().map(|e| e.seq).collect();
    assert_eq!(seqs, (4..20).collect::<Vec<_>>());
    assert_eq!(boot.faults.latest().unwrap().fault, sample_fault(950));
}
