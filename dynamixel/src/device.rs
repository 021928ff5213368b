//! One device on the bus: decodes the bytes it hears, executes the instructions addressed
//! to it against its control table and a [`Backend`], and says what to answer and when.
//!
//! The device never transmits by itself: [`Device::poll`] returns an [`Output`] whose
//! [`Reply`] carries the bytes and the delay after the end of the request (the Return Delay
//! Time, or a broadcast-ping slot); a reply to SYNC READ / BULK READ that must follow
//! another device's status is held until that status has been heard. The caller (the
//! firmware's UART task, or a simulated bus) schedules the bytes, keeps its receiver away
//! from its own transmission, and calls [`Device::idle`] when the line has been quiet for
//! a character time.

use crate::error::{DecodeError, Refusal};
use crate::table::{baud_bps, Access, Area, Field, Protocol, Register, FIRMWARE_VERSION};
use crate::table::{AX12A_MODEL, X_SERIES_MODEL};
use crate::{instruction as ins, v1, v2};
use heapless::Vec;

/// Longest data of one READ or WRITE, bytes (beyond every table's span).
pub const MAX_DATA: usize = 256;
/// Longest status packet the device sends: a 2.0 status with [`MAX_DATA`] bytes, every
/// third one stuffed.
pub const MAX_REPLY: usize = 11 + MAX_DATA + MAX_DATA / 3 + 1;
/// Silence before a device's slot in a 2.0 broadcast ping, per ID, µs. The SDK's
/// `broadcastPing` waits 3 ms plus one 14-byte status time per possible ID, so a device that
/// answers at `ID × (3 ms + status time)` (plus its return delay) always lands in the window.
pub const BROADCAST_PING_GAP_US: u32 = 3_000;
/// Bytes of a 2.0 ping status.
const PING_STATUS_BYTES: u32 = 14;
/// Most registers one write can cover: a write cannot cross a reserved byte, and the
/// longest run without one is 15 registers (AX-12A 24–44).
const MAX_ITEMS: usize = 16;

/// Bits a backend reports from [`Backend::hardware_errors`]: the AX-12A error bits of the
/// actuator's state, at the same positions as the X series' Hardware Error Status.
pub mod hardware {
    /// Supply outside the voltage limits.
    pub const INPUT_VOLTAGE: u8 = 1 << 0;
    /// Temperature above the limit.
    pub const OVERHEATING: u8 = 1 << 2;
    /// A sensor fault (2.0 only: 1.0 has no such bit).
    pub const SENSOR: u8 = 1 << 3;
    /// Over-current (2.0 only).
    pub const ELECTRICAL_SHOCK: u8 = 1 << 4;
    /// The load exceeds what the torque limit (or the beams) can hold.
    pub const OVERLOAD: u8 = 1 << 5;
}

/// What a factory reset keeps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Keep {
    /// Keep the ID.
    pub id: bool,
    /// Keep the baud rate.
    pub baud: bool,
}

/// The actuator behind the control table, as the device needs it. The firmware implements
/// it over the servo; [`crate::MemoryBackend`] is the in-memory one for tests and host tools.
///
/// The device has already checked every write against the table (access, range, limits,
/// Lock) before it calls [`Backend::check`] and [`Backend::write`]; it serves the model
/// number, firmware version, Registered, Lock and Hardware Error Status itself.
pub trait Backend {
    /// The current value of `field`, in the unit of its register.
    fn read(&mut self, field: Field) -> i32;

    /// The actuator's own checks of a value the table accepts (a clutch length the design
    /// cannot reach, a torque limit above the beams' capacity, …). Every item of a write is
    /// checked before any is written, so a refused write changes nothing.
    ///
    /// # Errors
    /// The refusal to report ([`Refusal::Range`] or [`Refusal::Failed`] as a rule).
    fn check(&mut self, field: Field, value: i32) -> Result<(), Refusal> {
        let _ = (field, value);
        Ok(())
    }

    /// Store a value that passed every check. Bus settings (ID, baud, protocol) take effect
    /// when the caller acts on [`After::ApplyBusSettings`], after the reply went out.
    fn write(&mut self, field: Field, value: i32);

    /// Reset the settings to their factory defaults, except what `keep` says and the bus
    /// protocol (a reset never silences the device in the protocol it was reset from).
    fn factory_reset(&mut self, keep: Keep);

