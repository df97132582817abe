//! The named methods of the batch API and the function that runs one of them over whole arrays.

use crate::config::{FilterConfig, InitialState};
use crate::error::{Error, Result};
use crate::filters::{Ackf, Arckf, Best, Ckf, Criekf, Ekf, Eskf, Iekf, InertialFilter, Rekf, Riekf, Shaf, Shfaf, Ukf};
use crate::init::{initialize_with_tdoa, SelfInit};
use crate::math::Vec3;
use crate::multilateration::{uwb_ls, Fix, LsConfig};
use crate::pipeline::{run, run_streams, smoothed_steps, StepRecord, Streams, Trace};
use crate::planar::{PlanarFilter, PlanarKind};
use crate::records::{ImuSample, MagSample, RangeMeasurement, TdoaMeasurement};

/// A method name accepted by the batch API.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// UWB-only least squares per epoch (seed 004 eqs. (8)–(13), then Gauss–Newton).
    UwbLs,
    /// The tightly coupled EKF of seed 000.
    Ekf,
    /// The iterated EKF (seed 000 Algorithm 1 without re-weighting).
    Iekf,
    /// The robust EKF of seed 000 (χ² inflation against the prior).
    Rekf,
    /// The robust iterated EKF of seed 000 (Algorithm 1).
    Riekf,
    /// RIEKF with zero-velocity, pseudo-velocity and plane constraints (seed 000 CRIEKF).
    Criekf,
    /// The complementary Kalman filter of seed 002.
    Ckf,
    /// The adaptive-robust complementary Kalman filter of seed 002 (ARCKF).
    Arckf,
    /// The adaptive complementary Kalman filter of seed 003 (gravity and geomagnetic aiding).
    Ackf,
    /// The loosely coupled error-state filter of seed 004.
    Eskf,
    /// The Sage–Husa adaptive ESKF of seed 004.
    Shaf,
    /// The Sage–Husa fuzzy adaptive ESKF of seed 004.
    Shfaf,
    /// The 15-state error-state UKF (seed 001 eqs. (11)–(14) on the INS error state).
    Ukf,
    /// The planar 4-state EKF of seed 001 (eqs. (5)–(10)).
    Ekf2d,
    /// The planar 4-state UKF of seed 001 (eqs. (11)–(14)).
    Ukf2d,
    /// The planar errors-complementary EKF of seed 001 with moving-average ranges (eqs. (15)–(18)).
    Cekf2d,
    /// The recommended method for real logs: the composition that measured best across the
    /// scenario zoo and isas-walk1 (README "`best` and the isas-walk1 table"), the filter
    /// [`crate::filters::Best`] (χ² inflation skewed against long ranges with the iterated
    /// update, the zero-velocity constraint while still), re-acquisition on divergence, self-initialisation when no initial
    /// state is given, and RTS smoothing unless a forward pass is asked for
    /// ([`Method::smooths_by_default`]). Range bias states, adaptive range noise and the
    /// pseudo-velocity and plane constraints were measured as candidates and left out (each cost
    /// more on most scenarios than it won on one).
    Best,
}

impl Method {
    /// Every method name, in the order listed by `uwbimu_rs.FILTERS`.
    pub const NAMES: [&'static str; 17] = [
        "uwb_ls", "ekf", "iekf", "rekf", "riekf", "criekf", "ckf", "arckf", "ackf", "eskf", "shaf", "shfaf", "ukf", "ekf2d",
        "ukf2d", "cekf2d", "best",
    ];

    /// The method's name (the variants are declared in the order of [`Method::NAMES`]).
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    /// Whether the method's run can be RTS-smoothed: the inertial 15-state filters (not
    /// `uwb_ls` and the planar filters).
    pub fn smoothable(self) -> bool {
        !matches!(self, Self::UwbLs | Self::Ekf2d | Self::Ukf2d | Self::Cekf2d)
    }

    /// Whether the batch API smooths the method's run when the caller does not say (`best`).
    pub fn smooths_by_default(self) -> bool {
        self == Self::Best
    }

    /// Whether to smooth: as `asked`, else the method's default ([`Method::smooths_by_default`]).
    pub fn smooth(self, asked: Option<bool>) -> bool {
        asked.unwrap_or(self.smooths_by_default())
    }

    /// The names of the methods for which `keep` holds, comma-separated (for error messages).
    pub fn names_where(keep: fn(Self) -> bool) -> String {
        Self::NAMES.iter().filter(|n| Self::parse(n).is_ok_and(keep)).copied().collect::<Vec<_>>().join(", ")
    }

