//! The host link's task side: protocol frames in (bytes the UART receive interrupt
//! queued), one reply per frame out, and the telemetry samples the control tick queued.
//!
//! The firmware runs it in its `serial` task, below the control tick and the receive
//! interrupt, over the UART's transmitter (any [`embedded_io::Write`]). Every
//! decoder result goes through [`protocol::Handler`]: bad frames and out-of-range requests
//! change nothing but its error counters; good requests reach [`crate::ServiceDevice`],
//! which prepares configurations here and applies each command to the shared actuator
//! under a lock, i.e. between two control ticks. Telemetry is sent only when no received
//! byte is waiting, so replies go first; the control tick never waits for the link (a full
//! queue drops the sample and counts it, `Status::telemetry_dropped`).
//!
//! With [`Link::with_dynamixel`] the same line also carries the Dynamixel bus: a
//! [`crate::line::Splitter`] sends each byte to our decoder or to the [`Bus`] (see there
//! how it tells them apart), and the bus's status packets go out under the half-duplex
//! rules: only to a packet addressed to this device (the bus device's rule), after the
//! Return Delay Time counted from the end of the request, and only while the line is
//! between packets — a packet heard meanwhile holds the status back until the line is
//! quiet again, for at most [`HOLD_LIMIT_US`] (or the idle time if longer), then it is
//! dropped (counted). The link task waits for that time itself (a spin on the board's µs
//! clock, at its low priority, the control tick running above it).

use crate::dynamixel::Bus;
use crate::line::{Route, Splitter};
use crate::{Actuator, Service};
use dynamixel::{After, Reply as Status};
use embedded_io::Write;
use heapless::spsc::Consumer;
use protocol::{encode, telemetry_frame, Decoder, Frame, Handler, Reply, Request, MAX_FRAME};
use rtic_core::Mutex;

/// Size of the receive queue: a heapless `Queue<u8, RX_QUEUE>` holds `RX_QUEUE − 1` = 255
/// bytes (about 4 full frames) ahead of the link task.
pub const RX_QUEUE: usize = 256;

/// Size of the telemetry queue: it holds `TELEMETRY_QUEUE − 1` = 15 samples (30 ms at
/// 500 Hz) ahead of the link task.
pub const TELEMETRY_QUEUE: usize = 16;

/// Longest a status waits, past its due time, for the line to fall quiet, µs; then it is
/// dropped (the host has given up on it by then: the SDK waits about 34 ms). On a line
/// whose idle time is longer (bytes trickling in, as into an emulated USART), the idle
/// time: a packet heard meanwhile may take that long to arrive whole.
pub const HOLD_LIMIT_US: u64 = 30_000;

/// A telemetry sample and its sequence number (see [`protocol::Reply::Telemetry`]).
pub type Sample = (u16, protocol::TelemetrySample);

/// The link task's state, over the transmitter `W`.
pub struct Link<'q, W> {
    decoder: Decoder<Request>,
    handler: Handler,
    service: Service,
    rx: Consumer<'q, u8>,
    telemetry: Consumer<'q, Sample>,
    tx: W,
    failures: LinkFailures,
    dynamixel: Option<DynamixelLine>,
}

/// The Dynamixel side of the line.
struct DynamixelLine {
    bus: Bus,
    splitter: Splitter,
    /// The board's µs clock.
    clock: fn() -> u64,
    /// No byte for this long: the line is idle, µs.
    idle_us: u64,
    /// Longest a due status is held back, µs ([`HOLD_LIMIT_US`] or `idle_us`).
    hold_us: u64,
    /// When the last byte was taken from the receive queue, µs.
    last_rx_us: u64,
    /// Whether the idle line since `last_rx_us` has been reported.
    idle_seen: bool,
    /// A status waiting for its time: due at, µs.
    pending: Option<(u64, Status, After)>,
    stats: DynamixelStats,
}

/// What the Dynamixel side sent, held back and lost (saturating counters).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DynamixelStats {
    /// Status packets sent.
    pub sent: u32,
    /// Status packets dropped: the line was not quiet within the hold limit of their
    /// due time, or a new instruction arrived before they went out.
    pub dropped: u32,
    /// Packets cut short: the line fell idle in the middle of one, which was abandoned
    /// (noise, a sender that stopped, or bytes that came too slowly).
    pub abandoned: u32,
}