    /// The actuator's error state, [`hardware`] bits.
    fn hardware_errors(&mut self) -> u8 {
        0
    }
}

/// Bytes to send and when.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reply {
    /// Delay from the end of the request (or of the status this reply waited for), µs.
    pub delay_us: u32,
    /// The status packet.
    pub bytes: Vec<u8, MAX_REPLY>,
}

/// What the caller does after sending the reply (if any).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum After {
    /// Nothing.
    Nothing,
    /// ID, baud rate or protocol may have changed: apply the backend's settings.
    ApplyBusSettings,
    /// REBOOT: restart (and make a new [`Device`]).
    Reboot,
}

/// The result of one instruction.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Output {
    /// The status packet to send, if the instruction is answered.
    pub reply: Option<Reply>,
    /// What to do once it is sent.
    pub after: After,
}

/// What the device has heard, since it was made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counters {
    /// Valid packets, for any ID.
    pub packets: u32,
    /// Instructions for this device (or broadcast) that it carried out.
    pub executed: u32,
    /// Instructions for this device that it refused (an error in the status).
    pub refused: u32,
    /// Complete packets with a bad checksum or CRC, for any ID.
    pub checksum_errors: u32,
    /// Other rejected candidates: bad or oversized length, truncated, bad stuffing.
    pub framing_errors: u32,
}

/// One Dynamixel device over a [`Backend`] it owns: a [`Port`] and its backend. It speaks
/// the protocol of the backend's Protocol Type (1 or 2; anything else is taken as 1).
pub struct Device<B> {
    port: Port,
    backend: B,
}

/// A device's bus state without its backend: the decoders, the protocol spoken, Lock, the
/// registered instruction, a held SYNC/BULK READ reply and the counters. For a backend that
/// only exists for the length of a call (the firmware's, which borrows the actuator under
/// a lock): keep the `Port`, and hand it the backend in [`Port::poll`].
pub struct Port {
    st: State,
    rx1: v1::Decoder,
    rx2: v2::Decoder,
}

struct State {
    protocol: Protocol,
    /// Lock (1.0, address 47): EEPROM writes refused until the device is made anew.
    locked: bool,
    registered: Option<Pending>,
    /// A SYNC/BULK READ reply held until the status of the ID before ours is heard.
    chain: Option<(u8, Reply)>,
    counters: Counters,
}

/// The bus state and the backend of one call.
struct Core<'a, B: ?Sized> {
    backend: &'a mut B,
    st: &'a mut State,
}

struct Pending {
    address: u16,
    data: Vec<u8, MAX_DATA>,
}

type Data = Vec<u8, MAX_DATA>;

impl<B: Backend> Device<B> {
    /// A device over `backend`, in the protocol its Protocol Type names.
    pub fn new(mut backend: B) -> Self {
        Device {
            port: Port::new(&mut backend),
            backend,
        }
    }

    /// The protocol being spoken.
    pub fn protocol(&self) -> Protocol {
        self.port.protocol()
    }

    /// The backend.
    pub fn backend(&self) -> &B {
        &self.backend
    }

    /// The backend, mutably (the firmware's tick updates the actuator's state through it).
    pub fn backend_mut(&mut self) -> &mut B {
        &mut self.backend
    }

    /// What the device has heard.
    pub fn counters(&self) -> Counters {
        self.port.counters()
    }

    /// Whether the EEPROM is locked (1.0 Lock register).
    pub fn locked(&self) -> bool {
        self.port.locked()
    }

    /// One byte heard on the bus (not one this device sent).
    pub fn push(&mut self, byte: u8) {
        self.port.push(byte);
    }

    /// The line has been idle for at least one character time.
    pub fn idle(&mut self) {
        self.port.idle();
    }

    /// The next thing to do for the bytes heard so far; call until `None` after every
    /// [`Device::push`] and [`Device::idle`].
    pub fn poll(&mut self) -> Option<Output> {
        self.port.poll(&mut self.backend)
    }
}

