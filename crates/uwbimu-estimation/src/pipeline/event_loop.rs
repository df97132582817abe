//! The event loop ([`Pipeline`]): its state and its calls per event (IMU sample, range,
//! observation), the range epochs it gathers and applies, and the steps and updates it records.

use uwbimu_vocabulary::config::GateConfig;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::sensors::Observation;

use super::marginals::MarginalsSampler;
use super::tally::Tally;
#[cfg(doc)]
use super::Stream;
use super::{Estimator, Event, Health, Marginals, Measured, StepRecord, UpdateRecord, STATUS_REJECTED};
use crate::epoch::{align_to_reference, EpochAssembler};
use crate::gate::Gate;
use crate::update::UpdateReport;

/// The event loop's own state: the gate, the open range epoch, scratch buffers, what it counted,
/// and the applied updates (and recorded steps) not yet collected. Each call takes the estimator
/// it drives; [`Stream`] bundles the two.
#[derive(Debug, Clone)]
pub struct Pipeline {
    gate: Gate,
    epochs: EpochAssembler,
    aligned: Vec<(usize, f64)>,
    reports: Vec<UpdateReport>,
    applied: Vec<UpdateRecord>,
    last_t_s: Option<f64>,
    tally: Tally,
    pending_step: Option<f64>,
    steps: Option<Vec<StepRecord>>,
    marginals: Option<MarginalsSampler>,
}

impl Pipeline {
    /// A loop for `anchors` with the epoch window `epoch_window_s` (s) and the plausibility gate
    /// of `gate`.
    pub fn new(epoch_window_s: f64, anchors: &[Vec3], gate: &GateConfig) -> Result<Self> {
        Ok(Self {
            gate: Gate::new(anchors, gate),
            epochs: EpochAssembler::new(epoch_window_s, anchors.len())?,
            aligned: Vec::with_capacity(anchors.len()),
            reports: Vec::with_capacity(anchors.len()),
            applied: Vec::with_capacity(anchors.len()),
            last_t_s: None,
            tally: Tally::default(),
            pending_step: None,
            steps: None,
            marginals: None,
        })
    }

    /// The loop for `est` (its epoch window, anchors and gate).
    pub fn for_estimator<E: Estimator>(est: &E) -> Result<Self> {
        Self::new(est.epoch_window_s(), est.anchors(), &est.gate_config())
    }

    /// Records one [`StepRecord`] per IMU sample from now on, taken once the events at its time
    /// are in (collected by [`Pipeline::take_steps`]); `capacity` steps are reserved.
    pub fn record_steps(&mut self, capacity: usize) {
        self.steps = Some(Vec::with_capacity(capacity));
    }

    /// Samples the estimate with its error marginals ([`Estimator::marginals`]) at the first step
    /// of every `every_s` from now on (collected by [`Pipeline::take_marginals`]); fails unless
    /// `every_s` is positive and finite.
    pub fn record_marginals(&mut self, every_s: f64) -> Result<()> {
        if !(every_s > 0.0 && every_s.is_finite()) {
            return Err(Error::InvalidCall(format!("marginals_every_s must be positive and finite, got {every_s}")));
        }
        self.marginals = Some(MarginalsSampler::new(every_s));
        Ok(())
    }

    /// The marginals sampled since [`Pipeline::record_marginals`] (empty when not sampling).
    pub fn take_marginals(&mut self) -> Vec<Marginals> {
        self.marginals.as_mut().map(MarginalsSampler::take).unwrap_or_default()
    }

    /// Checks that an event at `t_s` is not earlier than the previous one.
    fn check_order(&mut self, name: &'static str, t_s: f64) -> Result<()> {
        if !t_s.is_finite() {
            return Err(Error::NonFinite { name, row: 0, col: 0, value: t_s });
        }
        match self.last_t_s {
            Some(prev) if t_s < prev => Err(Error::NonMonotonicTime { name, row: 0, prev_s: prev, got_s: t_s }),
            _ => {
                self.last_t_s = Some(t_s);
                Ok(())
            }
        }
    }

