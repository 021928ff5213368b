//! Recording telemetry: [`Client::record`].

use std::time::{Duration, Instant};

use protocol::{
    FaultRecord, FaultSet, TelemetrySample, TELEMETRY_RATE_MAX_HZ, TELEMETRY_RATE_MIN_HZ,
};

use crate::client::{Client, TelemetryFrame};
use crate::{Error, Result};

/// How long the telemetry must stay quiet after streaming stops before the recording is
/// considered drained.
const DRAIN_QUIET: Duration = Duration::from_millis(50);
/// Longest drain after streaming stops.
const DRAIN_MAX: Duration = Duration::from_secs(1);

/// Progress of a recording, for a progress bar.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecordProgress {
    /// Board ticks (ms) covered so far.
    pub ticks_done: u32,
    /// Board ticks (ms) to cover.
    pub ticks_total: u32,
    /// Samples kept so far.
    pub samples: usize,
}

/// Samples missing between two received samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Gap {
    /// Tick of the sample before the gap.
    pub after_tick: u32,
    /// Tick of the sample after the gap.
    pub before_tick: u32,
    /// Samples missing at the recording's rate.
    pub missing: u32,
}

/// A telemetry recording ([`Client::record`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Recording {
    /// Requested rate, Hz.
    pub rate_hz: u16,
    /// Requested span, board ticks (ms).
    pub ticks: u32,
    /// The samples, in order: the first one received after streaming started and every
    /// later one whose tick is less than `ticks` after the first's.
    pub samples: Vec<TelemetrySample>,
    /// Where samples are missing (by tick, at `rate_hz`), including before the first
    /// sample past the end of the span.
    pub gaps: Vec<Gap>,
    /// Sum of [`Gap::missing`].
    pub missing_samples: u64,
    /// Samples skipped according to the telemetry frames' counter (dropped by the board or
    /// lost on the line).
    pub counter_skipped: u64,
    /// Increase of the board's `telemetry_dropped` counter during the recording.
    pub dropped: u32,
    /// The board's `telemetry_dropped` counter after the recording.
    pub dropped_total: u32,
    /// Frames that did not decode during the recording.
    pub bad_frames: u64,
    /// Faults latched at the board before the recording.
    pub faults_before: FaultSet,
    /// Faults seen during the recording: in any sample, or latched after it.
    pub faults_seen: FaultSet,
    /// The board's first fault after the recording, if any.
    pub first_fault_after: Option<FaultRecord>,
}

impl Recording {
    /// Samples expected at `rate_hz` over `ticks` ms.
    #[must_use]
    pub fn expected_samples(&self) -> u64 {
        u64::from(self.ticks) * u64::from(self.rate_hz) / 1000
    }

    /// Faults that latched during the recording (seen, and not latched before it).
    #[must_use]
    pub fn new_faults(&self) -> FaultSet {
        FaultSet(self.faults_seen.0 & !self.faults_before.0)
    }
}

/// Gaps by tick at `rate_hz`, and samples skipped according to the counter, between
/// consecutive frames.
#[must_use]
pub fn find_gaps(frames: &[TelemetryFrame], rate_hz: u16) -> (Vec<Gap>, u64) {
    let period = 1000.0 / f64::from(rate_hz.max(1));
    let mut gaps = Vec::new();
    let mut skipped = 0u64;
    for w in frames.windows(2) {
        let [a, b] = w else { continue };
        // Ticks wrap (u32 ms: after 49.7 days).
        let d = b.sample.tick.wrapping_sub(a.sample.tick);
        let n = (f64::from(d) / period).round();
        if n > 1.0 {
            gaps.push(Gap {
                after_tick: a.sample.tick,
                before_tick: b.sample.tick,
                missing: (n - 1.0).min(f64::from(u32::MAX)) as u32,
            });
        }
        let c = b.counter.wrapping_sub(a.counter);
        if (1..=0x8000).contains(&c) {
            skipped += u64::from(c - 1);
        }
    }
    (gaps, skipped)
}

