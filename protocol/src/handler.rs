//! The request handler: one reply per decoded frame, side effects through [`Device`].

use crate::frame::{Decoder, Frame, FrameError};
use crate::msg::{ErrorCode, FaultRecord, Gains, Limits, LoggedFault, Reply, Request, Status};
use crate::replay::ReplyCache;
use crate::VERSION;

/// What the handler asks of the device (implemented by the firmware over its controller
/// and supervisor; by a mock in tests).
///
/// Contract: a method that returns `Err` has changed nothing. The handler only calls these
/// for a frame that decoded and a request that passed [`Request::validate`], so every
/// argument is within its documented range; a device may still refuse with
/// [`ErrorCode::OutOfRange`] (e.g. a stiffness whose clutch length its design cannot
/// reach), [`ErrorCode::NotAllowed`] (wrong state) or [`ErrorCode::Busy`].
pub trait Device {
    /// [`Request::Enable`]: motor on, holding the current position.
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] while a fault is latched.
    fn enable(&mut self) -> Result<(), ErrorCode>;

    /// [`Request::Disable`]: motor off.
    ///
    /// # Errors
    /// Normally none: disabling is always allowed.
    fn disable(&mut self) -> Result<(), ErrorCode>;

    /// [`Request::ClearFault`]: clear the latched faults; the motor stays disabled. Only
    /// called when [`Device::persisting_fault`] is `None`.
    ///
    /// # Errors
    /// As the device decides.
    fn clear_fault(&mut self) -> Result<(), ErrorCode>;

    /// A latched fault whose condition still held at the last check (its value then), if
    /// any: [`Request::ClearFault`] then clears nothing and answers
    /// [`Reply::FaultPersists`].
    fn persisting_fault(&mut self) -> Option<FaultRecord>;

    /// [`Request::SetClutchLength`]: the clutch is at `length_um` µm; reconfigure.
    ///
    /// # Errors
    /// As the device decides (see the trait docs).
    fn set_clutch_length(&mut self, length_um: u32) -> Result<(), ErrorCode>;

    /// [`Request::SetStiffness`]: configure for `stiffness_mnm_per_rad` mN·m/rad and return
    /// the clutch length L(k) to set, µm.
    ///
    /// # Errors
    /// [`ErrorCode::OutOfRange`] if L(k) is outside the design's clutch range.
    fn set_stiffness(&mut self, stiffness_mnm_per_rad: u32) -> Result<u32, ErrorCode>;

    /// [`Request::Move`]: minimum-jerk move to `target_urad` µrad in `duration_ms` ms.
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] when not enabled.
    fn command_move(&mut self, target_urad: i32, duration_ms: u32) -> Result<(), ErrorCode>;

    /// [`Request::Step`]: reference step to `target_urad` µrad.
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] when not enabled.
    fn command_step(&mut self, target_urad: i32) -> Result<(), ErrorCode>;

    /// [`Request::Sine`]: sine of `amplitude_urad` µrad at `frequency_mhz` mHz.
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] when not enabled.
    fn command_sine(&mut self, amplitude_urad: u32, frequency_mhz: u32) -> Result<(), ErrorCode>;

    /// [`Request::Hold`]: stop the motion, hold the current reference.
    ///
    /// # Errors
    /// As the device decides.
    fn hold(&mut self) -> Result<(), ErrorCode>;

    /// [`Request::SetGains`] (`Some`) or [`Request::AutoGains`] (`None`).
    ///
    /// # Errors
    /// As the device decides.
    fn set_gains(&mut self, gains: Option<Gains>) -> Result<(), ErrorCode>;

    /// [`Request::SetLimits`].
    ///
    /// # Errors
    /// As the device decides.
    fn set_limits(&mut self, limits: &Limits) -> Result<(), ErrorCode>;

    /// [`Request::StreamTelemetry`]: `rate_hz` is 0 (off) or 10..=500.
    ///
    /// # Errors
    /// As the device decides.
    fn set_telemetry_rate(&mut self, rate_hz: u16) -> Result<(), ErrorCode>;

    /// [`Request::Heartbeat`]: arm (the first one) and restart the command timeout.
    fn heartbeat(&mut self);

    /// [`Request::DisarmHeartbeat`]: the command timeout is off until the next heartbeat.
    fn disarm_heartbeat(&mut self);

    /// A well-formed request of this version within its ranges arrived (whatever it asks,
    /// carried out or refused by the device): restart the command timeout if it is armed.
    /// Called before the request is carried out.
    fn link_activity(&mut self);

    /// [`Request::GetLimits`]: the limits and the position window in force.
    fn limits(&mut self) -> Limits;

    /// [`Request::Impedance`]: hold `target_urad` µrad with virtual stiffness
    /// `stiffness_mnm_per_rad` mN·m/rad, damping `damping_unms_per_rad` µN·m·s/rad and
    /// feed-forward torque `torque_unm` µN·m.
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] when not enabled; [`ErrorCode::OutOfRange`] for a
    /// stiffness above the joint's at the clutch setting or a target outside the position
    /// window.
    fn impedance(
        &mut self,
        target_urad: i32,
        stiffness_mnm_per_rad: u32,
        damping_unms_per_rad: u32,
        torque_unm: i32,
    ) -> Result<(), ErrorCode>;

    /// [`Request::GetStatus`]: the current status (`protocol_errors` is overwritten by the
    /// handler).
    fn status(&mut self) -> Status;

    /// [`Request::GetSensors`]: the raw readings of the last control tick.
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] by default: a device without raw readings.
    fn raw_sensors(&mut self) -> Result<crate::RawSensors, ErrorCode> {
        Err(ErrorCode::NotAllowed)
    }

    /// [`Request::Nudge`]: open-loop drive at `duty_permille` for `duration_ms`.
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] unless disabled (and by default: a device without it).
    fn nudge(&mut self, duty_permille: i16, duration_ms: u16) -> Result<(), ErrorCode> {
        let _ = (duty_permille, duration_ms);
        Err(ErrorCode::NotAllowed)
    }

    /// [`Request::Save`]: the running configuration into the settings store.
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] while enabled; [`ErrorCode::Storage`] if the flash failed
    /// or (the default) the device has no store.
    fn save(&mut self) -> Result<(), ErrorCode> {
        Err(ErrorCode::Storage)
    }

    /// [`Request::Load`]: re-read the store and apply it.
    ///
    /// # Errors
    /// [`ErrorCode::Storage`] without a store (the default).
    fn load(&mut self) -> Result<(), ErrorCode> {
        Err(ErrorCode::Storage)
    }

    /// [`Request::FactoryReset`]: forget the stored records and the fault log; defaults.
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] while enabled; [`ErrorCode::Storage`] if the flash failed
    /// or (the default) the device has no store.
    fn factory_reset(&mut self) -> Result<(), ErrorCode> {
        Err(ErrorCode::Storage)
    }

    /// [`Request::FaultsLog`]: the number of logged faults and entry `index` (0 = the most
    /// recent), if it exists.
    ///
    /// # Errors
    /// [`ErrorCode::Storage`] without a store (the default).
    fn faults_log(&mut self, _index: u8) -> Result<(u8, Option<LoggedFault>), ErrorCode> {
        Err(ErrorCode::Storage)
    }

    /// [`Request::SetBus`]: change the Dynamixel bus settings.
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] by default: a device without a bus.
    fn set_bus(&mut self, change: &crate::BusChange) -> Result<(), ErrorCode> {
        let _ = change;
        Err(ErrorCode::NotAllowed)
    }
}