    /// Takes an IMU sample: closes the open epoch first if the sample is past its window, then
    /// predicts.
    pub fn imu<E: Estimator>(&mut self, est: &mut E, s: &ImuSample) -> Result<()> {
        self.check_order("imu", s.t_s)?;
        if self.epochs.expires_before(s.t_s) {
            self.flush(est)?;
        }
        est.predict(s.t_s, &s.accel, &s.gyro)?;
        self.tally.check_propagation(est)
    }

    /// An IMU sample at `t_s` the gate rejected: once the filter has started, it is propagated
    /// to `t_s` with the last sample held (closing an epoch the sample is past first) and the
    /// step is recorded like any other, flagged [`STATUS_REJECTED`], so a run keeps one step per
    /// IMU sample; before the first accepted sample there is nothing to propagate.
    fn held_imu<E: Estimator>(&mut self, est: &mut E, t_s: f64) -> Result<()> {
        if est.time_s().is_none() {
            return Ok(());
        }
        self.check_order("imu", t_s)?;
        if self.epochs.expires_before(t_s) {
            self.flush(est)?;
        }
        est.advance_to(t_s)?;
        self.tally.check_propagation(est)?;
        self.pending_step = Some(t_s);
        Ok(())
    }

    /// Takes a range: before the first IMU sample it is counted and skipped; otherwise it closes
    /// the open epoch if it does not fit, joins the (new) open epoch, and closes it when it holds
    /// every anchor.
    pub fn range<E: Estimator>(&mut self, est: &mut E, r: &RangeMeasurement) -> Result<()> {
        if est.time_s().is_none() {
            self.tally.health.ranges_before_start += 1;
            return Ok(());
        }
        self.check_order("range", r.t_s)?;
        if self.epochs.closes_before(r) {
            self.flush(est)?;
        }
        self.epochs.push(*r);
        if self.epochs.is_full() {
            self.flush(est)?;
        }
        Ok(())
    }

    /// Takes an observation, applied at its own time (skipped before the first IMU sample); its
    /// report is kept for [`Pipeline::take_applied`].
    pub fn observation<E: Estimator>(&mut self, est: &mut E, o: &Observation) -> Result<()> {
        if est.time_s().is_none() {
            return Ok(());
        }
        self.check_order(o.stream(), o.t_s())?;
        let mut report = UpdateReport::skipped();
        self.tally.guarded(est, |est| {
            report = est.observe(o)?;
            Ok(())
        })?;
        self.applied.push(UpdateRecord { t_s: o.t_s(), epoch_t_s: o.t_s(), measured: Measured::Observation(*o), report });
        Ok(())
    }

    /// Takes any event: records the step of the previous IMU sample once the event is later than
    /// it (when recording), drops what the plausibility gate rejects (counted), then
    /// [`Pipeline::imu`], [`Pipeline::range`] or [`Pipeline::observation`].
    pub fn event<E: Estimator>(&mut self, est: &mut E, event: &Event) -> Result<()> {
        let t_s = event.t_s();
        if let Some(step_s) = self.pending_step.filter(|&step_s| t_s > step_s) {
            self.record_step(est, step_s);
        }
        if let Some(rejection) = self.gate.check(event) {
            self.tally.health.rejected.count(rejection);
            self.tally.status |= STATUS_REJECTED;
            if let Event::Imu(s) = event {
                self.held_imu(est, s.t_s)?;
            }
            return Ok(());
        }
        match event {
            Event::Imu(s) => {
                self.imu(est, s)?;
                self.pending_step = Some(t_s);
                Ok(())
            }
            Event::Range(r) => self.range(est, r),
            Event::Observation(o) => self.observation(est, o),
        }
    }

    fn record_step<E: Estimator>(&mut self, est: &E, t_s: f64) {
        self.pending_step = None;
        if let Some(sampler) = self.marginals.as_mut() {
            if sampler.due(t_s) {
                sampler.push(est.marginals(t_s));
            }
        }
        if let Some(steps) = self.steps.as_mut() {
            steps.push(StepRecord { status: self.tally.status, ..est.record(t_s) });
            self.tally.status = 0;
        }
    }

    /// The end of the input: records the last step and applies the open epoch.
    pub fn finish<E: Estimator>(&mut self, est: &mut E) -> Result<()> {
        if let Some(step_s) = self.pending_step {
            self.record_step(est, step_s);
        }
        self.flush(est)
    }

