//! Batch runs: the time-ordered input streams of one run ([`Streams`]), merged into events, and
//! [`run`] / [`run_streams`], which drive a [`Pipeline`] over them.

use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::sensors::{Observation, RANGE_RANK};

use super::{Estimator, Event, Pipeline, Progress, Trace};

/// Runs `filter` over time-ordered, validated IMU samples and ranges (see the module doc for the
/// event order).
pub fn run<F: Estimator>(filter: &mut F, imu: &[ImuSample], ranges: &[RangeMeasurement]) -> Result<Trace> {
    run_streams(filter, &Streams { imu, ranges, ..Streams::default() })
}

/// The time-ordered, validated input streams of one run.
#[derive(Debug, Clone, Copy, Default)]
pub struct Streams<'a> {
    /// IMU samples.
    pub imu: &'a [ImuSample],
    /// Ranges.
    pub ranges: &'a [RangeMeasurement],
    /// The measurements of every other sensor of the registry, merged in time order (at equal
    /// times by rank: [`uwbimu_vocabulary::sensors::merge`]).
    pub observations: &'a [Observation],
    /// Counts the IMU samples processed, for a progress bar (None: not counted).
    pub progress: Option<&'a Progress>,
    /// Sample the estimate with its error marginals into [`Trace::marginals`] at the first IMU
    /// step of every this many seconds (None: not sampled).
    pub marginals_every_s: Option<f64>,
}

impl Streams<'_> {
    /// The events of all streams merged by time; at equal times by rank ([`Event::rank`]; each
    /// stream keeps its own order).
    pub fn events(&self) -> impl Iterator<Item = Event> + '_ {
        let mut next = [0usize; 3];
        std::iter::from_fn(move || {
            // The key (time, rank) of each head; the earliest wins, the lower rank at equal times.
            let keys = [
                self.imu.get(next[0]).map(|s| (s.t_s, 0)),
                self.observations.get(next[1]).map(|o| (o.t_s(), o.rank())),
                self.ranges.get(next[2]).map(|r| (r.t_s, RANGE_RANK)),
            ];
            let mut first: Option<(usize, (f64, u8))> = None;
            for (k, key) in keys.into_iter().enumerate() {
                if let Some(key) = key.filter(|key| first.map_or(true, |(_, best)| *key < best)) {
                    first = Some((k, key));
                }
            }
            let (k, _) = first?;
            let event = match k {
                0 => Event::Imu(self.imu[next[0]]),
                1 => Event::Observation(self.observations[next[1]]),
                _ => Event::Range(self.ranges[next[2]]),
            };
            next[k] += 1;
            Some(event)
        })
    }
}

/// IMU samples counted at once in a [`Progress`] (a bar drawn a few times a second needs no more).
const PROGRESS_BATCH: u64 = 256;

/// Runs `filter` over all streams merged by time ([`Streams::events`]; see the module doc).
pub fn run_streams<F: Estimator>(filter: &mut F, streams: &Streams<'_>) -> Result<Trace> {
    let mut pipeline = Pipeline::for_estimator(filter)?;
    pipeline.record_steps(streams.imu.len());
    if let Some(every_s) = streams.marginals_every_s {
        pipeline.record_marginals(every_s)?;
    }
    let Some(last_imu_s) = streams.imu.last().map(|s| s.t_s) else {
        return Ok(Trace::default());
    };
    // The progress counter is shared with another thread: counted in batches, not per sample.
    let mut uncounted = 0;
    for event in streams.events().take_while(|e| e.t_s() <= last_imu_s) {
        if streams.progress.is_some_and(Progress::cancelled) {
            break;
        }
        pipeline.event(filter, &event)?;
        if let (Event::Imu(_), Some(p)) = (&event, streams.progress) {
            uncounted += 1;
            if uncounted == PROGRESS_BATCH {
                p.imu_samples(std::mem::take(&mut uncounted));
            }
        }
    }
    if let Some(p) = streams.progress {
        p.imu_samples(uncounted);
    }
    pipeline.finish(filter)?;
    let mut updates = Vec::with_capacity(streams.ranges.len() + streams.observations.len());
    pipeline.take_applied(&mut updates);
    Ok(Trace { steps: pipeline.take_steps(), updates, health: pipeline.health(), marginals: pipeline.take_marginals() })
}