impl DynamixelStats {
    /// Nothing sent, held back or lost (a const for a task's local state).
    pub const NONE: DynamixelStats = DynamixelStats {
        sent: 0,
        dropped: 0,
        abandoned: 0,
    };
}

/// What the link could not send (saturating counters).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkFailures {
    /// Frames that did not encode (never for this crate's messages).
    pub encode: u32,
    /// Frames the transmitter refused (partly sent: the host sees a bad frame).
    pub transmit: u32,
}

impl<'q, W: Write> Link<'q, W> {
    /// A link over these queues and transmitter, applying commands through `service`.
    pub fn new(
        service: Service,
        rx: Consumer<'q, u8>,
        telemetry: Consumer<'q, Sample>,
        tx: W,
    ) -> Self {
        Self {
            decoder: Decoder::new(),
            handler: Handler::new(),
            service,
            rx,
            telemetry,
            tx,
            failures: LinkFailures::default(),
            dynamixel: None,
        }
    }

    /// The same link serving the Dynamixel `bus` on the same line, with the board's µs
    /// `clock` and `idle_us`, the silence after which a partial packet is abandoned (a
    /// few character times on a real line; longer where bytes trickle in, as from QEMU's
    /// emulated USART).
    #[must_use]
    pub fn with_dynamixel(mut self, bus: Bus, clock: fn() -> u64, idle_us: u64) -> Self {
        self.service.bus_started(bus.settings());
        self.dynamixel = Some(DynamixelLine {
            bus,
            splitter: Splitter::new(),
            clock,
            idle_us,
            hold_us: HOLD_LIMIT_US.max(idle_us),
            last_rx_us: clock(),
            idle_seen: true,
            pending: None,
            stats: DynamixelStats::default(),
        });
        self
    }

    /// The Dynamixel bus device, if served (its settings: ID, baud, protocol).
    pub fn dynamixel(&mut self) -> Option<&mut Bus> {
        self.dynamixel.as_mut().map(|d| &mut d.bus)
    }

    /// The command service (its stored settings: [`Service::boot_bus_settings`]).
    pub fn service(&self) -> &Service {
        &self.service
    }

    /// The command service, to configure (e.g. [`Service::set_uart_rates`]).
    pub fn service_mut(&mut self) -> &mut Service {
        &mut self.service
    }

    /// What the Dynamixel side sent and dropped.
    pub fn dynamixel_stats(&self) -> Option<DynamixelStats> {
        self.dynamixel.as_ref().map(|d| d.stats)
    }

    /// What could not be sent so far.
    pub fn failures(&self) -> LinkFailures {
        self.failures
    }

    /// Well-formed requests handled so far (carried out or refused).
    pub fn requests(&self) -> u32 {
        self.handler.requests()
    }

    /// The protocol's error counters.
    pub fn errors(&self) -> &protocol::ErrorCounters {
        self.handler.errors()
    }

    /// The transmitter (e.g. to read what a test transmitter collected).
    pub fn tx(&self) -> &W {
        &self.tx
    }

    /// Handles everything queued (after logging a newly latched fault to the settings
    /// store, [`Service::log_latched_fault`]): received bytes first (a reply for each completed frame),
    /// then telemetry, until both queues are empty.
    ///
    /// With the Dynamixel bus, a status waiting for its time keeps the task here (taking
    /// received bytes meanwhile) until it is sent or dropped; an idle line is noticed on
    /// the first call after it began (the firmware calls this every control tick).
    pub fn poll(&mut self, actuator: &mut impl Mutex<T = Actuator>) {
        self.service.log_latched_fault(actuator);
        self.service.finish_calibration(actuator);
        if let Some(d) = self.dynamixel.as_mut() {
            d.bus
                .set_calibration_state(self.service.calibration_register(actuator));
        }
        loop {
            if let Some(byte) = self.rx.dequeue() {
                match self.dynamixel.as_mut() {
                    Some(d) => {
                        d.last_rx_us = (d.clock)();
                        d.idle_seen = false;
                        for route in d.splitter.route(byte).into_iter().flatten() {
                            match route {
                                Route::Ours(b) => self.feed_ours(b, actuator),
                                Route::Dynamixel(b) => self.feed_dynamixel(b, actuator),
                            }
                        }
                    }
                    None => self.feed_ours(byte, actuator),
                }
            } else if self.dynamixel_waits(actuator) {
                // A status is due soon or the line just fell idle: keep going.
            } else if let Some((seq, sample)) = self.telemetry.dequeue() {
                match telemetry_frame(seq, &sample) {
                    Ok(frame) => self.transmit(&frame),
                    Err(_) => self.failures.encode = self.failures.encode.saturating_add(1),
                }
            } else {
                // Nothing waits: bus settings changed on either side go to the store now.
                self.service.store_bus_settings(actuator);
                return;
            }
        }
    }

