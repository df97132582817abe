//! Replay of a decoded recording through one method ([`crate::methods::run_method`]), with the
//! per-anchor update statistics and the comparison with ground truth that the `uwbimu-replay`
//! binary and `uwbimu_rs.replay` report ([`ReplaySummary`]); and the same replay streamed from
//! the file, in memory that does not grow with it ([`streamed`]).

pub mod streamed;

use std::collections::BTreeMap;

use serde::Serialize;
use uwbimu_estimation::pipeline::{Measured, Progress, UpdateRecord};

use uwbimu_io::IoResult as Result;
use uwbimu_io::Recording;
use uwbimu_vocabulary::config::{ConfigValue, FilterConfig, InitialState};
use uwbimu_vocabulary::error::Error as CoreError;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::PosePoint;
use uwbimu_vocabulary::sensors::{merge, observations, Observation, SensorKind};

use crate::methods::run_method;
use crate::metrics::{evaluate, Evaluation};
use crate::model_choice::ModelChoice;
use crate::registry::Method;
use crate::run::{BatchInput, BatchOutput};

/// What the filter did with one anchor's ranges (or with one sensor's readings).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct AnchorUpdateStats {
    /// Anchor id (the sensor's name for a sensor).
    pub id: String,
    /// Measurements applied at full weight.
    pub accepted: usize,
    /// Measurements applied with inflated noise (robust methods).
    pub down_weighted: usize,
    /// Measurements not applied (gated out or unusable).
    pub rejected: usize,
}

/// The result of [`replay`].
#[derive(Debug, Clone, PartialEq)]
pub struct Replay {
    /// The method that ran.
    pub method: Method,
    /// The method's output.
    pub output: BatchOutput,
    /// Ranges per anchor, in anchor-index order (inertial methods; empty for `uwb_ls`).
    pub anchors: Vec<AnchorUpdateStats>,
    /// Per sensor of the recording besides the ranges (TDoA, altitude, odometry), by name.
    pub sensors: BTreeMap<&'static str, AnchorUpdateStats>,
    /// Mean NIS of the applied ranges and sensor readings (None when there were none).
    pub mean_nis: Option<f64>,
}

impl Replay {
    /// The estimated trajectory (filtered or smoothed records; `uwb_ls` fixes).
    pub fn trajectory(&self) -> Vec<PosePoint> {
        match &self.output {
            BatchOutput::Inertial { trace, smoothed, .. } => smoothed
                .as_deref()
                .unwrap_or(&trace.steps)
                .iter()
                .map(|s| (s.t_s, s.state.position, Some(s.state.orientation)))
                .collect(),
            BatchOutput::Multilateration(fixes) => fixes.iter().map(|(t, f)| (*t, f.position, None)).collect(),
        }
    }

    /// Whether [`Replay::trajectory`] is RTS-smoothed.
    pub fn smoothed(&self) -> bool {
        matches!(self.output, BatchOutput::Inertial { smoothed: Some(_), .. })
    }

    /// The end figures of this replay of `rec`, with the errors against its ground truth when it
    /// has some.
    ///
    /// # Errors
    /// As [`compare_with_truth`].
    pub fn summary(&self, rec: &Recording) -> Result<ReplaySummary> {
        let rmse = if rec.ground_truth.is_empty() {
            None
        } else {
            let (raw, aligned) = compare_with_truth(&self.trajectory(), &rec.ground_truth)?;
            Some(TruthRmse {
                rmse_steps: raw.horizontal.n,
                rmse_horizontal_m: raw.horizontal.rmse,
                rmse_horizontal_aligned_m: aligned.horizontal.rmse,
                rmse_3d_m: raw.three_d.rmse,
                rmse_3d_aligned_m: aligned.three_d.rmse,
            })
        };
        Ok(ReplaySummary {
            method: self.method.name(),
            smoothed: self.smoothed(),
            duration_s: rec.stats.duration_s(),
            n_imu: rec.imu.len(),
            n_ranges: rec.ranges.len(),
            n_tdoa: rec.tdoa.len(),
            n_ground_truth: rec.ground_truth.len(),
            truncated_bytes: rec.stats.end.lost_bytes(),
            anchors: self.anchors.clone(),
            sensors: self.sensors.clone(),
            mean_nis: self.mean_nis,
            model: match &self.output {
                BatchOutput::Inertial { model: Some(m), .. } => Some(ModelSummary::of(m)),
                _ => None,
            },
            smoothing_left_out: match &self.output {
                BatchOutput::Inertial { trace, .. } => trace.health.smoothing_left_out,
                BatchOutput::Multilateration(_) => 0,
            },
            map_passes: match &self.output {
                BatchOutput::Inertial { trace, .. } => trace.health.map_passes,
                BatchOutput::Multilateration(_) => 0,
            },
            map_objective: match &self.output {
                BatchOutput::Inertial { trace, .. } => trace.health.map_objective.as_slice().to_vec(),
                BatchOutput::Multilateration(_) => Vec::new(),
            },
            smoothing_repairs: match &self.output {
                BatchOutput::Inertial { trace, .. } => trace.health.smoothing_repairs,
                BatchOutput::Multilateration(_) => 0,
            },
            rmse,
        })
    }
}

