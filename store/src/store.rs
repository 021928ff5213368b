//! The store: the record set and the fault log in a sequential-storage map on a flash.

use embassy_futures::block_on;
use embedded_storage::nor_flash::NorFlash;
use protocol::FaultRecord;
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapStorage};
use serde::{Deserialize, Serialize};

use crate::blocking::Blocking;
use crate::fault_log::{FaultLog, FAULT_LOG_LEN};
use crate::records::{self, BusSettings, Calibration, Config, FaultEntry, Record, Rejection};

/// Map key of the record set.
const SET_KEY: u8 = 1;
/// Map key of fault-log slot 0 (slots are `FAULT_KEY_BASE..FAULT_KEY_BASE + 16`).
const FAULT_KEY_BASE: u8 = 0x10;
/// Format of the set item's envelope (the records inside carry their own versions).
const SET_FORMAT: u8 = 1;

/// Largest stored config record, bytes: version 1 + clutch (tag 1 + u32 5) + inertia 5 +
/// gains (1 + 3 × u64 10) + limits (3 + 3 + 5 + 3 + 5 + 5) + timeout 5 (postcard varints).
pub const CONFIG_MAX: usize = 1 + 6 + 5 + 31 + 24 + 5;
/// Largest stored calibration record, bytes: version 1 + 3 signs (1 each) + 2 offsets
/// (i16 varint 3) + 4 × u32 5 + 2 × `Option<u32>` 6 + u16 3.
pub const CALIBRATION_MAX: usize = 1 + 3 + 6 + 20 + 12 + 3;
/// Largest stored bus record, bytes: version 1 + ID 1 + baud 5 + 3 × u8 + 2 × u16 3.
pub const BUS_MAX: usize = 1 + 1 + 5 + 3 + 6;
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
    /// The flash's geometry does not suit the map (fewer than 2 erase pages, or pages too
    /// small): a board definition error.
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

type Map<F> = MapStorage<u8, Blocking<F>, Cache<Uncached, Uncached, Uncached, u8>>;

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
    /// [`StoreError::Layout`] if the flash has fewer than two erase pages (or pages too
    /// small for an item).
    pub fn open(flash: F, checks: &impl Validator) -> Result<(Self, Boot), StoreError> {
        let pages = flash.capacity() / F::ERASE_SIZE;
        let end = u32::try_from(pages * F::ERASE_SIZE).map_err(|_| StoreError::Layout)?;
        let config = MapConfig::try_new(0..end).map_err(|_| StoreError::Layout)?;
        let mut store = Self {
            map: MapStorage::new(Blocking(flash), config, Cache::new_uncached()),
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
        self.load_faults(&mut boot);
        boot
    }

    fn load_faults(&mut self, boot: &mut Boot) {
        let mut next = self.fault_floor;
        let mut flash_error = None;
        for slot in 0..FAULT_LOG_LEN as u8 {
            let key = FAULT_KEY_BASE + slot;
            match block_on(self.map.fetch_item::<&[u8]>(&mut self.work.0, &key)) {
                Ok(None) => {}
                Ok(Some(bytes)) => match records::decode::<FaultEntry>(bytes) {
                    Ok(entry) => {
                        next = next.max(entry.seq.saturating_add(1));
                        if entry.seq >= self.fault_floor {
                            boot.faults.insert(entry);
                        }
                    }
                    Err(why) => boot.faults.drop_entry(why),
                },
                Err(e) => flash_error = Some(Rejection::Flash(flash_fault(&e))),
            }
        }
        self.next_fault_seq = next;
        boot.report.faults = match (boot.faults.is_empty(), boot.faults.dropped().1, flash_error) {
            (false, _, _) => Outcome::Loaded,
            (true, _, Some(why)) | (true, Some(why), None) => Outcome::Rejected(why),
            (true, None, None) => Outcome::Default,
        };
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
    /// and a fault floor above every logged fault. If sequential-storage reports the flash
    /// corrupted beyond repair, erases the whole region instead.
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
            Err(StoreError::Flash(FlashFault::Corrupted)) => {
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