/// Protocol errors since start, per kind (saturating counters).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ErrorCounters {
    /// [`FrameError::Overflow`].
    pub overflow: u32,
    /// [`FrameError::Cobs`].
    pub cobs: u32,
    /// [`FrameError::Truncated`].
    pub truncated: u32,
    /// [`FrameError::Crc`].
    pub crc: u32,
    /// [`FrameError::Version`].
    pub version: u32,
    /// [`FrameError::UnknownMessage`].
    pub unknown_message: u32,
    /// [`FrameError::Decode`].
    pub decode: u32,
    /// Requests refused with [`ErrorCode::OutOfRange`] (by [`Request::validate`] or the
    /// device).
    pub out_of_range: u32,
    /// Requests refused by the device with [`ErrorCode::NotAllowed`].
    pub not_allowed: u32,
    /// Requests refused by the device with [`ErrorCode::Busy`].
    pub busy: u32,
    /// Requests refused by the device with any other code.
    pub other: u32,
}

fn bump(c: &mut u32) {
    *c = c.saturating_add(1);
}

impl ErrorCounters {
    /// All counters added up (saturating).
    #[must_use]
    pub const fn total(&self) -> u32 {
        self.frames()
            .saturating_add(self.out_of_range)
            .saturating_add(self.not_allowed)
            .saturating_add(self.busy)
            .saturating_add(self.other)
    }