    fn feed_ours(&mut self, byte: u8, actuator: &mut impl Mutex<T = Actuator>) {
        let mut device = self.service.device(actuator);
        if let Some(reply) = self.handler.feed(&mut self.decoder, byte, &mut device) {
            self.send(&reply);
            // A `SetBus` takes effect once its reply is out.
            if let Some(settings) = self.service.take_bus_request() {
                if let Some(d) = self.dynamixel.as_mut() {
                    d.bus.apply(&settings);
                    let _ = d.bus.settings_changed();
                }
            }
        }
    }

    fn feed_dynamixel(&mut self, byte: u8, actuator: &mut impl Mutex<T = Actuator>) {
        let Some(d) = self.dynamixel.as_mut() else {
            return;
        };
        d.bus.push(byte);
        d.take_outputs(&mut self.service, actuator);
        if !d.bus.receiving() {
            d.splitter.packet_decided();
        }
    }

    /// The Dynamixel side's timed work: the idle line, then a status that is due. Returns
    /// whether the caller should come back at once (a status is still waiting).
    fn dynamixel_waits(&mut self, actuator: &mut impl Mutex<T = Actuator>) -> bool {
        let Some(d) = self.dynamixel.as_mut() else {
            return false;
        };
        let now = (d.clock)();
        let quiet = now.saturating_sub(d.last_rx_us);
        if !d.idle_seen && quiet >= d.idle_us {
            d.idle_seen = true;
            if d.bus.receiving() {
                d.stats.abandoned = d.stats.abandoned.saturating_add(1);
            }
            d.bus.idle();
            d.splitter.idle();
            d.take_outputs(&mut self.service, actuator);
        }
        let Some((due, _, _)) = d.pending.as_ref() else {
            return false;
        };
        let due = *due;
        if now < due {
            return true;
        }
        if d.splitter.in_packet() {
            // Never over another packet: wait for it to end, within reason.
            if now - due > d.hold_us {
                d.pending = None;
                d.stats.dropped = d.stats.dropped.saturating_add(1);
            }
            return d.pending.is_some();
        }
        if let Some((_, status, after)) = d.pending.take() {
            d.stats.sent = d.stats.sent.saturating_add(1);
            if after == After::Reboot {
                d.bus.restart();
            }
            let bytes = status.bytes;
            self.transmit(&bytes);
        }
        false
    }

    fn send(&mut self, reply: &Frame<Reply>) {
        let mut buf = [0u8; MAX_FRAME];
        match encode(reply, &mut buf) {
            Ok(n) => self.transmit(buf.get(..n).unwrap_or(&[])),
            Err(_) => self.failures.encode = self.failures.encode.saturating_add(1),
        }
    }

    fn transmit(&mut self, frame: &[u8]) {
        if self.tx.write_all(frame).is_err() {
            self.failures.transmit = self.failures.transmit.saturating_add(1);
        }
    }
}

impl DynamixelLine {
    /// Every output of the bus for what it heard: the status to send (timed from the last
    /// byte received), and what to do once it is sent.
    fn take_outputs(&mut self, service: &mut Service, actuator: &mut impl Mutex<T = Actuator>) {
        while let Some(out) = self.bus.poll(service, actuator) {
            if self.pending.take().is_some() {
                // A new instruction before the last status went out: the host moved on.
                self.stats.dropped = self.stats.dropped.saturating_add(1);
            }
            match out.reply {
                Some(status) => {
                    let due = self.last_rx_us + u64::from(status.delay_us);
                    self.pending = Some((due, status, out.after));
                }
                None if out.after == After::Reboot => self.bus.restart(),
                None => {}
            }
        }
        // An EEPROM-area write: the service stores it (see `crate::bus_settings`).
        if self.bus.settings_changed() {
            service.bus_in_force(self.bus.settings());
        }
    }
}
