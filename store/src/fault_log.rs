//! The fault log as loaded: the last [`FAULT_LOG_LEN`] latched faults, oldest first.
//!
//! In flash it is a ring of [`FAULT_LOG_LEN`] slots, one map key each: fault number `seq`
//! goes to slot `seq % FAULT_LOG_LEN`, so logging a fault writes one small item and
//! overwrites the oldest entry. Entries numbered below the set's fault floor were cleared by
//! a factory reset and are skipped.

use heapless::Vec;

use crate::records::{FaultEntry, Rejection};

/// Entries the log keeps.
pub const FAULT_LOG_LEN: usize = 16;

/// The faults of the log, ordered by number (oldest first).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FaultLog {
    entries: Vec<FaultEntry, FAULT_LOG_LEN>,
    dropped: u8,
    first_rejection: Option<Rejection>,
}

impl FaultLog {
    /// Entries, oldest first.
    pub fn iter(&self) -> impl DoubleEndedIterator<Item = &FaultEntry> {
        self.entries.iter()
    }

    /// Number of entries.
    #[must_use]
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether the log is empty.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The most recent entry.
    #[must_use]
    pub fn latest(&self) -> Option<&FaultEntry> {
        self.entries.last()
    }

    /// Stored entries that were not loaded (undecodable, unknown version), and why the
    /// first of them was not.
    #[must_use]
    pub const fn dropped(&self) -> (u8, Option<Rejection>) {
        (self.dropped, self.first_rejection)
    }

    /// Inserts in number order (at most [`FAULT_LOG_LEN`] calls per load: one per slot).
    pub(crate) fn insert(&mut self, entry: FaultEntry) {
        let at = self
            .entries
            .iter()
            .position(|e| e.seq > entry.seq)
            .unwrap_or(self.entries.len());
        // Full only if called more than once per slot; the oldest is then the one to lose.
        if self.entries.insert(at, entry).is_err() && at > 0 {
            self.entries.remove(0);
            let _ = self.entries.insert(at - 1, entry);
        }
    }

    pub(crate) fn drop_entry(&mut self, why: Rejection) {
        self.dropped = self.dropped.saturating_add(1);
        self.first_rejection.get_or_insert(why);
    }
}