    /// Bad frames only (everything but the refused requests).
    #[must_use]
    pub const fn frames(&self) -> u32 {
        self.overflow
            .saturating_add(self.cobs)
            .saturating_add(self.truncated)
            .saturating_add(self.crc)
            .saturating_add(self.version)
            .saturating_add(self.unknown_message)
            .saturating_add(self.decode)
    }

    fn count_frame(&mut self, e: &FrameError) {
        bump(match e {
            FrameError::Overflow => &mut self.overflow,
            FrameError::Cobs => &mut self.cobs,
            FrameError::Truncated => &mut self.truncated,
            FrameError::Crc => &mut self.crc,
            FrameError::Version { .. } => &mut self.version,
            FrameError::UnknownMessage { .. } => &mut self.unknown_message,
            FrameError::Decode { .. } => &mut self.decode,
        });
    }

    fn count_refusal(&mut self, code: ErrorCode) {
        bump(match code {
            ErrorCode::OutOfRange => &mut self.out_of_range,
            ErrorCode::NotAllowed => &mut self.not_allowed,
            ErrorCode::Busy => &mut self.busy,
            _ => &mut self.other,
        });
    }
}

/// The command handler core: turns each decoder result into exactly one reply frame.
///
/// Bad frames and out-of-range requests never reach the [`Device`]: they change nothing but
/// a counter in [`Handler::errors`] and are answered with [`Reply::Error`] — echoing the
/// request's `seq` when it can be trusted, [`crate::NO_SEQ`] otherwise.
#[derive(Clone, Debug, Default)]
pub struct Handler {
    errors: ErrorCounters,
    requests: u32,
    /// The last reply, for a retried request (same `seq`, same request).
    cache: ReplyCache,
}

fn done(r: Result<(), ErrorCode>) -> Result<Reply, ErrorCode> {
    r.map(|()| Reply::Ok)
}

impl Handler {
    /// A handler with zeroed counters.
    #[must_use]
    pub const fn new() -> Self {
        Handler {
            errors: ErrorCounters {
                overflow: 0,
                cobs: 0,
                truncated: 0,
                crc: 0,
                version: 0,
                unknown_message: 0,
                decode: 0,
                out_of_range: 0,
                not_allowed: 0,
                busy: 0,
                other: 0,
            },
            requests: 0,
            cache: ReplyCache::new(),
        }
    }

    /// Retried requests answered with the reply they already had (carried out once).
    #[must_use]
    pub const fn replayed(&self) -> u32 {
        self.cache.replayed()
    }

    /// The error counters.
    #[must_use]
    pub const fn errors(&self) -> &ErrorCounters {
        &self.errors
    }

    /// Well-formed requests handled (whether carried out or refused), saturating.
    #[must_use]
    pub const fn requests(&self) -> u32 {
        self.requests
    }

    /// The reply to a bad frame; counts it. Cannot touch the device.
    pub fn handle_error(&mut self, err: FrameError) -> Frame<Reply> {
        self.errors.count_frame(&err);
        err.reply()
    }