impl Port {
    /// The bus state of a device over `backend`, in the protocol its Protocol Type names.
    pub fn new<B: Backend + ?Sized>(backend: &mut B) -> Self {
        let protocol =
            Protocol::from_number(backend.read(Field::BusProtocol)).unwrap_or(Protocol::V1);
        Port {
            st: State {
                protocol,
                locked: false,
                registered: None,
                chain: None,
                counters: Counters::default(),
            },
            rx1: v1::Decoder::new(),
            rx2: v2::Decoder::new(),
        }
    }

    /// The protocol being spoken.
    pub fn protocol(&self) -> Protocol {
        self.st.protocol
    }

    /// What the device has heard.
    pub fn counters(&self) -> Counters {
        self.st.counters
    }

    /// Whether the EEPROM is locked (1.0 Lock register).
    pub fn locked(&self) -> bool {
        self.st.locked
    }

    /// One byte heard on the bus (not one this device sent).
    pub fn push(&mut self, byte: u8) {
        match self.st.protocol {
            Protocol::V1 => self.rx1.push(byte),
            Protocol::V2 => self.rx2.push(byte),
        }
    }

    /// The line has been idle for at least one character time.
    pub fn idle(&mut self) {
        self.rx1.idle();
        self.rx2.idle();
    }

    /// Whether a packet has begun and not yet been decided (bytes heard since the last
    /// packet, error or idle line that a decoder has not consumed).
    pub fn receiving(&self) -> bool {
        match self.st.protocol {
            Protocol::V1 => self.rx1.pending(),
            Protocol::V2 => self.rx2.pending(),
        }
    }

    /// The next thing to do for the bytes heard so far, with `backend` behind the control
    /// table; call until `None` after every [`Port::push`] and [`Port::idle`].
    pub fn poll<B: Backend + ?Sized>(&mut self, backend: &mut B) -> Option<Output> {
        loop {
            let mut core = Core {
                backend: &mut *backend,
                st: &mut self.st,
            };
            let out = match core.st.protocol {
                Protocol::V1 => {
                    let r = self.rx1.next()?;
                    core.on_v1(r)
                }
                Protocol::V2 => {
                    let r = self.rx2.next()?;
                    core.on_v2(r)
                }
            };
            if let Some(out) = out {
                if out.after == After::ApplyBusSettings {
                    self.follow_protocol(backend);
                }
                return Some(out);
            }
        }
    }

    /// Switch to the protocol the backend now names, forgetting the other's partial state.
    fn follow_protocol<B: Backend + ?Sized>(&mut self, backend: &mut B) {
        let Some(p) = Protocol::from_number(backend.read(Field::BusProtocol)) else {
            return;
        };
        if p != self.st.protocol {
            self.st.protocol = p;
            self.st.registered = None;
            self.st.chain = None;
            self.rx1.reset();
            self.rx2.reset();
        }
    }
}

/// Little-endian 16-bit value at `p[i..i + 2]`.
fn le16(p: &[u8], i: usize) -> Option<u16> {
    Some(u16::from_le_bytes([*p.get(i)?, *p.get(i + 1)?]))
}

