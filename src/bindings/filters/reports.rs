//! What runs and streams report: the `UpdateReport` class, the health dict and the
//! self-initialisation's info items.

use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_estimation::init::SelfInit;
use uwbimu_estimation::pipeline::{Estimator, Health, Stream, UpdateRecord};

use super::super::errors::PyResult;
use super::super::repr;

/// One report of an update (a range or an observation).
#[pyclass(name = "UpdateReport", module = "uwbimu_rs._native", frozen, get_all)]
pub struct PyUpdateReport {
    /// Measurement time, s.
    t: f64,
    /// Time at which its epoch was applied, s.
    epoch_t: f64,
    /// The sensor: `range` or a name of `SENSORS`.
    sensor: &'static str,
    /// Anchor index (a TDoA's anchor i); None for a sensor without anchors.
    anchor: Option<usize>,
    /// A TDoA's anchor j; None for the others.
    anchor_j: Option<usize>,
    /// A range's tag; None for the other sensors.
    tag: Option<usize>,
    /// An odometry reading's body axis; None for the others.
    axis: Option<usize>,
    /// The value as measured: the range, d_ij, altitude (m) or speed (m/s).
    value: f64,
    /// Innovation z − h(x_op), m.
    innovation: f64,
    /// γ, squared Mahalanobis distance of the innovation.
    nis: f64,
    /// Whether the range changed the state.
    accepted: bool,
    /// Weight relative to the nominal range noise, R / R_used (1 = full).
    weight: f64,
    /// R_used / R (Li & Wang 2020 eq. (40)).
    inflation: f64,
    /// Whether the noise policy down-weighted the range.
    down_weighted: bool,
    /// Iterations of the update.
    iterations: u32,
    /// Factor by which the epoch's prior covariance was inflated (the ARCKF paper's eq. (42)); 1 if not.
    prior_fading: f64,
    /// Whether the epoch was applied as its UWB-only fix (re-acquisition,
    /// `uwbimu_estimation::filters::reacquire`).
    reacquired: bool,
    /// The anchor's estimated range bias after the update, m (NaN without `range_bias.states`).
    bias: f64,
    /// Its standard deviation, m (NaN without `range_bias.states`).
    bias_std: f64,
}

impl From<UpdateRecord> for PyUpdateReport {
    fn from(u: UpdateRecord) -> Self {
        let r = u.report;
        Self {
            t: u.t_s,
            epoch_t: u.epoch_t_s,
            sensor: u.measured.sensor(),
            anchor: u.measured.anchors()[0],
            anchor_j: u.measured.anchors()[1],
            tag: u.measured.tag(),
            axis: u.measured.axis(),
            value: u.measured.value(),
            innovation: r.innovation,
            nis: r.nis,
            accepted: r.accepted,
            weight: r.weight,
            inflation: r.inflation,
            down_weighted: r.down_weighted,
            iterations: r.iterations,
            prior_fading: r.prior_fading,
            reacquired: r.reacquired,
            bias: r.bias.map_or(f64::NAN, |b| b.0),
            bias_std: r.bias.map_or(f64::NAN, |b| b.1),
        }
    }
}

#[pymethods]
impl PyUpdateReport {
    /// The report as `UpdateReport(t=1.25, anchor=2, range=4.013, nis=0.82, accepted=True, ...)`
    /// (`anchor_j` only for a TDoA, the bias only with bias states).
    fn __repr__(&self) -> String {
        let f = repr::float;
        let mut items =
            vec![format!("t={}", f(self.t)), format!("epoch_t={}", f(self.epoch_t)), format!("sensor='{}'", self.sensor)];
        let indices = [("anchor", self.anchor), ("anchor_j", self.anchor_j), ("axis", self.axis)];
        items.extend(indices.iter().filter_map(|(name, i)| i.map(|i| format!("{name}={i}"))));
        items.extend([
            format!("value={}", f(self.value)),
            format!("innovation={}", f(self.innovation)),
            format!("nis={}", f(self.nis)),
            format!("accepted={}", repr::boolean(self.accepted)),
            format!("weight={}", f(self.weight)),
            format!("inflation={}", f(self.inflation)),
            format!("down_weighted={}", repr::boolean(self.down_weighted)),
            format!("iterations={}", self.iterations),
            format!("prior_fading={}", f(self.prior_fading)),
            format!("reacquired={}", repr::boolean(self.reacquired)),
        ]);
        if !self.bias.is_nan() {
            items.push(format!("bias={}, bias_std={}", f(self.bias), f(self.bias_std)));
        }
        format!("UpdateReport({})", items.join(", "))
    }
}

/// The reports of the updates a streaming call applied.
pub(super) fn applied_reports<E: Estimator>(stream: &mut Stream<E>) -> Vec<PyUpdateReport> {
    let mut out = Vec::new();
    stream.take_applied(&mut out);
    out.into_iter().map(PyUpdateReport::from).collect()
}

/// Sets `still_start` and `heading_from` ("motion" or "fallback") of a self-initialisation in `d`.
pub(super) fn init_info_items(d: &Bound<'_, PyDict>, s: &SelfInit) -> PyResult<()> {
    d.set_item("still_start", s.still)?;
    d.set_item("heading_from", s.heading.name())?;
    Ok(())
}

/// What a run or stream counted, as a dict: `rejected` ({gate kind: count}), `numerical_repairs`,
/// `ranges_before_start`, `reordered`, `late_dropped`, `smoothing_left_out` (a smoothed batch
/// run's robust smoothing; 0 for a stream), `map_passes` (its MAP passes kept; 0 for a stream),
/// `map_objective` (the MAP objective at its first smoothed pass and after each kept pass, a list;
/// empty when the MAP did not run),
/// `smoothing_repairs` (predicted covariances its RTS smoother repaired) and `smoothing_failed`
/// (its smoother failed numerically and the forward estimate stands in).
pub(crate) fn health_dict<'py>(py: Python<'py>, h: &Health) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let rejected = PyDict::new(py);
    for (kind, n) in h.rejected.by_kind() {
        rejected.set_item(kind.name(), n)?;
    }
    d.set_item("rejected", rejected)?;
    d.set_item("numerical_repairs", h.numerical_repairs)?;
    d.set_item("ranges_before_start", h.ranges_before_start)?;
    d.set_item("reordered", h.reordered)?;
    d.set_item("late_dropped", h.late_dropped)?;
    d.set_item("smoothing_left_out", h.smoothing_left_out)?;
    d.set_item("map_passes", h.map_passes)?;
    d.set_item("map_objective", h.map_objective.as_slice().to_vec())?;
    d.set_item("smoothing_repairs", h.smoothing_repairs)?;
    d.set_item("smoothing_failed", h.smoothing_failed)?;
    Ok(d)
}
