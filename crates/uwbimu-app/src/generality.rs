//! The generality matrix: one method on one scenario of the zoo ([`crate::sim::zoo`]), compared
//! with UWB-only least squares (`uwb_ls`) on the same run — the check that a method holds up on
//! data it was not tuned on.
//!
//! **How a cell is measured.** The scenario is simulated with its seed; the method runs with the
//! initial state given (the truth at the first IMU sample, [`crate::sim::Scenario::true_initial`])
//! or self-initialised, with the scenario's matched configuration or the library defaults. Its
//! horizontal RMSE is taken over its per-IMU-sample body positions against the truth; `uwb_ls`'s
//! over its fixes against the true tag position. Both leave out
//! - the first [`SETTLE_S`] when self-initialised (the filter is still aligning), and
//! - the time inside range outages (gaps of more than [`OUTAGE_GAP_S`] without any range), where
//!   `uwb_ls` has no output; the error reached there is reported separately
//!   ([`CellResult::outage_max_error_m`]).
//!
//! With matched or default settings the model selection ([`crate::select`]) is off: the matrix
//! measures the compositions themselves (a selecting method would run each cell 8·F + 1 times);
//! the selection is checked on its own rigs (tests/integration/select.rs, docs/model-selection.md).

use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::RangeMeasurement;

use crate::methods::run_method;
use crate::registry::Method;
use crate::run::{BatchInput, BatchOutput, SETTLE_S};
use crate::sim::{simulate, zoo, Scenario, ZOO_NAMES};

/// A gap longer than this without any range is an outage, s.
pub const OUTAGE_GAP_S: f64 = 1.0;

/// How the filter starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// The true state at the first IMU sample.
    Given,
    /// Self-initialisation from the data ([`uwbimu_estimation::init`]).
    SelfInit,
}

impl Start {
    /// Parses `"given"` or `"self"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "given" => Ok(Self::Given),
            "self" => Ok(Self::SelfInit),
            _ => Err(Error::unknown_option("start", name, ["given", "self"])),
        }
    }
}

/// Which configuration the filter gets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Settings<'a> {
    /// The scenario's configuration matched to its sensors.
    Matched,
    /// The library defaults with the rig's geometry only: `FilterConfig::default()` plus the
    /// scenario's lever arm and declared IMU mounting (a user who gives nothing but what a tape
    /// measure tells).
    Defaults,
    /// A configuration of the caller's (e.g. to try settings on the zoo).
    Custom(&'a FilterConfig),
}

impl Settings<'_> {
    /// The configuration these settings give a rig whose configuration matched to its sensors
    /// is `matched`.
    pub fn config(&self, matched: &FilterConfig) -> FilterConfig {
        match self {
            Self::Matched => matched.clone(),
            Self::Defaults => FilterConfig { mounting: matched.mounting, ..FilterConfig::default() },
            Self::Custom(c) => (*c).clone(),
        }
    }
}

impl<'a> Settings<'a> {
    /// Parses `"matched"`, `"defaults"` or `"custom"` (which takes `custom`).
    pub fn parse(name: &str, custom: &'a FilterConfig) -> Result<Self> {
        match name {
            "matched" => Ok(Self::Matched),
            "defaults" => Ok(Self::Defaults),
            "custom" => Ok(Self::Custom(custom)),
            _ => Err(Error::unknown_option("settings", name, ["matched", "defaults", "custom"])),
        }
    }
}

/// One cell of the matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell<'a> {
    /// Zoo scenario name.
    pub scenario: &'a str,
    /// Simulator seed.
    pub seed: u64,
    /// The method.
    pub method: Method,
    /// Initial state given or self-initialised.
    pub start: Start,
    /// Matched configuration, defaults or the caller's.
    pub settings: Settings<'a>,
}

/// What one cell measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellResult {
    /// Horizontal RMSE of the method, m.
    pub rmse_m: f64,
    /// Horizontal RMSE of `uwb_ls` on the same run and times, m.
    pub uwb_ls_rmse_m: f64,
    /// Whether every output of the method is finite.
    pub finite: bool,
    /// Largest horizontal error of the method inside range outages, m (None without outages).
    pub outage_max_error_m: Option<f64>,
}

impl CellResult {
    /// `rmse_m / uwb_ls_rmse_m`.
    pub fn ratio(&self) -> f64 {
        self.rmse_m / self.uwb_ls_rmse_m
    }
}

/// Every cell of the matrix over `scenarios` × `seeds` × `methods` (in that nesting order) with
/// one `start` and `settings`. Fails on an unknown scenario and on `uwb_ls`, the baseline every
/// cell is compared with.
pub fn cells<'a, S: AsRef<str>>(
    methods: &[Method],
    scenarios: &'a [S],
    seeds: &[u64],
    start: Start,
    settings: Settings<'a>,
) -> Result<Vec<Cell<'a>>> {
    if let Some(bad) = methods.iter().find(|m| **m == Method::UwbLs) {
        return Err(Error::InvalidCall(format!("{} is the baseline of the matrix, not a cell", bad.name())));
    }
    let mut out = Vec::with_capacity(scenarios.len() * seeds.len() * methods.len());
    for scenario in scenarios.iter().map(AsRef::as_ref) {
        if !ZOO_NAMES.contains(&scenario) {
            return Err(Error::unknown_option("zoo scenario", scenario, ZOO_NAMES.iter().copied()));
        }
        for &seed in seeds {
            out.extend(methods.iter().map(|&method| Cell { scenario, seed, method, start, settings }));
        }
    }
    Ok(out)
}

