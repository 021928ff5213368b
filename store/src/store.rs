//! The store: the record set and the fault log in a sequential-storage map on a flash.

use embassy_futures::block_on;
use embedded_storage::nor_flash::NorFlash;
use protocol::FaultRecord;
use sequential_storage::cache::key_pointers::ArrayKeyPointers;
use sequential_storage::cache::page_pointers::ArrayPagePointers;
use sequential_storage::cache::page_states::ArrayPageStates;
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage};
use serde::{Deserialize, Serialize};

use crate::blocking::Blocking;
use crate::fault_log::{FaultLog, FAULT_LOG_LEN};
use crate::records::{self, BusSettings, Calibration, Config, FaultEntry, Record, Rejection};
use crate::PAGES;

/// Map key of the record set.
const SET_KEY: u8 = 1;
/// Map key of fault-log slot 0 (slots are `FAULT_KEY_BASE..FAULT_KEY_BASE + 16`).
const FAULT_KEY_BASE: u8 = 0x10;
/// Format of the set item's envelope (the records inside carry their own versions).
const SET_FORMAT: u8 = 1;

/// Largest stored config record, bytes: version 1 + clutch (tag 1 + u32 5) + inertia 5 +
/// gains (1 + 3 × u64 10) + limits (3 + 3 + 5 + 3 + 5 + 5 + 3) + timeout 5 (postcard
/// varints).
pub const CONFIG_MAX: usize = 1 + 6 + 5 + 31 + 27 + 5;
/// Largest stored calibration record, bytes: version 1 + 3 signs (1 each) + 2 offsets
/// (i16 varint 3) + 4 × u32 5 + 2 × `Option<u32>` 6 + u16 3, then (version 2) encoder
/// counts (u16 3) + 2 gains (u32 5) + the pot error table (`Option<[u16; 16]>` 1 + 48).
pub const CALIBRATION_MAX: usize = 1 + 3 + 6 + 20 + 12 + 3 + 3 + 10 + 49;
/// Largest stored bus record, bytes: version 1 + ID 1 + baud 5 + 3 × u8 + 2 × u16 3, and
/// the limits: 5 × u8 + 4 × u16 3.
pub const BUS_MAX: usize = 1 + 1 + 5 + 3 + 6 + 5 + 12;
/// Largest stored fault entry, bytes: version 1 + seq 5 + code 1 + value 5 + tick 5.
pub const FAULT_MAX: usize = 1 + 5 + 1 + 5 + 5;
/// Largest set item, bytes: format 1 + generation 5 + fault floor 5 + each record with its
/// length byte.
pub const SET_ITEM_MAX: usize =
    1 + 5 + 5 + (1 + CONFIG_MAX) + (1 + CALIBRATION_MAX) + (1 + BUS_MAX);

/// The map's working buffer: key (1 byte) and the largest item, rounded up to a word.
const WORK_LEN: usize = 256;
const _: () = assert!(SET_ITEM_MAX < WORK_LEN && FAULT_MAX < WORK_LEN);

/// The records saved and loaded together, atomically (one map item). `None`: not stored
/// (the firmware's defaults apply).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RecordSet {
    /// The active configuration.
    pub config: Option<Config>,
    /// The calibration.
    pub calibration: Option<Calibration>,
    /// The bus identity and settings.
    pub bus: Option<BusSettings>,
}

/// What the device adds to each record's own range checks ([`Record::check`], the
/// protocol's): checks that need the design or the hardware (the clutch length the design
/// reaches, L(k), a baud rate the UART makes). Every method defaults to "no further check".
pub trait Validator {
    /// Device checks of a config.
    ///
    /// # Errors
    /// Why the config cannot be applied, as a short phrase for the log.
    fn config(&self, _config: &Config) -> Result<(), &'static str> {
        Ok(())
    }
    /// Device checks of a calibration.
    ///
    /// # Errors
    /// Why the calibration cannot be applied.
    fn calibration(&self, _calibration: &Calibration) -> Result<(), &'static str> {
        Ok(())
    }
    /// Device checks of the bus settings.
    ///
    /// # Errors
    /// Why the settings cannot be applied.
    fn bus(&self, _bus: &BusSettings) -> Result<(), &'static str> {
        Ok(())
    }
}

/// Only the records' own range checks (the host tests; a board with nothing to add).
#[derive(Clone, Copy, Debug, Default)]
pub struct RangeChecks;

impl Validator for RangeChecks {}