    /// Validates and carries out one request; returns its reply (same `seq`).
    pub fn handle_request<D: Device + ?Sized>(
        &mut self,
        frame: Frame<Request>,
        dev: &mut D,
    ) -> Frame<Reply> {
        if frame.version != VERSION {
            return self.handle_error(FrameError::Version {
                found: frame.version,
                seq: Some(frame.seq),
            });
        }
        if let Some(reply) = self.cache.replay(&frame) {
            dev.link_activity();
            return reply;
        }
        bump(&mut self.requests);
        let reply = match frame.body.validate() {
            Ok(()) => {
                dev.link_activity();
                self.dispatch(frame.body, dev)
            }
            Err(code) => Err(code),
        };
        let body = match reply {
            Ok(body) => body,
            Err(code) => {
                self.errors.count_refusal(code);
                Reply::Error(code)
            }
        };
        self.cache.keep(frame.seq, frame.body, body);
        Frame::new(frame.seq, body)
    }

    fn dispatch<D: Device + ?Sized>(&self, req: Request, dev: &mut D) -> Result<Reply, ErrorCode> {
        match req {
            Request::Ping => Ok(Reply::Ok),
            Request::GetStatus => {
                let mut status = dev.status();
                status.protocol_errors = self.errors.total();
                Ok(Reply::Status(status))
            }
            Request::Enable => done(dev.enable()),
            Request::Disable => done(dev.disable()),
            Request::ClearFault => match dev.persisting_fault() {
                Some(record) => Ok(Reply::FaultPersists(record)),
                None => done(dev.clear_fault()),
            },
            Request::SetClutchLength { length_um } => done(dev.set_clutch_length(length_um)),
            Request::SetStiffness {
                stiffness_mnm_per_rad,
            } => dev
                .set_stiffness(stiffness_mnm_per_rad)
                .map(|length_um| Reply::ClutchToSet { length_um }),
            Request::Move {
                target_urad,
                duration_ms,
            } => done(dev.command_move(target_urad, duration_ms)),
            Request::Step { target_urad } => done(dev.command_step(target_urad)),
            Request::Sine {
                amplitude_urad,
                frequency_mhz,
            } => done(dev.command_sine(amplitude_urad, frequency_mhz)),
            Request::Hold => done(dev.hold()),
            Request::SetGains(g) => done(dev.set_gains(Some(g))),
            Request::AutoGains => done(dev.set_gains(None)),
            Request::SetLimits(l) => done(dev.set_limits(&l)),
            Request::StreamTelemetry { rate_hz } => done(dev.set_telemetry_rate(rate_hz)),
            Request::Heartbeat => {
                dev.heartbeat();
                Ok(Reply::Ok)
            }
            Request::DisarmHeartbeat => {
                dev.disarm_heartbeat();
                Ok(Reply::Ok)
            }
            Request::GetLimits => Ok(Reply::Limits(dev.limits())),
            Request::GetSensors | Request::Nudge { .. } => crate::sensors::dispatch(req, dev),
            Request::Save => done(dev.save()),
            Request::Load => done(dev.load()),
            Request::FactoryReset => done(dev.factory_reset()),
            Request::FaultsLog { index } => dev
                .faults_log(index)
                .map(|(count, entry)| Reply::FaultsLog { count, entry }),
            Request::Impedance {
                target_urad,
                stiffness_mnm_per_rad,
                damping_unms_per_rad,
                torque_unm,
            } => done(dev.impedance(
                target_urad,
                stiffness_mnm_per_rad,
                damping_unms_per_rad,
                torque_unm,
            )),
            Request::SetBus(_) => crate::bus::dispatch(req, dev),
        }
    }

    /// [`Handler::handle_request`] or [`Handler::handle_error`] for one decoder result.
    pub fn handle<D: Device + ?Sized>(
        &mut self,
        input: Result<Frame<Request>, FrameError>,
        dev: &mut D,
    ) -> Frame<Reply> {
        match input {
            Ok(frame) => self.handle_request(frame, dev),
            Err(e) => self.handle_error(e),
        }
    }

    /// Feeds one byte to `decoder` and handles what it yields: `Some(reply)` exactly when
    /// the byte completed a frame (good or bad) or overflowed one.
    pub fn feed<D: Device + ?Sized>(
        &mut self,
        decoder: &mut Decoder<Request>,
        byte: u8,
        dev: &mut D,
    ) -> Option<Frame<Reply>> {
        match decoder.feed(byte) {
            Ok(None) => None,
            Ok(Some(frame)) => Some(self.handle_request(frame, dev)),
            Err(e) => Some(self.handle_error(e)),
        }
    }
}