/// The end figures of a replay: what the CLI's `--json` prints and what `uwbimu_rs.replay`
/// returns in its info dict, under the same keys (the field names).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplaySummary {
    /// Method name.
    pub method: &'static str,
    /// Whether the trajectory is RTS-smoothed.
    pub smoothed: bool,
    /// Time between the first and the last message used, s.
    pub duration_s: f64,
    /// IMU samples read.
    pub n_imu: usize,
    /// Usable ranges read.
    pub n_ranges: usize,
    /// Usable TDoA read.
    pub n_tdoa: usize,
    /// Ground-truth samples read.
    pub n_ground_truth: usize,
    /// Bytes lost at the end of a recording that ends before its footer (0 for a complete file;
    /// [`uwbimu_io::recordings::mcap_read::McapEnd::lost_bytes`]).
    pub truncated_bytes: u64,
    /// Per anchor: what the filter did with its ranges.
    pub anchors: Vec<AnchorUpdateStats>,
    /// Per sensor of the recording besides the ranges (TDoA, altitude, odometry): what the filter
    /// did with its readings, by name (empty when there are none).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub sensors: BTreeMap<&'static str, AnchorUpdateStats>,
    /// Mean NIS of the applied ranges and sensor readings (None when there were none).
    pub mean_nis: Option<f64>,
    /// What the method chose on the log ([`crate::select`]; `best` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model: Option<ModelSummary>,
    /// Ranges the robust smoothing left out as far longer than the smoothed track predicts
    /// (`smoothing.outlier_passes`, [`crate::outlier_smoothing`]; 0 for a forward run). The
    /// per-anchor counts are those of the last pass, which did not see them.
    pub smoothing_left_out: usize,
    /// MAP passes the smoothing ran (`smoothing.map_passes`, [`crate::map_smoothing`]; 0 for a
    /// forward run).
    pub map_passes: u32,
    /// The MAP objective at the first smoothed pass and after each kept pass
    /// ([`uwbimu_estimation::pipeline::Health::map_objective`]; empty when the MAP did not run).
    pub map_objective: Vec<f64>,
    /// Predicted covariances the RTS smoother repaired ([`uwbimu_estimation::pipeline::Health::smoothing_repairs`]; 0 for a
    /// forward run).
    pub smoothing_repairs: usize,
    /// The errors against ground truth (only with ground truth; its keys sit at the top level).
    #[serde(flatten)]
    pub rmse: Option<TruthRmse>,
}

/// A model choice ([`crate::select::ModelChoice`]) as a replay reports it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelSummary {
    /// The chosen candidate's label (None when no selection ran).
    pub chosen: Option<String>,
    /// The scores behind the choice, or why no selection ran.
    pub reason: String,
    /// The settings it changed, as `key = value`.
    pub overrides: Vec<String>,
}

impl ModelSummary {
    pub(crate) fn of(choice: &ModelChoice) -> Self {
        let value = |v: &ConfigValue| match v {
            ConfigValue::Scalar(x) => x.to_string(),
            ConfigValue::Flag(b) => b.to_string(),
            ConfigValue::Vector(xs) => format!("{xs:?}"),
        };
        Self {
            chosen: choice.chosen().map(|c| c.label.clone()),
            reason: choice.reason.clone(),
            overrides: choice.overrides().iter().map(|(k, v)| format!("{k} = {}", value(v))).collect(),
        }
    }
}

/// Root-mean-square errors of a trajectory against ground truth ([`compare_with_truth`]), m.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TruthRmse {
    /// Estimates inside the truth time span (the number of errors).
    pub rmse_steps: usize,
    /// Horizontal (x-y) RMSE, m.
    pub rmse_horizontal_m: f64,
    /// Horizontal RMSE after the rigid alignment onto the truth, m.
    pub rmse_horizontal_aligned_m: f64,
    /// 3-D RMSE, m.
    pub rmse_3d_m: f64,
    /// 3-D RMSE after the rigid alignment onto the truth, m.
    pub rmse_3d_aligned_m: f64,
}

