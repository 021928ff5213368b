//! The host link's task side: protocol frames in (bytes the UART receive interrupt
//! queued), one reply per frame out, and the telemetry samples the control tick queued.
//!
//! The firmware runs it in its `serial` task, below the control tick and the receive
//! interrupt, over the UART's transmitter (any [`embedded_io::Write`]). Every
//! decoder result goes through [`protocol::Handler`]: bad frames and out-of-range requests
//! change nothing but its error counters; good requests reach [`service::ServiceDevice`],
//! which prepares configurations here and applies each command to the shared actuator
//! under a lock, i.e. between two control ticks. Telemetry is sent only when no received
//! byte is waiting, so replies go first; the control tick never waits for the link (a full
//! queue drops the sample and counts it, `Status::telemetry_dropped`).

use crate::{Actuator, Service};
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
        }
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
    pub fn poll(&mut self, actuator: &mut impl Mutex<T = Actuator>) {
        self.service.log_latched_fault(actuator);
        loop {
            if let Some(byte) = self.rx.dequeue() {
                let mut device = self.service.device(actuator);
                if let Some(reply) = self.handler.feed(&mut self.decoder, byte, &mut device) {
                    self.send(&reply);
                }
            } else if let Some((seq, sample)) = self.telemetry.dequeue() {
                match telemetry_frame(seq, &sample) {
                    Ok(frame) => self.transmit(&frame),
                    Err(_) => self.failures.encode = self.failures.encode.saturating_add(1),
                }
            } else {
                return;
            }
        }
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