    /// Applies the open epoch (if any) at `max(time of its last range, filter time)`, its ranges
    /// aligned to that time, and keeps one [`UpdateRecord`] per range for [`Pipeline::take_applied`].
    pub fn flush<E: Estimator>(&mut self, est: &mut E) -> Result<()> {
        let Some(last) = self.epochs.ranges().last() else {
            return Ok(());
        };
        let t_ref = est.time_s().map_or(last.t_s, |t| t.max(last.t_s));
        est.advance_to(t_ref)?;
        self.tally.check_propagation(est)?;
        let (tag, velocity) = est.tag_motion(last.tag);
        let epoch = self.epochs.ranges();
        self.aligned.resize(epoch.len(), (0, 0.0));
        align_to_reference(epoch, t_ref, est.anchors(), &tag, &velocity, &mut self.aligned);
        let (aligned, reports, applied) = (&self.aligned, &mut self.reports, &mut self.applied);
        apply_epoch(est, t_ref, aligned, epoch.iter().copied(), reports, applied, &mut self.tally)?;
        self.epochs.clear();
        Ok(())
    }

    /// Applies the open epoch (if any), then `ranges` (anchor, m) as one epoch measured at `t_s`
    /// (no alignment: they share their time), keeping one [`UpdateRecord`] per range for
    /// [`Pipeline::take_applied`]. An immediate epoch a caller has already gathered: it bypasses
    /// the epoch rule and the gate.
    pub fn epoch<E: Estimator>(&mut self, est: &mut E, t_s: f64, ranges: &[(usize, f64)]) -> Result<()> {
        self.flush(est)?;
        self.check_order("range", t_s)?;
        let measured = ranges.iter().map(|&(anchor, range_m)| RangeMeasurement { t_s, anchor, range_m, tag: 0 });
        apply_epoch(est, t_s, ranges, measured, &mut self.reports, &mut self.applied, &mut self.tally)
    }

    /// Moves the records of the ranges applied since the last call into `out`.
    pub fn take_applied(&mut self, out: &mut Vec<UpdateRecord>) {
        out.append(&mut self.applied);
    }

    /// The steps recorded since [`Pipeline::record_steps`] (empty when not recording).
    pub fn take_steps(&mut self) -> Vec<StepRecord> {
        self.steps.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// Moves the steps recorded since the last call into `out` (nothing when not recording), so a
    /// long run can write them out as it goes.
    pub fn move_steps(&mut self, out: &mut Vec<StepRecord>) {
        if let Some(steps) = self.steps.as_mut() {
            out.append(steps);
        }
    }

    /// What the loop counted so far.
    pub fn health(&self) -> Health {
        self.tally.health
    }

    /// Ranges of the open (not yet applied) epoch.
    pub fn pending(&self) -> &[RangeMeasurement] {
        self.epochs.ranges()
    }
}

/// Applies the epoch `ranges` (anchor, m) of one tag at `t_s` to `est` with `reports` as scratch,
/// and keeps one [`UpdateRecord`] per range in `applied`, with the range as `measured` (its tag
/// is the epoch's) and the epoch time the filter reached. A numerical failure skips the whole
/// epoch ([`Tally::guarded`]; its reports say skipped).
fn apply_epoch<E: Estimator>(
    est: &mut E,
    t_s: f64,
    ranges: &[(usize, f64)],
    mut measured: impl Iterator<Item = RangeMeasurement> + Clone,
    reports: &mut Vec<UpdateReport>,
    applied: &mut Vec<UpdateRecord>,
    tally: &mut Tally,
) -> Result<()> {
    reports.clear();
    reports.resize(ranges.len(), UpdateReport::skipped());
    let tag = measured.clone().next().map_or(0, |r| r.tag);
    if !tally.guarded(est, |est| est.update_tag_ranges(t_s, tag, ranges, reports))? {
        reports.iter_mut().for_each(|r| *r = UpdateReport::skipped());
    }
    let epoch_t_s = est.time_s().unwrap_or(t_s);
    applied.extend(measured.by_ref().zip(reports.iter()).map(|(r, report)| UpdateRecord {
        t_s: r.t_s,
        epoch_t_s,
        measured: Measured::Range { anchor: r.anchor, tag: r.tag, range_m: r.range_m },
        report: *report,
    }));
    Ok(())
}