/// Why the flash did not do what the store asked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FlashFault {
    /// The flash driver returned an error (on the emulated boards: also a power cut).
    Driver,
    /// No room even after reclaiming pages (the live data outgrew the store).
    Full,
    /// sequential-storage found state it could not repair.
    Corrupted,
    /// A buffer or serialization error inside sequential-storage (a defect).
    Internal,
}

impl core::fmt::Display for FlashFault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FlashFault::Driver => "driver error",
            FlashFault::Full => "store full",
            FlashFault::Corrupted => "corrupted beyond repair",
            FlashFault::Internal => "internal error",
        })
    }
}

fn flash_fault<E>(e: &sequential_storage::Error<E>) -> FlashFault {
    match e {
        sequential_storage::Error::Storage { .. } => FlashFault::Driver,
        sequential_storage::Error::FullStorage => FlashFault::Full,
        sequential_storage::Error::Corrupted { .. } => FlashFault::Corrupted,
        _ => FlashFault::Internal,
    }
}

/// Why a store operation failed (nothing is half-done: the stored set is the old one or,
/// after a power cut, the old or the new one, whole).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StoreError {
    /// The flash is not [`PAGES`] erase pages that each hold an item: a board definition
    /// error.
    Layout,
    /// The flash failed.
    Flash(FlashFault),
    /// A record fails its checks; nothing was written.
    Invalid {
        /// [`Record::NAME`] of the record.
        record: &'static str,
        /// Which check.
        reason: &'static str,
    },
}

impl core::fmt::Display for StoreError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            StoreError::Layout => f.write_str("flash geometry unsuitable for the store"),
            StoreError::Flash(e) => write!(f, "flash: {e}"),
            StoreError::Invalid { record, reason } => write!(f, "{record}: {reason}"),
        }
    }
}

impl core::error::Error for StoreError {}

/// What became of one record at load.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Outcome {
    /// Stored, decoded and valid: applied.
    Loaded,
    /// Nothing stored: defaults.
    #[default]
    Default,
    /// Stored but not applied (defaults instead), and why.
    Rejected(Rejection),
}

impl core::fmt::Display for Outcome {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Outcome::Loaded => f.write_str("loaded"),
            Outcome::Default => f.write_str("nothing stored, defaults"),
            Outcome::Rejected(why) => write!(f, "rejected ({why}), defaults"),
        }
    }
}

/// One outcome per record, for the boot log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Report {
    /// Number of the stored set (saves and resets since the store was empty), if one was
    /// read.
    pub generation: Option<u32>,
    /// The config record.
    pub config: Outcome,
    /// The calibration record.
    pub calibration: Outcome,
    /// The bus record.
    pub bus: Outcome,
    /// The fault log: loaded if it has an entry, rejected if every stored entry was.
    pub faults: Outcome,
}

impl Report {
    /// `(record name, outcome)`, one per record: one log line each.
    #[must_use]
    pub const fn lines(&self) -> [(&'static str, Outcome); 4] {
        [
            (Config::NAME, self.config),
            (Calibration::NAME, self.calibration),
            (BusSettings::NAME, self.bus),
            (FaultEntry::NAME, self.faults),
        ]
    }
}

/// What a load found.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Boot {
    /// The records to apply (only loaded ones are `Some`).
    pub set: RecordSet,
    /// What became of each.
    pub report: Report,
    /// The fault log.
    pub faults: FaultLog,
}

/// The set item's envelope; each record inside is `[version] ++ postcard` (or empty).
#[derive(Serialize, Deserialize)]
struct SetBody<'a> {
    generation: u32,
    fault_floor: u32,
    config: &'a [u8],
    calibration: &'a [u8],
    bus: &'a [u8],
}

#[repr(align(4))]
struct Work([u8; WORK_LEN]);

/// Keys in use: the set and the fault-log slots.
const KEYS: usize = 1 + FAULT_LOG_LEN;

/// Page states, page pointers and the location of every key, in RAM (≈ 110 bytes): a
/// lookup goes straight to its item instead of scanning pages, which matters most when a
/// page is reclaimed (each item on it is looked up). Built afresh at every open.
type MapCache =
    Cache<ArrayPageStates<PAGES>, ArrayPagePointers<PAGES>, ArrayKeyPointers<u8, KEYS>, u8>;

type Map<F> = MapStorage<u8, Blocking<F>, MapCache>;