impl Client {
    /// Streams telemetry at `rate_hz` (10–500 Hz) until the samples span `duration` of
    /// board ticks (1 tick = 1 ms), then stops streaming, drains what is still in flight,
    /// and reports the gaps and the board's dropped-sample counter. `progress` is called
    /// after every sample. Telemetry buffered before the call is discarded; streaming is
    /// off afterwards (also after an error, as far as the link allows).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a rate outside 10–500 Hz or a span under 1 ms or over
    /// `u32::MAX` ms; [`Error::NoTelemetry`] if no sample arrives within the timeout;
    /// [`Error::TickBackwards`]; any error of the requests involved.
    pub fn record(
        &mut self,
        duration: Duration,
        rate_hz: u16,
        mut progress: impl FnMut(&RecordProgress),
    ) -> Result<Recording> {
        if !(TELEMETRY_RATE_MIN_HZ..=TELEMETRY_RATE_MAX_HZ).contains(&rate_hz) {
            return Err(Error::InvalidArgument(format!(
                "telemetry rate {rate_hz} Hz is outside {TELEMETRY_RATE_MIN_HZ}..={TELEMETRY_RATE_MAX_HZ} Hz"
            )));
        }
        let ticks = u32::try_from(duration.as_millis())
            .ok()
            .filter(|&t| t > 0)
            .ok_or_else(|| {
                Error::InvalidArgument(format!(
                    "recording span {duration:?} is not between 1 ms and {} ms",
                    u32::MAX
                ))
            })?;
        let before = self.status()?;
        let bad0 = self.stats().bad_frames;
        self.stream_telemetry(rate_hz)?;
        self.clear_telemetry();
        let collected = self.collect(ticks, &mut progress);
        let stopped = self.stream_telemetry(0);
        let frames = collected?;
        stopped?;
        self.drain()?;
        let after = self.status()?;
        let (gaps, counter_skipped) = find_gaps(&frames, rate_hz);
        let seen = frames
            .iter()
            .fold(after.faults.0, |m, f| m | f.sample.faults.0);
        let mut samples: Vec<TelemetrySample> = frames.iter().map(|f| f.sample).collect();
        samples.pop(); // the first sample past the span
        Ok(Recording {
            rate_hz,
            ticks,
            samples,
            missing_samples: gaps.iter().map(|g| u64::from(g.missing)).sum(),
            gaps,
            counter_skipped,
            dropped: after
                .telemetry_dropped
                .saturating_sub(before.telemetry_dropped),
            dropped_total: after.telemetry_dropped,
            bad_frames: self.stats().bad_frames.saturating_sub(bad0),
            faults_before: before.faults,
            faults_seen: FaultSet(seen),
            first_fault_after: after.first_fault,
        })
    }

    /// Collects frames until one is `ticks` or more after the first (that one included).
    fn collect(
        &mut self,
        ticks: u32,
        progress: &mut impl FnMut(&RecordProgress),
    ) -> Result<Vec<TelemetryFrame>> {
        let mut frames: Vec<TelemetryFrame> = Vec::new();
        let capacity = usize::try_from(ticks).unwrap_or(usize::MAX).min(1 << 20);
        frames.reserve(capacity / 2);
        loop {
            let Some(f) = self.next_telemetry(self.timeout())? else {
                return Err(Error::NoTelemetry {
                    timeout: self.timeout(),
                });
            };
            let tick = f.sample.tick;
            if let Some(prev) = frames.last() {
                // Forward by less than half the counter's range, wrapping included.
                let step = tick.wrapping_sub(prev.sample.tick);
                if step == 0 || step > u32::MAX / 2 {
                    return Err(Error::TickBackwards {
                        from: prev.sample.tick,
                        to: tick,
                    });
                }
            }
            let t0 = frames.first().map_or(tick, |g| g.sample.tick);
            let done = tick.wrapping_sub(t0);
            frames.push(f);
            progress(&RecordProgress {
                ticks_done: done.min(ticks),
                ticks_total: ticks,
                samples: frames.len() - usize::from(done >= ticks),
            });
            if done >= ticks {
                return Ok(frames);
            }
        }
    }

    /// Reads until no telemetry has arrived for [`DRAIN_QUIET`] (at most [`DRAIN_MAX`]) and
    /// drops the buffered telemetry.
    fn drain(&mut self) -> Result<()> {
        let start = Instant::now();
        while start.elapsed() < DRAIN_MAX {
            if self.next_telemetry(DRAIN_QUIET)?.is_none() {
                break;
            }
        }
        self.clear_telemetry();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(counter: u16, tick: u32) -> TelemetryFrame {
        TelemetryFrame {
            counter,
            sample: TelemetrySample {
                tick,
                ..TelemetrySample::default()
            },
        }
    }

    #[test]
    fn gaps_by_tick_and_counter() {
        // 100 Hz: one sample every 10 ticks; 20 → 50 misses 30 and 40; the counter says
        // one was dropped at the board (the other was lost on the line).
        let f = [
            frame(1, 10),
            frame(2, 20),
            frame(4, 50),
            frame(5, 60),
            frame(6, 70),
        ];
        let (gaps, skipped) = find_gaps(&f, 100);
        assert_eq!(
            gaps,
            vec![Gap {
                after_tick: 20,
                before_tick: 50,
                missing: 2
            }]
        );
        assert_eq!(skipped, 1);
    }

    #[test]
    fn uneven_decimation_is_not_a_gap() {
        // 300 Hz from a 1 kHz tick: intervals 3, 3, 4.
        let ticks = [0, 3, 6, 10, 13, 16, 20];
        let f: Vec<_> = ticks
            .iter()
            .enumerate()
            .map(|(i, &t)| frame(i as u16, t))
            .collect();
        assert_eq!(find_gaps(&f, 300), (vec![], 0));
    }

    #[test]
    fn ticks_wrap() {
        let f = [frame(1, u32::MAX - 1), frame(2, 0), frame(4, 4)];
        let (gaps, skipped) = find_gaps(&f, 500);
        assert_eq!(skipped, 1);
        assert_eq!(
            gaps,
            vec![Gap {
                after_tick: 0,
                before_tick: 4,
                missing: 1
            }]
        );
    }

    #[test]
    fn counter_wraps() {
        let f = [frame(u16::MAX, 0), frame(0, 2), frame(2, 6)];
        let (gaps, skipped) = find_gaps(&f, 500);
        assert_eq!(skipped, 1);
        assert_eq!(gaps.len(), 1);
    }
}