/// Runs every cell ([`run_cell`]), on all cores with the `parallel` feature, else one after the
/// other; one result per cell, in order.
pub fn run_cells(cells: &[Cell<'_>]) -> Vec<Result<CellResult>> {
    crate::parallel::map_all(cells, run_cell)
}

/// The `[start, end)` range outages of a time-ordered range stream within `[t0, t1]`.
fn outages(ranges: &[RangeMeasurement], t0: f64, t1: f64) -> Vec<(f64, f64)> {
    let times = std::iter::once(t0).chain(ranges.iter().map(|r| r.t_s)).chain(std::iter::once(t1));
    let times: Vec<f64> = times.collect();
    times.windows(2).filter(|w| w[1] - w[0] > OUTAGE_GAP_S).map(|w| (w[0], w[1])).collect()
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// Runs one cell (see the module doc).
///
/// # Errors
/// An unknown scenario; a method error (reported as is: the matrix treats it as a failure).
pub fn run_cell(cell: &Cell<'_>) -> Result<CellResult> {
    let scenario: Scenario = zoo(cell.scenario, cell.seed)?;
    let data = simulate(&scenario.sim)?;
    let mut config = cell.settings.config(&scenario.config);
    if !matches!(cell.settings, Settings::Custom(_)) {
        config.model_selection.enabled = false;
    }
    let initial = scenario.true_initial(&data)?;
    let input = BatchInput {
        imu: &data.imu,
        ranges: &data.ranges,
        anchors: &data.anchors,
        initial: (cell.start == Start::Given).then_some(&initial),
        config: &config,
        smooth: cell.method.smooths_by_default(),
        observations: &[],
        progress: None,
        marginals_every_s: None,
    };
    let (t0, t1) = match (data.imu.first(), data.imu.last()) {
        (Some(a), Some(b)) => (a.t_s, b.t_s),
        _ => return Err(Error::InsufficientData("the scenario has no IMU samples".into())),
    };
    let from = if cell.start == Start::SelfInit { t0 + SETTLE_S } else { t0 };
    let gaps = outages(&data.ranges, t0, t1);
    let in_gap = |t: f64| gaps.iter().any(|&(a, b)| a < t && t < b);
    let counted = |t: f64| t >= from && !in_gap(t);

    let BatchOutput::Multilateration(fixes) = run_method(Method::UwbLs, &BatchInput { smooth: false, ..input })? else {
        return Err(Error::InvalidCall("uwb_ls returned no fixes".into()));
    };
    let lever = scenario.sim.lever_arm_m;
    let tag_truth = |t: f64| -> Vec3 {
        let k = scenario.sim.trajectory.sample(t);
        k.position + k.orientation * lever
    };
    let ls_errors: Vec<f64> =
        fixes.iter().filter(|(t, _)| counted(*t)).map(|(t, f)| (f.position - tag_truth(*t)).xy().norm()).collect();

    let BatchOutput::Inertial { trace, smoothed, .. } = run_method(cell.method, &input)? else {
        return Err(Error::InvalidCall(format!("{} is not a filter", cell.method.name())));
    };
    // `best` is scored on its smoothed track, what it returns by default.
    let steps = smoothed.as_deref().unwrap_or(&trace.steps);
    let mut finite = true;
    let mut errors = Vec::with_capacity(steps.len());
    let mut outage_max: Option<f64> = None;
    for (step, truth) in steps.iter().zip(&data.truth) {
        let e = (step.state.position - truth.position).xy().norm();
        finite &= e.is_finite() && step.position_cov.iter().all(|v| v.is_finite());
        let e = if e.is_finite() { e } else { f64::INFINITY };
        if in_gap(step.t_s) {
            outage_max = Some(outage_max.map_or(e, |m: f64| m.max(e)));
        } else if step.t_s >= from {
            errors.push(e);
        }
    }
    Ok(CellResult { rmse_m: rms(&errors), uwb_ls_rmse_m: rms(&ls_errors), finite, outage_max_error_m: outage_max })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outages_are_gaps_longer_than_the_threshold() {
        let r = |t_s| RangeMeasurement { t_s, anchor: 0, range_m: 1.0, tag: 0 };
        let ranges = [r(0.5), r(0.9), r(5.0), r(5.5)];
        assert_eq!(outages(&ranges, 0.0, 6.0), vec![(0.9, 5.0)]);
        assert_eq!(outages(&ranges, 0.0, 8.0), vec![(0.9, 5.0), (5.5, 8.0)]);
        assert!(outages(&[], 0.0, 0.5).is_empty());
    }
}