/// The settings store on one flash region (offsets `0..capacity`, whole erase pages).
pub struct Store<F: NorFlash> {
    map: Map<F>,
    work: Work,
    stored: RecordSet,
    generation: u32,
    fault_floor: u32,
    next_fault_seq: u32,
}

impl<F: NorFlash> Store<F> {
    /// Opens the store on `flash` and loads it ([`Store::load`]): never fails because of
    /// what the flash holds.
    ///
    /// # Errors
    /// [`StoreError::Layout`] unless the flash is [`PAGES`] erase pages (of a size that
    /// holds an item): the one layout of every board.
    pub fn open(flash: F, checks: &impl Validator) -> Result<(Self, Boot), StoreError> {
        if flash.capacity() != PAGES * F::ERASE_SIZE {
            return Err(StoreError::Layout);
        }
        let end = u32::try_from(PAGES * F::ERASE_SIZE).map_err(|_| StoreError::Layout)?;
        let config = MapConfig::try_new(0..end).map_err(|_| StoreError::Layout)?;
        let cache = Cache::new(
            ArrayPageStates::new(),
            ArrayPagePointers::new(),
            ArrayKeyPointers::new(),
        );
        let mut store = Self {
            map: MapStorage::new(Blocking(flash), config, cache),
            work: Work([0; WORK_LEN]),
            stored: RecordSet::default(),
            generation: 0,
            fault_floor: 0,
            next_fault_seq: 0,
        };
        let boot = store.load(checks);
        Ok((store, boot))
    }

    /// The flash (the emulated boards snapshot it after each operation).
    pub fn flash(&mut self) -> &mut F {
        &mut self.map.flash().0
    }

    /// Closes the store, giving the flash back.
    pub fn into_flash(self) -> F {
        self.map.destroy().0 .0
    }

    /// The set as stored (loaded records, or the last saved), to compare with the running
    /// one.
    #[must_use]
    pub const fn stored(&self) -> &RecordSet {
        &self.stored
    }

    /// Reads the record set and the fault log: each record decoded by its version, checked
    /// ([`Record::check`], then `checks`), and applied only if all that passes.
    pub fn load(&mut self, checks: &impl Validator) -> Boot {
        let mut boot = Boot::default();
        self.generation = 0;
        self.fault_floor = 0;
        match block_on(self.map.fetch_item::<&[u8]>(&mut self.work.0, &SET_KEY)) {
            Ok(None) => {}
            Ok(Some(bytes)) => {
                if let Some((generation, floor)) = decode_set(bytes, checks, &mut boot) {
                    self.generation = generation;
                    self.fault_floor = floor;
                    boot.report.generation = Some(generation);
                }
            }
            Err(e) => {
                let r = Outcome::Rejected(Rejection::Flash(flash_fault(&e)));
                (boot.report.config, boot.report.calibration, boot.report.bus) = (r, r, r);
            }
        }
        self.stored = boot.set;
        // After the set's lookup, which repairs the map after an interrupted operation.
        self.load_faults(&mut boot);
        boot
    }

    /// Re-reads the fault log alone (the record set in force is left as it is).
    pub fn fault_log(&mut self) -> FaultLog {
        let mut boot = Boot::default();
        self.load_faults(&mut boot);
        boot.faults
    }

    fn load_faults(&mut self, boot: &mut Boot) {
        let mut slots: [Option<Result<FaultEntry, Rejection>>; FAULT_LOG_LEN] =
            [None; FAULT_LOG_LEN];
        // One pass over every item (the newest of each key comes last); if the pass fails,
        // one lookup per slot, each of which repairs the map if it has to.
        if self.scan_fault_slots(&mut slots).is_err() {
            for (slot, entry) in (0u8..).zip(slots.iter_mut()) {
                let key = FAULT_KEY_BASE + slot;
                *entry = match block_on(self.map.fetch_item::<&[u8]>(&mut self.work.0, &key)) {
                    Ok(None) => None,
                    Ok(Some(bytes)) => Some(records::decode::<FaultEntry>(bytes)),
                    Err(e) => Some(Err(Rejection::Flash(flash_fault(&e)))),
                };
            }
        }
        let mut next = self.fault_floor;
        for entry in slots.into_iter().flatten() {
            match entry {
                Ok(entry) => {
                    next = next.max(entry.seq.saturating_add(1));
                    if entry.seq >= self.fault_floor {
                        boot.faults.insert(entry);
                    }
                }
                Err(why) => boot.faults.drop_entry(why),
            }
        }
        self.next_fault_seq = next;
        boot.report.faults = match (boot.faults.is_empty(), boot.faults.dropped().1) {
            (false, _) => Outcome::Loaded,
            (true, Some(why)) => Outcome::Rejected(why),
            (true, None) => Outcome::Default,
        };
    }