    /// Whether the method takes TDoA: the tightly coupled inertial filters and `best` (the loosely coupled
    /// ones fuse a per-epoch fix from ranges, the planar ones and `uwb_ls` take ranges only).
    pub fn takes_tdoa(self) -> bool {
        !matches!(self, Self::UwbLs | Self::Eskf | Self::Shaf | Self::Shfaf | Self::Ekf2d | Self::Ukf2d | Self::Cekf2d)
    }

    /// Parses a method name; the error lists the allowed names.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "uwb_ls" => Ok(Self::UwbLs),
            "ekf" => Ok(Self::Ekf),
            "iekf" => Ok(Self::Iekf),
            "rekf" => Ok(Self::Rekf),
            "riekf" => Ok(Self::Riekf),
            "criekf" => Ok(Self::Criekf),
            "ckf" => Ok(Self::Ckf),
            "arckf" => Ok(Self::Arckf),
            "ackf" => Ok(Self::Ackf),
            "eskf" => Ok(Self::Eskf),
            "shaf" => Ok(Self::Shaf),
            "shfaf" => Ok(Self::Shfaf),
            "ukf" => Ok(Self::Ukf),
            "ekf2d" => Ok(Self::Ekf2d),
            "ukf2d" => Ok(Self::Ukf2d),
            "cekf2d" => Ok(Self::Cekf2d),
            "best" => Ok(Self::Best),
            _ => Err(Error::UnknownOption { kind: "method", got: name.to_string(), allowed: Self::NAMES.join(", ") }),
        }
    }
}

/// The method replays use when none is given.
pub const DEFAULT_METHOD: Method = Method::Best;

/// What a batch run produced.
#[derive(Debug, Clone, PartialEq)]
pub enum BatchOutput {
    /// An inertial filter's trace, with the self-initialisation used (None if the caller gave
    /// the initial state).
    Inertial {
        /// Per-IMU-sample records and per-range reports.
        trace: Trace,
        /// Self-initialisation result, when the filter initialised itself.
        init: Option<Box<SelfInit>>,
        /// RTS-smoothed records, one per IMU sample, when smoothing was asked for.
        smoothed: Option<Vec<StepRecord>>,
    },
    /// One UWB-only fix per solvable epoch: (epoch time s, fix).
    Multilateration(Vec<(f64, Fix)>),
}

/// What a batch run is given besides the method.
#[derive(Debug, Clone, Copy)]
pub struct BatchInput<'a> {
    /// IMU samples, validated and time-ordered.
    pub imu: &'a [ImuSample],
    /// Ranges, validated and time-ordered.
    pub ranges: &'a [RangeMeasurement],
    /// Anchor positions, m.
    pub anchors: &'a [Vec3],
    /// Initial state (None: self-initialisation, [`crate::init`]).
    pub initial: Option<&'a InitialState>,
    /// Filter settings.
    pub config: &'a FilterConfig,
    /// Also RTS-smooth the run (inertial filters only).
    pub smooth: bool,
    /// Magnetometer samples, validated and time-ordered (used by `ackf`; empty if none).
    pub mag: &'a [MagSample],
    /// TDoA, validated and time-ordered (tightly coupled inertial methods; empty if none).
    pub tdoa: &'a [TdoaMeasurement],
}

/// Runs `method` over one recording. A non-empty `config.range_calibration` (seed 001 §2.2) and a
/// non-zero `ranging.time_offset_s` are applied to the measurements first, for every method.
pub fn run_method(method: Method, input: &BatchInput<'_>) -> Result<BatchOutput> {
    if !input.mag.is_empty() && method != Method::Ackf {
        return Err(Error::InvalidCall("magnetometer data given, but only ackf uses a magnetometer".into()));
    }
    if !input.tdoa.is_empty() && !method.takes_tdoa() {
        return Err(Error::InvalidCall(format!(
            "TDoA given, but {} does not take TDoA (the tightly coupled inertial methods do: {})",
            method.name(),
            Method::names_where(Method::takes_tdoa)
        )));
    }
    let offset = input.config.ranging.time_offset_s;
    if offset != 0.0 {
        let span = |t: f64| input.imu.first().is_some_and(|a| t >= a.t_s) && input.imu.last().is_some_and(|b| t <= b.t_s);
        let shift = |t: f64| Some(t + offset).filter(|&t| span(t));
        let ranges: Vec<_> = input.ranges.iter().filter_map(|r| shift(r.t_s).map(|t_s| RangeMeasurement { t_s, ..*r })).collect();
        let tdoa: Vec<_> = input.tdoa.iter().filter_map(|m| shift(m.t_s).map(|t_s| TdoaMeasurement { t_s, ..*m })).collect();
        let mut config = input.config.clone();
        config.ranging.time_offset_s = 0.0;
        return run_method(method, &BatchInput { ranges: &ranges, tdoa: &tdoa, config: &config, ..*input });
    }
    if !input.config.range_calibration.is_empty() {
        let calibrated = input.config.range_calibration.apply(input.ranges, input.anchors.len())?;
        return run_calibrated(method, &BatchInput { ranges: &calibrated, ..*input });
    }
    run_calibrated(method, input)
}

