//! The link task's logic on the host: bytes in through the receive queue, replies and
//! telemetry out through an `embedded_io::Write`.

mod common;

use common::Cell;
use heapless::spsc::Queue;
use model::control::Config;
use model::servo::Servo;
use model::supervisor::SupervisorConfig;
use model::{Design, Length};
use protocol::{encode_to_vec, Decoder, Frame, Reply, Request, TelemetrySample};
use service::link::{Link, Sample, RX_QUEUE, TELEMETRY_QUEUE};
use service::{Actuator, Service};

/// Collects what the link sends; fails every write once `fail` is set.
#[derive(Default)]
struct Wire {
    bytes: Vec<u8>,
    fail: bool,
}

impl embedded_io::ErrorType for Wire {
    type Error = embedded_io::ErrorKind;
}

impl embedded_io::Write for Wire {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        if self.fail {
            return Err(embedded_io::ErrorKind::TimedOut);
        }
        self.bytes.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

fn replies(bytes: &[u8]) -> Vec<Frame<Reply>> {
    let mut d = Decoder::<Reply>::new();
    bytes
        .iter()
        .filter_map(|b| d.feed(*b).expect("the link sends good frames"))
        .collect()
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

#[test]
fn one_reply_per_frame_replies_before_telemetry_and_garbage_answered_once() {
    let (mut actuator, service) = parts();
    let mut rxq: Queue<u8, RX_QUEUE> = Queue::new();
    let mut tq: Queue<Sample, TELEMETRY_QUEUE> = Queue::new();
    let (mut rx_in, rx_out) = rxq.split();
    let (mut t_in, t_out) = tq.split();
    let mut link = Link::new(service, rx_out, t_out, Wire::default());

    let sample = TelemetrySample {
        tick: 7,
        ..TelemetrySample::default()
    };
    t_in.enqueue((41, sample)).unwrap();
    for b in encode_to_vec(&Frame::new(5, Request::Ping)).unwrap() {
        rx_in.enqueue(b).unwrap();
    }
    for b in [0x13, 0x37, 0xFF, 0x00] {
        rx_in.enqueue(b).unwrap();
    }
    for b in encode_to_vec(&Frame::new(6, Request::Enable)).unwrap() {
        rx_in.enqueue(b).unwrap();
    }
    link.poll(&mut actuator);

    let out = replies(&link.tx().bytes);
    assert_eq!(out.len(), 4, "{out:?}");
    assert_eq!((out[0].seq, out[0].body), (5, Reply::Ok));
    assert!(matches!(out[1].body, Reply::Error(_)), "{:?}", out[1]);
    assert_eq!((out[2].seq, out[2].body), (6, Reply::Ok));
    assert_eq!((out[3].seq, out[3].body), (41, Reply::Telemetry(sample)));
    assert_eq!(link.errors().frames(), 1);
    assert_eq!(
        actuator.0.servo.state(),
        model::servo::ServoState::Enabled,
        "the enable reached the servo"
    );
}

#[test]
fn a_refusing_transmitter_is_counted_not_fatal() {
    let (mut actuator, service) = parts();
    let mut rxq: Queue<u8, RX_QUEUE> = Queue::new();
    let mut tq: Queue<Sample, TELEMETRY_QUEUE> = Queue::new();
    let (mut rx_in, rx_out) = rxq.split();
    let (_t_in, t_out) = tq.split();
    let wire = Wire {
        fail: true,
        ..Wire::default()
    };
    let mut link = Link::new(service, rx_out, t_out, wire);
    for seq in 1..=3 {
        for b in encode_to_vec(&Frame::new(seq, Request::Ping)).unwrap() {
            rx_in.enqueue(b).unwrap();
        }
    }
    link.poll(&mut actuator);
    assert_eq!(link.failures().transmit, 3);
    assert!(link.tx().bytes.is_empty());
}

#[test]
fn a_full_telemetry_queue_drops_counts_and_skips_sequence_numbers() {
    use model::servo::TickInput;
    let (mut actuator, mut service) = parts();
    let mut tq: Queue<Sample, 4> = Queue::new(); // holds 3
    let (mut t_in, mut t_out) = tq.split();
    {
        let mut dev = service.device(&mut actuator);
        protocol::Device::set_telemetry_rate(&mut dev, 500).unwrap();
    }
    let a = &mut actuator.0;
    let input = TickInput {
        link_encoder: 0,
        gear_pot: Some(512),
        current_adc: 2048,
        supply_adc: None,
        read_error: None,
    };
    // 20 ticks at 500 Hz: 10 samples due; the link takes none, so 3 queue, 7 drop.
    let queued = (0..20)
        .filter(|_| {
            let out = a.servo.tick(&input);
            a.publish_tick(&input, &out, &mut t_in)
        })
        .count();
    assert_eq!(queued, 3);
    assert_eq!(a.telemetry.dropped(), 7);
    assert_eq!(a.status().telemetry_dropped, 7);
    let seqs: Vec<u16> = std::iter::from_fn(|| t_out.dequeue().map(|(s, _)| s)).collect();
    assert_eq!(seqs, [1, 2, 3]);
    // The next queued sample carries the counter past the dropped ones.
    let out = a.servo.tick(&input);
    let out2 = a.servo.tick(&input);
    let _ = a.publish_tick(&input, &out, &mut t_in);
    assert!(a.publish_tick(&input, &out2, &mut t_in));
    assert_eq!(t_out.dequeue().map(|(s, _)| s), Some(11));
}