    fn scan_fault_slots(
        &mut self,
        slots: &mut [Option<Result<FaultEntry, Rejection>>; FAULT_LOG_LEN],
    ) -> Result<(), sequential_storage::Error<F::Error>> {
        let mut items = block_on(self.map.fetch_all_items(&mut self.work.0))?;
        while let Some((key, bytes)) = block_on(items.next::<&[u8]>(&mut self.work.0))? {
            let slot = usize::from(key.wrapping_sub(FAULT_KEY_BASE));
            if let Some(entry) = slots.get_mut(slot) {
                *entry = Some(records::decode::<FaultEntry>(bytes));
            }
        }
        Ok(())
    }

    /// Saves `set` as the new stored set, in one map item: after a power cut the store holds
    /// the old set or this one, whole. Records that are `None` are stored as absent.
    /// Returns the new set's generation.
    ///
    /// # Errors
    /// [`StoreError::Invalid`] if a record fails its checks (nothing written);
    /// [`StoreError::Flash`] if the flash failed.
    pub fn save(&mut self, set: &RecordSet, checks: &impl Validator) -> Result<u32, StoreError> {
        if let Some(c) = &set.config {
            accept(c, checks.config(c))?;
        }
        if let Some(c) = &set.calibration {
            accept(c, checks.calibration(c))?;
        }
        if let Some(b) = &set.bus {
            accept(b, checks.bus(b))?;
        }
        let generation = self.generation.wrapping_add(1);
        self.write_set(set, generation, self.fault_floor)?;
        self.generation = generation;
        self.stored = *set;
        Ok(generation)
    }

    /// Forgets every record and the fault log, atomically: one set item with no records
    /// and a fault floor above every logged fault. If that cannot be written (flash
    /// corrupted beyond repair, or holding something other than a store), erases the whole
    /// region instead.
    ///
    /// # Errors
    /// [`StoreError::Flash`] if the flash failed.
    pub fn factory_reset(&mut self) -> Result<(), StoreError> {
        let generation = self.generation.wrapping_add(1);
        let floor = self.next_fault_seq;
        match self.write_set(&RecordSet::default(), generation, floor) {
            Ok(()) => {
                self.generation = generation;
                self.fault_floor = floor;
            }
            // Flash the map cannot write (corrupted beyond repair, or words not erased where
            // it expects free space): the user asked to forget everything, so erase it.
            Err(StoreError::Flash(_)) => {
                block_on(self.map.erase_all()).map_err(|e| StoreError::Flash(flash_fault(&e)))?;
                self.generation = 0;
                self.fault_floor = 0;
                self.next_fault_seq = 0;
            }
            Err(e) => return Err(e),
        }
        self.stored = RecordSet::default();
        Ok(())
    }

    /// Appends a latched fault to the log (one small item; the oldest of the
    /// [`FAULT_LOG_LEN`] is overwritten). Returns its number.
    ///
    /// # Errors
    /// [`StoreError::Flash`] if the flash failed (the fault is not logged).
    pub fn log_fault(&mut self, fault: FaultRecord) -> Result<u32, StoreError> {
        let seq = self.next_fault_seq;
        let mut item = [0u8; FAULT_MAX];
        let n = records::encode(&FaultEntry { seq, fault }, &mut item).map_err(internal)?;
        let key = FAULT_KEY_BASE + (seq % FAULT_LOG_LEN as u32) as u8;
        let bytes: &[u8] = item.get(..n).ok_or(internal(()))?;
        block_on(self.map.store_item(&mut self.work.0, &key, &bytes))
            .map_err(|e| StoreError::Flash(flash_fault(&e)))?;
        self.next_fault_seq = seq.saturating_add(1);
        Ok(seq)
    }

