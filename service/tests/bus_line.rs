//! One line, both protocols: the link task with the Dynamixel bus, on the host, with a
//! clock that advances 10 µs per reading (the task spins on the board's clock while a
//! status waits for its time).

mod common;

use common::Cell;
use dynamixel::instruction as ins;
use dynamixel::{v1, Protocol};
use heapless::spsc::Queue;
use model::control::Config;
use model::servo::Servo;
use model::supervisor::SupervisorConfig;
use model::{Design, Length};
use protocol::{encode, Decoder, Frame, Reply, Request};
use service::dynamixel::Bus;
use service::link::{Link, Sample, HOLD_LIMIT_US, RX_QUEUE, TELEMETRY_QUEUE};
use service::{Actuator, Service};
use std::sync::atomic::{AtomicU64, Ordering};

static NOW_US: AtomicU64 = AtomicU64::new(0);

fn clock() -> u64 {
    NOW_US.fetch_add(10, Ordering::Relaxed)
}

/// What the link sent, each write with the time it went out.
#[derive(Default)]
struct Wire {
    writes: Vec<(u64, Vec<u8>)>,
}

impl embedded_io::ErrorType for Wire {
    type Error = embedded_io::ErrorKind;
}

impl embedded_io::Write for Wire {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        self.writes
            .push((NOW_US.load(Ordering::Relaxed), buf.to_vec()));
        Ok(buf.len())
    }
    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

fn parts() -> (Cell, Service) {
    let design = Design::paper();
    let config = Config::paper(Length::from_int(3));
    let sup = SupervisorConfig::DEFAULT;
    let servo = Servo::new(&design, &config, &sup).unwrap();
    (
        Cell(Actuator::aligned(servo)),
        Service::new(design, config, sup),
    )
}

fn packet(id: u8, code: u8, params: &[u8]) -> Vec<u8> {
    let mut buf = [0u8; v1::MAX_PACKET];
    let n = v1::encode(id, code, params, &mut buf).unwrap();
    buf[..n].to_vec()
}

const IDLE_US: u64 = 2_000;

// One test: the clock is shared.
#[test]
fn both_protocols_share_the_line_under_the_half_duplex_rules() {
    let (mut actuator, service) = parts();
    let mut rxq: Queue<u8, RX_QUEUE> = Queue::new();
    let mut tq: Queue<Sample, TELEMETRY_QUEUE> = Queue::new();
    let (mut rx_in, rx_out) = rxq.split();
    let (_t_in, t_out) = tq.split();
    let mut link = Link::new(service, rx_out, t_out, Wire::default()).with_dynamixel(
        Bus::new(1, Protocol::V1),
        clock,
        IDLE_US,
    );
    let mut feed = |bytes: &[u8], link: &mut Link<'_, Wire>| {
        for &b in bytes {
            rx_in.enqueue(b).unwrap();
        }
        link.poll(&mut actuator);
    };

    // A PING to ID 1: answered after the default return delay, 500 µs.
    let t0 = NOW_US.load(Ordering::Relaxed);
    feed(&packet(1, ins::PING, &[]), &mut link);
    let (at, bytes) = link.tx().writes.last().cloned().unwrap();
    assert_eq!(bytes, [0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC]);
    assert!(at - t0 >= 500, "sent {} µs after the request", at - t0);
    assert!(at - t0 < 600, "sent {} µs after the request", at - t0);

    // Another ID and a broadcast: never answered.
    let n = link.tx().writes.len();
    feed(&packet(2, ins::PING, &[]), &mut link);
    feed(&packet(0xFE, ins::WRITE, &[25, 1]), &mut link);
    assert_eq!(link.tx().writes.len(), n);

    // One of our frames right after a packet: answered as before, same sequence number.
    let mut buf = [0u8; protocol::MAX_FRAME];
    let len = encode(&Frame::new(9, Request::Ping), &mut buf).unwrap();
    let mut both = packet(1, ins::READ, &[36, 2]);
    both.extend_from_slice(&buf[..len]);
    feed(&both, &mut link);
    let sent: Vec<Vec<u8>> = link.tx().writes[n..].iter().map(|w| w.1.clone()).collect();
    assert_eq!(sent.len(), 2, "{sent:?}");
    let ours = sent.iter().find(|b| b[0] != 0xFF).unwrap();
    let mut d = Decoder::<Reply>::new();
    let frame = ours.iter().find_map(|b| d.feed(*b).unwrap()).unwrap();
    assert_eq!((frame.seq, frame.body), (9, Reply::Ok));
    let status = sent.iter().find(|b| b[0] == 0xFF).unwrap();
    assert_eq!(
        &status[..5],
        &[0xFF, 0xFF, 0x01, 0x04, 0x00],
        "READ of present position"
    );

    // A packet on the line when the status is due: held until the line is idle.
    let n = link.tx().writes.len();
    let mut busy = packet(1, ins::PING, &[]);
    busy.extend_from_slice(&[0xFF, 0xFF, 0x02]); // another packet begins
    let t1 = NOW_US.load(Ordering::Relaxed);
    feed(&busy, &mut link);
    assert_eq!(link.tx().writes.len(), n + 1);
    let (at, bytes) = link.tx().writes.last().cloned().unwrap();
    assert_eq!(bytes, [0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC]);
    assert!(
        at - t1 >= IDLE_US,
        "not over another packet: sent once the line was idle"
    );
    assert!(at - t1 < IDLE_US + HOLD_LIMIT_US);
    let stats = link.dynamixel_stats().unwrap();
    assert_eq!(stats.dropped, 0);
    // The 3 bytes of the other packet were all that came: abandoned at the idle line, the
    // only packet cut short so far.
    assert_eq!(stats.abandoned, 1);

    // Our protocol switches the bus to Protocol 2.0.
    assert_eq!(link.dynamixel().unwrap().protocol(), Protocol::V1);
}