/// Runs `method` over the ranges and TDoA of `rec`, from `initial` (None: self-initialisation,
/// from the ranges or else the TDoA) and gathers per-anchor statistics. A recording with TDoA
/// needs a method that takes them ([`Method::takes_tdoa`]). `progress`, when given, counts the
/// IMU samples processed ([`Progress`]).
///
/// # Errors
/// As [`run_method`]; [`CoreError::InsufficientData`] if the recording has no IMU samples, no
/// ranges and no TDoA.
pub fn replay(
    rec: &Recording,
    method: Method,
    config: &FilterConfig,
    initial: Option<&InitialState>,
    smooth: bool,
    progress: Option<&Progress>,
) -> Result<Replay> {
    if rec.imu.is_empty() || (rec.ranges.is_empty() && rec.tdoa.is_empty()) {
        return Err(CoreError::InsufficientData(format!(
            "the recording has {} IMU samples, {} usable ranges and {} usable TDoA",
            rec.imu.len(),
            rec.ranges.len(),
            rec.tdoa.len()
        ))
        .into());
    }
    let observations = merge(&[&observations(&rec.tdoa), &rec.observations]);
    let input = BatchInput {
        imu: &rec.imu,
        ranges: &rec.ranges,
        anchors: &rec.anchors,
        initial,
        config,
        smooth,
        observations: &observations,
        progress,
        marginals_every_s: None,
    };
    let output = run_method(method, &input)?;
    let mut tally = UpdateTally::new(&rec.anchor_ids, observations.iter().map(Observation::kind));
    if let BatchOutput::Inertial { trace, .. } = &output {
        trace.updates.iter().for_each(|u| tally.add(u));
    }
    let (anchors, sensors, mean_nis) = tally.finish();
    Ok(Replay { method, output, anchors, sensors, mean_nis })
}

/// What the filter did with each anchor's ranges and with each sensor's readings, and the mean
/// NIS of what it applied, counted update by update.
#[derive(Debug, Clone)]
pub(crate) struct UpdateTally {
    anchors: Vec<AnchorUpdateStats>,
    sensors: BTreeMap<&'static str, AnchorUpdateStats>,
    nis_sum: f64,
    nis_n: usize,
}

/// The counts of a sensor, named.
fn sensor_counts(kind: SensorKind) -> AnchorUpdateStats {
    AnchorUpdateStats { id: kind.info().name.into(), ..AnchorUpdateStats::default() }
}

impl UpdateTally {
    /// Counts for the anchors `ids` (in anchor-index order) and for the sensors `kinds` (listed
    /// even when none of their readings reaches the filter).
    pub(crate) fn new(ids: &[String], kinds: impl IntoIterator<Item = SensorKind>) -> Self {
        Self {
            anchors: ids.iter().map(|id| AnchorUpdateStats { id: id.clone(), ..AnchorUpdateStats::default() }).collect(),
            sensors: kinds.into_iter().map(|k| (k.info().name, sensor_counts(k))).collect(),
            nis_sum: 0.0,
            nis_n: 0,
        }
    }

    /// Counts one applied (or refused) update.
    pub(crate) fn add(&mut self, u: &UpdateRecord) {
        let counts = match u.measured {
            Measured::Range { anchor, .. } => self.anchors.get_mut(anchor),
            Measured::Observation(o) => Some(self.sensors.entry(o.stream()).or_insert_with(|| sensor_counts(o.kind()))),
        };
        let Some(a) = counts else { return };
        match (u.report.accepted, u.report.down_weighted) {
            (true, false) => a.accepted += 1,
            (true, true) => a.down_weighted += 1,
            (false, _) => a.rejected += 1,
        }
        if u.report.accepted && u.report.nis.is_finite() {
            self.nis_sum += u.report.nis;
            self.nis_n += 1;
        }
    }

    /// Per anchor, per sensor, and the mean NIS (None when nothing was applied).
    pub(crate) fn finish(self) -> (Vec<AnchorUpdateStats>, BTreeMap<&'static str, AnchorUpdateStats>, Option<f64>) {
        (self.anchors, self.sensors, (self.nis_n > 0).then(|| self.nis_sum / self.nis_n as f64))
    }
}

/// Errors of a trajectory against ground truth: directly and after the least-squares rigid
/// (SE(3)) alignment of the estimate onto the truth ([`crate::metrics::rigid_alignment`]).
///
/// # Errors
/// As [`evaluate`] (e.g. no estimate inside the truth time span).
pub fn compare_with_truth(trajectory: &[PosePoint], truth: &[(f64, Vec3)]) -> Result<(Evaluation, Evaluation)> {
    let t: Vec<f64> = trajectory.iter().map(|p| p.0).collect();
    let p: Vec<Vec3> = trajectory.iter().map(|p| p.1).collect();
    let tt: Vec<f64> = truth.iter().map(|g| g.0).collect();
    let tp: Vec<Vec3> = truth.iter().map(|g| g.1).collect();
    Ok((evaluate(&t, &p, &tt, &tp, false)?, evaluate(&t, &p, &tt, &tp, true)?))
}