    fn write_set(
        &mut self,
        set: &RecordSet,
        generation: u32,
        floor: u32,
    ) -> Result<(), StoreError> {
        let mut config = [0u8; CONFIG_MAX];
        let mut calibration = [0u8; CALIBRATION_MAX];
        let mut bus = [0u8; BUS_MAX];
        let body = SetBody {
            generation,
            fault_floor: floor,
            config: encode_opt(set.config.as_ref(), &mut config)?,
            calibration: encode_opt(set.calibration.as_ref(), &mut calibration)?,
            bus: encode_opt(set.bus.as_ref(), &mut bus)?,
        };
        let mut item = [0u8; SET_ITEM_MAX];
        let (head, rest) = item.split_first_mut().ok_or(internal(()))?;
        *head = SET_FORMAT;
        let n = 1 + postcard::to_slice(&body, rest).map_err(internal)?.len();
        let bytes: &[u8] = item.get(..n).ok_or(internal(()))?;
        block_on(self.map.store_item(&mut self.work.0, &SET_KEY, &bytes))
            .map_err(|e| StoreError::Flash(flash_fault(&e)))
    }
}

fn internal<E>(_: E) -> StoreError {
    StoreError::Flash(FlashFault::Internal)
}

/// A record's own checks, then the device's.
fn accept<R: Record>(record: &R, device: Result<(), &'static str>) -> Result<(), StoreError> {
    record
        .check()
        .and(device)
        .map_err(|reason| StoreError::Invalid {
            record: R::NAME,
            reason,
        })
}

fn encode_opt<'b, R: Record>(
    record: Option<&R>,
    buf: &'b mut [u8],
) -> Result<&'b [u8], StoreError> {
    let n = match record {
        Some(r) => records::encode(r, buf).map_err(internal)?,
        None => 0,
    };
    buf.get(..n).ok_or(internal(()))
}

/// One record of the set: absent, or decoded and checked.
fn load_record<R: Record + Copy>(
    bytes: &[u8],
    device: impl Fn(&R) -> Result<(), &'static str>,
) -> (Option<R>, Outcome) {
    if bytes.is_empty() {
        return (None, Outcome::Default);
    }
    let checked = records::decode::<R>(bytes).and_then(|r| {
        r.check()
            .and_then(|()| device(&r))
            .map(|()| r)
            .map_err(Rejection::Invalid)
    });
    match checked {
        Ok(r) => (Some(r), Outcome::Loaded),
        Err(why) => (None, Outcome::Rejected(why)),
    }
}