impl<B: Backend + ?Sized> Core<'_, B> {
    fn id(&mut self) -> u8 {
        u8::try_from(self.backend.read(Field::Id)).unwrap_or(u8::MAX)
    }

    fn delay_us(&mut self) -> u32 {
        2 * u32::try_from(self.backend.read(Field::ReturnDelayTime)).unwrap_or(0)
    }

    /// Whether the Status Return Level lets `instruction` be answered (PING always; reads
    /// from level 1; everything at level 2).
    fn answers(&mut self, instruction: u8) -> bool {
        let level = self.backend.read(Field::StatusReturnLevel);
        match instruction {
            ins::PING => true,
            ins::READ | ins::SYNC_READ | ins::BULK_READ => level >= 1,
            _ => level >= 2,
        }
    }

    fn eeprom_locked(&mut self) -> bool {
        match self.st.protocol {
            Protocol::V1 => self.st.locked,
            Protocol::V2 => self.backend.read(Field::TorqueEnable) != 0,
        }
    }

    fn count(&mut self, r: &Result<After, Refusal>) {
        match r {
            Ok(_) => self.st.counters.executed = self.st.counters.executed.wrapping_add(1),
            Err(_) => self.st.counters.refused = self.st.counters.refused.wrapping_add(1),
        }
    }

    fn on_decode_error(&mut self, e: DecodeError) -> Option<u8> {
        match e {
            DecodeError::Checksum { id, instruction } => {
                self.st.counters.checksum_errors = self.st.counters.checksum_errors.wrapping_add(1);
                (id == self.id() && self.answers(instruction)).then_some(instruction)
            }
            _ => {
                self.st.counters.framing_errors = self.st.counters.framing_errors.wrapping_add(1);
                None
            }
        }
    }

    // ---- Protocol 1.0 ----

    fn on_v1(&mut self, r: Result<v1::Packet<'_>, DecodeError>) -> Option<Output> {
        let p = match r {
            Ok(p) => p,
            Err(e) => {
                self.on_decode_error(e)?;
                let me = self.id();
                let reply = self.status_v1(me, v1::error::CHECKSUM, &[]);
                return Some(Output {
                    reply,
                    after: After::Nothing,
                });
            }
        };
        self.st.counters.packets = self.st.counters.packets.wrapping_add(1);
        let me = self.id();
        let broadcast = p.id == v1::BROADCAST_ID;
        if p.id != me && !broadcast {
            return None;
        }
        let mut data = Data::new();
        let result = self.exec_v1(&p, broadcast, me, &mut data);
        self.count(&result);
        let after = *result.as_ref().unwrap_or(&After::Nothing);
        let reply = if broadcast || !self.answers(p.code) {
            None
        } else {
            let bits = result.err().map_or(0, Refusal::v1_bits);
            self.status_v1(me, bits, &data)
        };
        (reply.is_some() || after != After::Nothing).then_some(Output { reply, after })
    }

    fn exec_v1(
        &mut self,
        p: &v1::Packet<'_>,
        broadcast: bool,
        me: u8,
        data: &mut Data,
    ) -> Result<After, Refusal> {
        match (p.code, p.params) {
            (ins::PING, []) => Ok(After::Nothing),
            (ins::READ, &[address, length]) => {
                self.read(u16::from(address), u16::from(length), data)?;
                Ok(After::Nothing)
            }
            (ins::WRITE, [address, bytes @ ..]) => self.write(u16::from(*address), bytes, true),
            (ins::REG_WRITE, [address, bytes @ ..]) => self.reg_write(u16::from(*address), bytes),
            (ins::ACTION, []) => self.action(),
            (ins::FACTORY_RESET, []) => self.factory_reset(Keep::default()),
            (ins::SYNC_WRITE, [address, length, entries @ ..]) if broadcast && *length > 0 => {
                let n = usize::from(*length) + 1;
                if !entries.len().is_multiple_of(n) {
                    return Err(Refusal::Instruction);
                }
                match entries.chunks_exact(n).find(|e| e[0] == me) {
                    Some(e) => self.write(u16::from(*address), &e[1..], true),
                    None => Ok(After::Nothing),
                }
            }
            _ => Err(Refusal::Instruction),
        }
    }

    /// A status from `me`: the ID the instruction was addressed to, even when it changed
    /// the ID (the SDK matches replies by the ID it asked).
    fn status_v1(&mut self, me: u8, bits: u8, data: &[u8]) -> Option<Reply> {
        let hw = self.backend.hardware_errors() & v1::error::HARDWARE;
        let delay_us = self.delay_us();
        let mut bytes = Vec::new();
        bytes.resize_default(MAX_REPLY).ok()?;
        let n = v1::encode(me, bits | hw, data, &mut bytes).ok()?;
        bytes.truncate(n);
        Some(Reply { delay_us, bytes })
    }

    // ---- Protocol 2.0 ----

    fn on_v2(&mut self, r: Result<v2::Packet<'_>, DecodeError>) -> Option<Output> {
        let p = match r {
            Ok(p) => p,
            Err(e) => {
                self.on_decode_error(e)?;
                let me = self.id();
                let reply = self.status_v2(me, v2::ErrorCode::Crc as u8, &[]);
                return Some(Output {
                    reply,
                    after: After::Nothing,
                });
            }
        };
        self.st.counters.packets = self.st.counters.packets.wrapping_add(1);
        if p.instruction == v2::STATUS {
            // Another device's status: the cue for a reply waiting on it.
            let waiting = matches!(self.st.chain, Some((id, _)) if id == p.id);
            return if waiting {
                let (_, mut reply) = self.st.chain.take()?;
                reply.delay_us = self.delay_us();
                Some(Output {
                    reply: Some(reply),
                    after: After::Nothing,
                })
            } else {
                None
            };
        }
        self.st.chain = None;
        let me = self.id();
        let broadcast = p.id == v2::BROADCAST_ID;
        if p.id != me && !broadcast {
            return None;
        }
        let mut data = Data::new();
        let mut reply_to_broadcast = false;
        let mut after_id = None;
        let mut delay_us = self.delay_us();
        let result = match (p.instruction, p.params) {
            (ins::PING, []) => {
                let [lo, hi] = (X_SERIES_MODEL as u16).to_le_bytes();
                data.extend_from_slice(&[lo, hi, FIRMWARE_VERSION as u8])
                    .ok();
                if broadcast {
                    reply_to_broadcast = true;
                    delay_us += u32::from(me) * self.ping_slot_us();
                }
                Ok(After::Nothing)
            }
            (ins::SYNC_READ, params) if broadcast => {
                let (Some(address), Some(length)) = (le16(params, 0), le16(params, 2)) else {
                    return None;
                };
                let ids = &params[4..];
                let k = ids.iter().position(|&i| i == me)?;
                reply_to_broadcast = true;
                after_id = k.checked_sub(1).map(|j| ids[j]);
                self.read(address, length, &mut data)
                    .map(|()| After::Nothing)
            }
            (ins::BULK_READ, params) if broadcast => {
                if !params.len().is_multiple_of(5) {
                    return None;
                }
                let mut entries = params.chunks_exact(5);
                let k = entries.position(|e| e[0] == me)?;
                let e = &params[5 * k..5 * k + 5];
                reply_to_broadcast = true;
                after_id = k.checked_sub(1).map(|j| params[5 * j]);
                let (address, length) = (le16(e, 1)?, le16(e, 3)?);
                self.read(address, length, &mut data)
                    .map(|()| After::Nothing)
            }
            _ => self.exec_v2(&p, broadcast, me, &mut data),
        };
        self.count(&result);
        let after = *result.as_ref().unwrap_or(&After::Nothing);
        let answered = (!broadcast || reply_to_broadcast) && self.answers(p.instruction);
        let mut reply = if answered {
            let code = result.err().map_or(0, |r| r.v2_code() as u8);
            self.status_v2(me, code, &data)
        } else {
            None
        };
        if let Some(r) = reply.as_mut() {
            r.delay_us = delay_us;
        }
        if let Some(id) = after_id {
            // Held until the status of the device listed before this one is heard.
            self.st.chain = reply.take().map(|r| (id, r));
        }
        (reply.is_some() || after != After::Nothing).then_some(Output { reply, after })
    }

    fn exec_v2(
        &mut self,
        p: &v2::Packet<'_>,
        broadcast: bool,
        me: u8,
        data: &mut Data,
    ) -> Result<After, Refusal> {
        let params = p.params;
        match p.instruction {
            ins::READ => {
                let (Some(address), Some(length), 4) =
                    (le16(params, 0), le16(params, 2), params.len())
                else {
                    return Err(Refusal::Length);
                };
                self.read(address, length, data)?;
                Ok(After::Nothing)
            }
            ins::WRITE | ins::REG_WRITE => {
                let Some(address) = le16(params, 0) else {
                    return Err(Refusal::Length);
                };
                if p.instruction == ins::WRITE {
                    self.write(address, &params[2..], true)
                } else {
                    self.reg_write(address, &params[2..])
                }
            }
            ins::ACTION if params.is_empty() => self.action(),
            ins::FACTORY_RESET => match params {
                [0xFF] if broadcast => Ok(After::Nothing),
                [0xFF] => self.factory_reset(Keep::default()),
                [0x01] => self.factory_reset(Keep {
                    id: true,
                    baud: false,
                }),
                [0x02] => self.factory_reset(Keep {
                    id: true,
                    baud: true,
                }),
                _ => Err(Refusal::Range),
            },
            ins::REBOOT if params.is_empty() => Ok(After::Reboot),
            ins::SYNC_WRITE if broadcast => {
                let (Some(address), Some(length)) = (le16(params, 0), le16(params, 2)) else {
                    return Err(Refusal::Length);
                };
                let n = usize::from(length) + 1;
                let entries = &params[4..];
                if length == 0 || !entries.len().is_multiple_of(n) {
                    return Err(Refusal::Length);
                }
                match entries.chunks_exact(n).find(|e| e[0] == me) {
                    Some(e) => self.write(address, &e[1..], true),
                    None => Ok(After::Nothing),
                }
            }
            ins::BULK_WRITE if broadcast => {
                let mut rest = params;
                while !rest.is_empty() {
                    let (Some(address), Some(length)) = (le16(rest, 1), le16(rest, 3)) else {
                        return Err(Refusal::Length);
                    };
                    let end = 5 + usize::from(length);
                    let Some(bytes) = rest.get(5..end) else {
                        return Err(Refusal::Length);
                    };
                    if rest[0] == me {
                        return self.write(address, bytes, true);
                    }
                    rest = &rest[end..];
                }
                Ok(After::Nothing)
            }
            _ => Err(Refusal::Instruction),
        }
    }

    fn alert(&mut self) -> u8 {
        if self.backend.hardware_errors() != 0 {
            v2::ALERT
        } else {
            0
        }
    }

    /// A status with error number `code` (0: none; then `data` is sent) and the alert bit.
    fn status_v2(&mut self, me: u8, code: u8, data: &[u8]) -> Option<Reply> {
        let error = code | self.alert();
        let data = if code == 0 { data } else { &[] };
        let delay_us = self.delay_us();
        let mut bytes = Vec::new();
        bytes.resize_default(MAX_REPLY).ok()?;
        let n = v2::encode_status(me, error, data, &mut bytes).ok()?;
        bytes.truncate(n);
        Some(Reply { delay_us, bytes })
    }

    /// One broadcast-ping slot at the current baud rate, µs.
    fn ping_slot_us(&mut self) -> u32 {
        let bps = baud_bps(Protocol::V2, self.backend.read(Field::BaudRateX)).unwrap_or(57_600);
        BROADCAST_PING_GAP_US + (PING_STATUS_BYTES * 10_000_000).div_ceil(bps)
    }

    // ---- Register access, both protocols ----

    /// The value of `field` as the bus sees it.
    fn value(&mut self, field: Field) -> i32 {
        match field {
            Field::ModelNumber => match self.st.protocol {
                Protocol::V1 => AX12A_MODEL,
                Protocol::V2 => X_SERIES_MODEL,
            },
            Field::ModelInformation => 0,
            Field::FirmwareVersion => FIRMWARE_VERSION,
            Field::Registered => i32::from(self.st.registered.is_some()),
            Field::Lock => i32::from(self.st.locked),
            Field::HardwareErrorStatus => i32::from(self.backend.hardware_errors()),
            f => self.backend.read(f),
        }
    }

    /// READ: `length` bytes from `address`; reserved bytes between registers read as 0.
    fn read(&mut self, address: u16, length: u16, data: &mut Data) -> Result<(), Refusal> {
        let max = match self.st.protocol {
            Protocol::V1 => v1::MAX_PARAMS,
            Protocol::V2 => MAX_DATA,
        };
        if length == 0 {
            return Err(Refusal::Length);
        }
        if usize::from(length) > max {
            return Err(Refusal::Range);
        }
        let table = self.st.protocol.table();
        let mut cached: Option<(u16, i32)> = None;
        for i in 0..length {
            let a = address.checked_add(i).ok_or(Refusal::Access)?;
            let byte = match table.containing(a) {
                Some(r) => {
                    let v = match cached {
                        Some((at, v)) if at == r.address => v,
                        _ => {
                            let v = self.value(r.field);
                            cached = Some((r.address, v));
                            v
                        }
                    };
                    r.byte(v, a - r.address)
                }
                None if table.in_span(a) => 0,
                None => {
                    data.clear();
                    return Err(Refusal::Access);
                }
            };
            data.push(byte).map_err(|_| Refusal::Range)?;
        }
        Ok(())
    }

    /// WRITE: every register of the span is checked before any is written; with `apply`
    /// false nothing is written (REG_WRITE's check).
    fn write(&mut self, address: u16, bytes: &[u8], apply: bool) -> Result<After, Refusal> {
        if bytes.is_empty() {
            return Err(Refusal::Length);
        }
        let table = self.st.protocol.table();
        let mut items: Vec<(Register, i32), MAX_ITEMS> = Vec::new();
        let mut i = 0;
        while i < bytes.len() {
            let a = u16::try_from(usize::from(address) + i).map_err(|_| Refusal::Access)?;
            let r = table.containing(a).ok_or(Refusal::Access)?;
            let size = usize::from(r.size);
            if r.address != a || i + size > bytes.len() {
                return Err(Refusal::Length);
            }
            if r.access == Access::R {
                return Err(Refusal::Access);
            }
            if r.area == Area::Eeprom && self.eeprom_locked() {
                return Err(Refusal::Access);
            }
            let v = r.decode(&bytes[i..i + size]).ok_or(Refusal::Range)?;
            items.push((r, v)).map_err(|_| Refusal::Length)?;
            i += size;
        }
        for &(r, v) in &items {
            self.check_value(&items, &r, v)?;
        }
        let mut after = After::Nothing;
        for &(r, _) in &items {
            if matches!(
                r.field,
                Field::Id | Field::BaudRate | Field::BaudRateX | Field::BusProtocol
            ) {
                after = After::ApplyBusSettings;
            }
        }
        if apply {
            for &(r, v) in &items {
                match r.field {
                    Field::Lock => self.st.locked = v != 0,
                    f => self.backend.write(f, v),
                }
            }
        }
        Ok(after)
    }

    /// Table checks of one value (limits against the values this write leaves), then the
    /// backend's.
    fn check_value(
        &mut self,
        items: &[(Register, i32)],
        r: &Register,
        v: i32,
    ) -> Result<(), Refusal> {
        let after_write = |core: &mut Self, f: Field| {
            items
                .iter()
                .find(|(r, _)| r.field == f)
                .map_or_else(|| core.value(f), |&(_, v)| v)
        };
        let limits = match r.field {
            Field::GoalPosition => {
                let (cw, ccw) = (
                    after_write(self, Field::CwAngleLimit),
                    after_write(self, Field::CcwAngleLimit),
                );
                // Both limits 0 is wheel mode: the goal is not limited.
                (cw != 0 || ccw != 0).then_some((cw, ccw))
            }
            Field::GoalPositionX => Some((
                after_write(self, Field::MinPositionLimit),
                after_write(self, Field::MaxPositionLimit),
            )),
            _ => None,
        };
        if let Some((lo, hi)) = limits {
            if v < lo || v > hi {
                return Err(Refusal::Limit);
            }
        }
        if v < r.min || v > r.max {
            return Err(Refusal::Range);
        }
        if r.field == Field::Lock && self.st.locked && v == 0 {
            return Err(Refusal::Access);
        }
        match r.field {
            Field::Lock => Ok(()),
            f => self.backend.check(f, v),
        }
    }

    fn reg_write(&mut self, address: u16, bytes: &[u8]) -> Result<After, Refusal> {
        self.write(address, bytes, false)?;
        let data = Vec::from_slice(bytes).map_err(|_| Refusal::Length)?;
        self.st.registered = Some(Pending { address, data });
        Ok(After::Nothing)
    }

    fn action(&mut self) -> Result<After, Refusal> {
        let p = self.st.registered.take().ok_or(Refusal::Instruction)?;
        self.write(p.address, &p.data, true)
    }

    fn factory_reset(&mut self, keep: Keep) -> Result<After, Refusal> {
        if self.eeprom_locked() {
            return Err(Refusal::Access);
        }
        self.st.registered = None;
        self.backend.factory_reset(keep);
        Ok(After::ApplyBusSettings)
    }
}

#[cfg(test)]
mod tests {
    use super::MAX_ITEMS;
    use crate::table::{AX12A, X_SERIES};

    #[test]
    fn max_items_covers_the_longest_run_of_registers() {
        for table in [&AX12A, &X_SERIES] {
            let (mut run, mut longest, mut next) = (0, 0, None);
            for r in table.registers() {
                run = if Some(r.address) == next { run + 1 } else { 1 };
                longest = longest.max(run);
                next = Some(r.address + u16::from(r.size));
            }
            assert!(longest <= MAX_ITEMS, "{}: {longest}", table.model);
        }
    }
}