fn run_calibrated(method: Method, input: &BatchInput<'_>) -> Result<BatchOutput> {
    let BatchInput { ranges, anchors, config, .. } = *input;
    match method {
        _ if input.smooth && !method.smoothable() => Err(Error::UnknownOption {
            kind: "smoothing method",
            got: method.name().into(),
            allowed: Method::names_where(Method::smoothable),
        }),
        Method::UwbLs => {
            let ls = LsConfig::from_filter_config(config);
            Ok(BatchOutput::Multilateration(uwb_ls(ranges, anchors, &ls)))
        }
        Method::Ekf => run_inertial(|i| Ekf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Iekf => run_inertial(|i| Iekf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Rekf => run_inertial(|i| Rekf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Riekf => run_inertial(|i| Riekf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Best => run_inertial(|i| Best::new(anchors.to_vec(), i, config.clone()), input),
        Method::Criekf => run_inertial(|i| Criekf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Ckf => run_inertial(|i| Ckf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Arckf => run_inertial(|i| Arckf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Ackf => run_inertial(|i| Ackf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Eskf => run_inertial(|i| Eskf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Shaf => run_inertial(|i| Shaf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Shfaf => run_inertial(|i| Shfaf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Ukf => run_inertial(|i| Ukf::new(anchors.to_vec(), i, config.clone()), input),
        Method::Ekf2d => run_planar(PlanarKind::Ekf, input),
        Method::Ukf2d => run_planar(PlanarKind::Ukf, input),
        Method::Cekf2d => run_planar(PlanarKind::Cekf, input),
    }
}

/// Runs `method` over many recordings, in parallel on all cores with the `parallel` feature
/// (rayon), else one after the other; one result per input, in order.
pub fn run_many(method: Method, inputs: &[BatchInput<'_>]) -> Vec<Result<BatchOutput>> {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        inputs.par_iter().map(|input| run_method(method, input)).collect()
    }
    #[cfg(not(feature = "parallel"))]
    {
        inputs.iter().map(|input| run_method(method, input)).collect()
    }
}

/// The given initial state, or the self-initialisation's.
fn initial_state(input: &BatchInput<'_>) -> Result<(InitialState, Option<Box<SelfInit>>)> {
    let BatchInput { imu, ranges, anchors, initial, config, tdoa, .. } = *input;
    Ok(match initial {
        Some(i) => (i.clone(), None),
        None => {
            let s = initialize_with_tdoa(imu, ranges, tdoa, anchors, config)?;
            (s.initial.clone(), Some(Box::new(s)))
        }
    })
}

/// Runs a planar filter of seed 001 (initialised like the inertial filters: x, y, velocity, yaw
/// and gyro bias from the initial state).
fn run_planar(kind: PlanarKind, input: &BatchInput<'_>) -> Result<BatchOutput> {
    let (initial, init) = initial_state(input)?;
    let mut filter = PlanarFilter::new(kind, input.anchors.to_vec(), &initial, input.config)?;
    Ok(BatchOutput::Inertial { trace: run(&mut filter, input.imu, input.ranges)?, init, smoothed: None })
}

/// Initialises (unless `initial` is given), builds the filter with `build` and runs the pipeline.
fn run_inertial<F: InertialFilter>(
    build: impl FnOnce(&InitialState) -> Result<F>,
    input: &BatchInput<'_>,
) -> Result<BatchOutput> {
    let BatchInput { imu, ranges, smooth, mag, tdoa, .. } = *input;
    let (initial, init) = initial_state(input)?;
    let mut filter = build(&initial)?;
    if smooth {
        filter.core_mut().start_recording(imu.len() + ranges.len() + mag.len() + tdoa.len());
    }
    let trace = run_streams(&mut filter, &Streams { imu, ranges, mag, tdoa })?;
    let smoothed = if smooth { Some(smoothed_steps(&trace, filter.core())?) } else { None };
    Ok(BatchOutput::Inertial { trace, init, smoothed })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for name in Method::NAMES {
            assert_eq!(Method::parse(name).map(Method::name), Ok(name));
        }
    }
}
