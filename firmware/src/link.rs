//! The host link's task side: protocol frames in (bytes the USART2 receive interrupt
//! queued), one reply per frame out, and the telemetry samples the control tick queued.
//!
//! Runs in the `serial` task, below the control tick and the receive interrupt. Every
//! decoder result goes through [`protocol::Handler`]: bad frames and out-of-range requests
//! change nothing but its error counters; good requests reach [`service::ServiceDevice`],
//! which prepares configurations here and applies each command to the shared actuator
//! under a lock, i.e. between two control ticks. Telemetry is sent only when no received
//! byte is waiting, so replies go first; the control tick never waits for the link (a full
//! queue drops the sample and counts it, `Status::telemetry_dropped`).

use crate::board::SerialTx;
use heapless::spsc::Consumer;
use protocol::{encode, telemetry_frame, Decoder, Frame, Handler, Reply, Request, MAX_FRAME};
use rtic::Mutex;
use service::{Actuator, Service};

/// Bytes the receive interrupt can queue ahead of the link task (about 4 full frames).
pub const RX_QUEUE: usize = 256;

/// Telemetry samples the control tick can queue ahead of the link task (32 ms at 500 Hz).
pub const TELEMETRY_QUEUE: usize = 16;

/// A telemetry sample and its sequence number (see [`protocol::Reply::Telemetry`]).
pub type Sample = (u16, protocol::TelemetrySample);

/// The link task's state.
pub struct Link {
    decoder: Decoder<Request>,
    handler: Handler,
    service: Service,
    rx: Consumer<'static, u8>,
    telemetry: Consumer<'static, Sample>,
    tx: SerialTx,
    encode_failures: u32,
}

impl Link {
    /// A link over these queues and transmitter, applying commands through `service`.
    pub fn new(
        service: Service,
        rx: Consumer<'static, u8>,
        telemetry: Consumer<'static, Sample>,
        tx: SerialTx,
    ) -> Self {
        Self {
            decoder: Decoder::new(),
            handler: Handler::new(),
            service,
            rx,
            telemetry,
            tx,
            encode_failures: 0,
        }
    }

    /// Handles everything queued: received bytes first (a reply for each completed frame),
    /// then telemetry, until both queues are empty.
    pub fn poll(&mut self, actuator: &mut impl Mutex<T = Actuator>) {
        loop {
            if let Some(byte) = self.rx.dequeue() {
                let mut device = self.service.device(actuator);
                if let Some(reply) = self.handler.feed(&mut self.decoder, byte, &mut device) {
                    self.send(&reply);
                }
            } else if let Some((seq, sample)) = self.telemetry.dequeue() {
                match telemetry_frame(seq, &sample) {
                    Ok(frame) => self.tx.write_all(&frame),
                    Err(_) => self.encode_failures = self.encode_failures.saturating_add(1),
                }
            } else {
                return;
            }
        }
    }

    fn send(&mut self, reply: &Frame<Reply>) {
        let mut buf = [0u8; MAX_FRAME];
        match encode(reply, &mut buf) {
            Ok(n) => self.tx.write_all(buf.get(..n).unwrap_or(&[])),
            Err(_) => self.encode_failures = self.encode_failures.saturating_add(1),
        }
    }
}