/// Decodes the set item into `boot`; its generation and fault floor if the envelope
/// decodes.
fn decode_set(bytes: &[u8], checks: &impl Validator, boot: &mut Boot) -> Option<(u32, u32)> {
    let envelope = match bytes.split_first() {
        Some((&SET_FORMAT, body)) => match postcard::take_from_bytes::<SetBody<'_>>(body) {
            Ok((set, [])) => Ok(set),
            _ => Err(Rejection::Undecodable),
        },
        Some((&found, _)) => Err(Rejection::UnknownVersion {
            found,
            current: SET_FORMAT,
        }),
        None => Err(Rejection::Undecodable),
    };
    let body = match envelope {
        Ok(body) => body,
        Err(why) => {
            let r = Outcome::Rejected(why);
            (boot.report.config, boot.report.calibration, boot.report.bus) = (r, r, r);
            return None;
        }
    };
    (boot.set.config, boot.report.config) = load_record(body.config, |c| checks.config(c));
    (boot.set.calibration, boot.report.calibration) =
        load_record(body.calibration, |c| checks.calibration(c));
    (boot.set.bus, boot.report.bus) = load_record(body.bus, |b| checks.bus(b));
    Some((body.generation, body.fault_floor))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BusLimits, Clutch, RamFlash};
    use protocol::CLUTCH_MAX_UM as CLUTCH_MAX;
    use protocol::{FaultCode, Gains, Limits};

    type Flash = RamFlash<PAGES>;

    fn config() -> Config {
        Config {
            clutch: Clutch::LengthUm(3_000),
            link_inertia_kg_mm2: 1_000,
            gains: None,
            limits: Limits::DEFAULT,
            command_timeout_ms: 100,
        }
    }

    fn bus() -> BusSettings {
        BusSettings::ax12a_default()
    }

    /// Writes a raw set item (as some other firmware might have) and loads it.
    fn load_raw(item: &[u8], checks: &impl Validator) -> Boot {
        let (mut s, _) = Store::open(Flash::new(), &RangeChecks).unwrap();
        block_on(s.map.store_item(&mut s.work.0, &SET_KEY, &item)).unwrap();
        s.load(checks)
    }

    /// A set item with these record bytes.
    fn raw_set(config: &[u8], calibration: &[u8], bus: &[u8]) -> ([u8; SET_ITEM_MAX], usize) {
        let body = SetBody {
            generation: 7,
            fault_floor: 0,
            config,
            calibration,
            bus,
        };
        let mut item = [0u8; SET_ITEM_MAX];
        item[0] = SET_FORMAT;
        let n = 1 + postcard::to_slice(&body, &mut item[1..]).unwrap().len();
        (item, n)
    }

    fn encoded<R: Record>(r: &R) -> Vec<u8> {
        let mut buf = [0u8; SET_ITEM_MAX];
        let n = records::encode(r, &mut buf).unwrap();
        buf[..n].to_vec()
    }

    #[test]
    fn an_empty_store_boots_with_defaults() {
        let (_, boot) = Store::open(Flash::new(), &RangeChecks).unwrap();
        assert_eq!(boot, Boot::default());
        assert!(boot
            .report
            .lines()
            .iter()
            .all(|(_, o)| *o == Outcome::Default));
        assert_eq!(boot.report.lines()[0].0, "config");
    }

    #[test]
    fn a_saved_set_loads_whole_and_absent_records_stay_default() {
        let (mut s, _) = Store::open(Flash::new(), &RangeChecks).unwrap();
        let set = RecordSet {
            config: Some(config()),
            calibration: None,
            bus: Some(bus()),
        };
        assert_eq!(s.save(&set, &RangeChecks), Ok(1));
        assert_eq!(s.stored(), &set);
        let (_, boot) = Store::open(s.into_flash(), &RangeChecks).unwrap();
        assert_eq!(boot.set, set);
        assert_eq!(boot.report.generation, Some(1));
        assert_eq!(
            boot.report.lines().map(|(_, o)| o),
            [
                Outcome::Loaded,
                Outcome::Default,
                Outcome::Loaded,
                Outcome::Default
            ]
        );
    }

    #[test]
    fn a_newer_or_older_schema_version_is_rejected_with_the_reason() {
        // Version 1 migrates (`records`' tests); 0 and anything above 2 are unknown.
        for version in [0u8, 3, 255] {
            let mut cfg = encoded(&config());
            cfg[0] = version;
            let (item, n) = raw_set(&cfg, &[], &encoded(&bus()));
            let boot = load_raw(&item[..n], &RangeChecks);
            let why = Rejection::UnknownVersion {
                found: version,
                current: 2,
            };
            assert_eq!(boot.report.config, Outcome::Rejected(why));
            assert_eq!(boot.set.config, None);
            assert_eq!(boot.set.bus, Some(bus()), "the other records still load");
            assert_eq!(
                format!("{}", boot.report.config),
                format!("rejected (schema version {version} unknown (this firmware: 2)), defaults")
            );
        }
    }

    #[test]
    fn bytes_that_do_not_decode_are_rejected() {
        let mut long = encoded(&config());
        long.push(0); // trailing byte
        let short = &encoded(&config())[..5];
        let bad_code = [1u8, 0, 99, 0, 0]; // fault code 99 does not exist
        for cfg in [&long[..], short, &[1u8][..]] {
            let (item, n) = raw_set(cfg, &[], &[]);
            let boot = load_raw(&item[..n], &RangeChecks);
            assert_eq!(
                boot.report.config,
                Outcome::Rejected(Rejection::Undecodable)
            );
        }
        let (mut s, _) = Store::open(Flash::new(), &RangeChecks).unwrap();
        block_on(
            s.map
                .store_item(&mut s.work.0, &FAULT_KEY_BASE, &&bad_code[..]),
        )
        .unwrap();
        let boot = s.load(&RangeChecks);
        assert_eq!(boot.faults.dropped(), (1, Some(Rejection::Undecodable)));
        assert_eq!(
            boot.report.faults,
            Outcome::Rejected(Rejection::Undecodable)
        );
    }

    #[test]
    fn an_unknown_envelope_rejects_every_record() {
        let (mut item, n) = raw_set(&encoded(&config()), &[], &[]);
        item[0] = 9;
        let boot = load_raw(&item[..n], &RangeChecks);
        let r = Outcome::Rejected(Rejection::UnknownVersion {
            found: 9,
            current: 1,
        });
        assert_eq!(
            (boot.report.config, boot.report.calibration, boot.report.bus),
            (r, r, r)
        );
        assert_eq!(boot.report.generation, None);
        assert_eq!(boot.set, RecordSet::default());
    }

    struct NoLongClutch;
    impl Validator for NoLongClutch {
        fn config(&self, c: &Config) -> Result<(), &'static str> {
            match c.clutch {
                Clutch::LengthUm(l) if l > 5_000 => Err("beyond the design's 5 mm"),
                _ => Ok(()),
            }
        }
    }

    #[test]
    fn stored_values_failing_the_range_or_device_checks_are_not_applied() {
        let out_of_range = Config {
            clutch: Clutch::LengthUm(CLUTCH_MAX + 1),
            ..config()
        };
        let (item, n) = raw_set(&encoded(&out_of_range), &[], &[]);
        let boot = load_raw(&item[..n], &RangeChecks);
        assert_eq!(
            boot.report.config,
            Outcome::Rejected(Rejection::Invalid(
                "clutch length or stiffness out of range"
            ))
        );
        let long = Config {
            clutch: Clutch::LengthUm(6_000),
            ..config()
        };
        let (item, n) = raw_set(&encoded(&long), &[], &[]);
        assert_eq!(load_raw(&item[..n], &RangeChecks).set.config, Some(long));
        let boot = load_raw(&item[..n], &NoLongClutch);
        assert_eq!(
            boot.report.config,
            Outcome::Rejected(Rejection::Invalid("beyond the design's 5 mm"))
        );
        assert_eq!(boot.set.config, None);
    }

    #[test]
    fn an_invalid_record_is_not_saved() {
        let (mut s, _) = Store::open(Flash::new(), &RangeChecks).unwrap();
        s.save(
            &RecordSet {
                config: Some(config()),
                ..RecordSet::default()
            },
            &RangeChecks,
        )
        .unwrap();
        let words = s.flash().words_written();
        let bad = RecordSet {
            config: Some(config()),
            bus: Some(BusSettings { id: 254, ..bus() }),
            ..RecordSet::default()
        };
        assert_eq!(
            s.save(&bad, &RangeChecks),
            Err(StoreError::Invalid {
                record: "bus",
                reason: "bus ID outside the control table's range"
            })
        );
        assert_eq!(s.flash().words_written(), words, "nothing written");
        let timeout0 = RecordSet {
            config: Some(Config {
                command_timeout_ms: 0,
                ..config()
            }),
            ..RecordSet::default()
        };
        assert!(s.save(&timeout0, &RangeChecks).is_err());
        let (_, boot) = Store::open(s.into_flash(), &RangeChecks).unwrap();
        assert_eq!(boot.report.generation, Some(1));
    }

    #[test]
    fn bus_settings_follow_the_control_tables() {
        let ax = BusSettings::ax12a_default();
        let want = BusSettings {
            id: 1,
            baud_bps: 1_000_000,
            protocol_version: 1,
            return_delay_2us: 250,
            status_return_level: 2,
            cw_angle_limit: 0,
            ccw_angle_limit: 1023,
            // The e-Manual's defaults (AX-12A; XL430 for the X-only registers).
            limits: BusLimits {
                max_torque: 1023,
                temperature_limit: 70,
                min_voltage_limit: 60,
                max_voltage_limit: 140,
                alarm_led: 36,
                shutdown: 36,
                velocity_limit: 265,
                min_position_limit: 0,
                max_position_limit: 4095,
            },
        };
        assert_eq!(ax, want);
        for bad in [
            BusLimits {
                max_torque: 1024,
                ..want.limits
            },
            BusLimits {
                min_voltage_limit: 49,
                ..want.limits
            },
            BusLimits {
                min_position_limit: 3000,
                max_position_limit: 2000,
                ..want.limits
            },
        ] {
            assert!(
                BusSettings { limits: bad, ..ax }.check().is_err(),
                "{bad:?}"
            );
        }
        let x = BusSettings {
            protocol_version: 2,
            ..ax
        };
        assert_eq!((ax.check(), x.check()), (Ok(()), Ok(())));
        // 250 kbit/s is AX register 7, not an X rate; ID 253 is AX-only.
        assert!(BusSettings {
            baud_bps: 250_000,
            ..ax
        }
        .check()
        .is_ok());
        assert!(BusSettings {
            baud_bps: 250_000,
            ..x
        }
        .check()
        .is_err());
        assert!(BusSettings {
            baud_bps: 300_000,
            ..ax
        }
        .check()
        .is_err());
        assert!(BusSettings { id: 253, ..ax }.check().is_ok());
        assert!(BusSettings { id: 253, ..x }.check().is_err());
        assert!(BusSettings {
            return_delay_2us: 255,
            ..ax
        }
        .check()
        .is_err());
        assert!(BusSettings {
            protocol_version: 3,
            ..ax
        }
        .check()
        .is_err());
        assert!(BusSettings {
            status_return_level: 3,
            ..ax
        }
        .check()
        .is_err());
        let crossed = BusSettings {
            cw_angle_limit: 600,
            ccw_angle_limit: 500,
            ..ax
        };
        assert!(crossed.check().is_err());
    }

    #[test]
    fn the_largest_records_are_the_documented_sizes() {
        let config = Config {
            clutch: Clutch::StiffnessMnmPerRad(u32::MAX),
            link_inertia_kg_mm2: u32::MAX,
            gains: Some(Gains {
                kp: u64::MAX,
                ki: u64::MAX,
                kd: u64::MAX,
            }),
            limits: Limits {
                torque_margin_permille: u16::MAX,
                current_ma: u16::MAX,
                motor_torque_unm: u32::MAX,
                duty_permille: u16::MAX,
                position_min_urad: i32::MIN,
                position_max_urad: i32::MIN,
                clutch_tolerance_um: u16::MAX,
            },
            command_timeout_ms: u32::MAX,
        };
        let calibration = Calibration {
            wire: protocol::Calibration {
                motor_polarity: i8::MIN,
                encoder_direction: i8::MIN,
                pot_direction: i8::MIN,
                current_offset_counts: i16::MIN,
                pot_offset_counts: i16::MIN,
                resistance_mohm: u32::MAX,
                back_emf_uv_s_per_rad: u32::MAX,
                gear_friction_unm: u32::MAX,
                link_inertia_kg_mm2: u32::MAX,
                stiffness_mnm_per_rad: Some(u32::MAX),
                clutch_length_um: Some(u32::MAX),
                stiffness_uncertainty_permille: u16::MAX,
            },
            encoder_counts_per_turn: u16::MAX,
            pot_gain_ppm: u32::MAX,
            current_gain_ppm: u32::MAX,
            pot_error_centi: Some([u16::MAX; 16]),
        };
        let bus = BusSettings {
            id: u8::MAX,
            baud_bps: u32::MAX,
            protocol_version: u8::MAX,
            return_delay_2us: u8::MAX,
            status_return_level: u8::MAX,
            cw_angle_limit: u16::MAX,
            ccw_angle_limit: u16::MAX,
            limits: BusLimits {
                max_torque: u16::MAX,
                temperature_limit: u8::MAX,
                min_voltage_limit: u8::MAX,
                max_voltage_limit: u8::MAX,
                alarm_led: u8::MAX,
                shutdown: u8::MAX,
                velocity_limit: u16::MAX,
                min_position_limit: u16::MAX,
                max_position_limit: u16::MAX,
            },
        };
        let fault = FaultEntry {
            seq: u32::MAX,
            fault: FaultRecord {
                code: FaultCode::CommandTimeout,
                value: i32::MIN,
                tick: u32::MAX,
            },
        };
        let (c, k, b) = (encoded(&config), encoded(&calibration), encoded(&bus));
        assert_eq!(
            (c.len(), k.len(), b.len()),
            (CONFIG_MAX, CALIBRATION_MAX, BUS_MAX)
        );
        assert_eq!(encoded(&fault).len(), FAULT_MAX);
        let body = SetBody {
            generation: u32::MAX,
            fault_floor: u32::MAX,
            config: &c,
            calibration: &k,
            bus: &b,
        };
        assert_eq!(
            1 + postcard::to_slice(&body, &mut [0u8; 2 * SET_ITEM_MAX])
                .unwrap()
                .len(),
            SET_ITEM_MAX
        );
    }

    #[test]
    fn the_config_layout_is_pinned_to_its_schema_version() {
        // If this changes (a field added, a protocol type changed), bump the version and
        // add a migration: flash written by the old firmware must not decode as the new.
        assert_eq!(
            encoded(&config()),
            [
                2, // version
                0, 0xB8, 0x17, // Clutch::LengthUm(3000)
                0xE8, 0x07, // 1000 kg·mm²
                0,    // automatic gains
                0xD2, 0x06, 0xDC, 0x0B, 0xE0, 0xC6, 0x5B, 0xE8,
                0x07, // limits: 850 ‰, 1500 mA, 1.5 N·m, 1000 ‰
                0xBF, 0x96, 0xB1, 0x02, 0xC0, 0x96, 0xB1, 0x02, // ±2.5 rad (zig-zag)
                0,    // no clutch tolerance
                100,  // command timeout, ms
            ]
        );
    }
}
