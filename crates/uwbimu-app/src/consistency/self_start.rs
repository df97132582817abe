//! Consistency from a self-initialised start: no initial state is given, the filter finds its
//! heading with the heading bank ([`uwbimu_estimation::init`]) and must say how sure it is from
//! the first pose it publishes. The oracle is the simulator's truth: the heading error against
//! the heading σ the filter reports (the attitude covariance about the navigation z axis) at
//! the moment the self-initialisation decided, and the attitude NEES from then on against its
//! χ² interval ([`NeesSeries`]).
//!
//! **The scenarios** ([`SELF_START_SCENARIOS`], [`self_start_scenario`]): the `hall_vehicle`
//! figure-8 of the other consistency scenarios (four anchors at 0.8–2.2 m, IMU at 100 Hz, UWB
//! σ 0.1 m) unless said otherwise; logs of [`LOG_S`].
//!
//! | scenario | start | what it tests |
//! |---|---|---|
//! | `self_still` | 2 s still, then the figure-8; UWB 10 Hz | a start at rest |
//! | `self_moving` | at 0.98 m/s on the straight crossing; UWB 5 Hz from 0.5 s | a vehicle already driving |
//! | `self_turning` | at speed in the middle of a turn; UWB 5 Hz from 0.5 s | a vehicle already turning |
//! | `self_tags_short` | still; two tags 0.2 m apart across the body | a short baseline |
//! | `self_tags_long` | moving; two tags 1 m apart along the body | a long baseline at speed |
//! | `self_imu_20hz` | still; IMU at 20 Hz | a slow IMU |
//! | `self_imu_1000hz` | still; IMU at 1 kHz | a fast IMU |
//! | `self_z_down` | still; IMU mounted upside down (told) | a z-down mounting |

use uwbimu_estimation::init::heading_bank::{angle_difference, nav_yaw_variance, yaw_of};
use uwbimu_estimation::pipeline::Marginals;
use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{Quat, Vec3};
use uwbimu_vocabulary::state::{ErrCov, ATT};

use super::{known_scenario, nees, scenario, settings_config, NeesSeries, LOG_S};
use crate::generality::Settings;
use crate::methods::run_method;
use crate::registry::{Input, Method};
use crate::run::{BatchInput, BatchOutput};
use crate::sim::{simulate, SimConfig, SimData};

/// The self-initialised scenarios, in the order of the module table.
pub const SELF_START_SCENARIOS: &[&str] = &[
    "self_still",
    "self_moving",
    "self_turning",
    "self_tags_short",
    "self_tags_long",
    "self_imu_20hz",
    "self_imu_1000hz",
    "self_z_down",
];

/// Seconds after the start over which the attitude NEES is sampled (one sample a second).
pub const AFTER_START_S: usize = 20;

/// Time into the `hall_vehicle` figure-8 (2 s still, 37 s laps) at which `self_turning` starts:
/// a quarter lap past the straight crossing, in the turn.
const TURNING_START_S: f64 = 20.5 + 37.0 / 4.0;

/// The scenario `name` of [`SELF_START_SCENARIOS`] with every random draw seeded by `seed`
/// (module table). Unknown name → [`Error::UnknownOption`] listing them.
pub fn self_start_scenario(name: &str, seed: u64) -> Result<SimConfig> {
    let still = || scenario("still_start", seed);
    let moving = || scenario("moving_start", seed);
    let with_tag = |base: SimConfig, offset: Vec3| SimConfig { more_tags_m: vec![base.lever_arm_m + offset], ..base };
    Ok(match name {
        "self_still" => still()?,
        "self_moving" => moving()?,
        "self_turning" => {
            let base = moving()?;
            let mut uwb = base.uwb.clone();
            for outage in &mut uwb.outages {
                outage.start_s += TURNING_START_S - base.start_s;
                outage.end_s += TURNING_START_S - base.start_s;
            }
            SimConfig { start_s: TURNING_START_S, uwb, ..base }
        }
        "self_tags_short" => with_tag(still()?, Vec3::new(0.0, 0.2, 0.0)),
        "self_tags_long" => with_tag(moving()?, Vec3::new(1.0, 0.0, 0.0)),
        "self_imu_20hz" => SimConfig { imu_rate_hz: 20.0, ..still()? },
        "self_imu_1000hz" => SimConfig { imu_rate_hz: 1000.0, ..still()? },
        "self_z_down" => SimConfig { imu_rotation: Quat::from_axis_angle(&Vec3::x_axis(), std::f64::consts::PI), ..still()? },
        _ => return Err(Error::unknown_option("self-initialised scenario", name, SELF_START_SCENARIOS.iter().copied())),
    })
}

/// The inputs of a self-initialised scenario besides the IMU and one tag's ranges.
pub fn self_start_inputs(name: &str) -> &'static [Input] {
    match name {
        "self_tags_short" | "self_tags_long" => &[Input::Tags],
        _ => &[],
    }
}

/// One run's start: when the self-initialisation decided (s after the first IMU sample), the
/// heading error then (rad, navigation z) and the heading σ the filter reported (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartSample {
    /// The decision's time since the first IMU sample, s.
    pub decided_s: f64,
    /// The heading error at the first sample at or after it, rad.
    pub heading_error_rad: f64,
    /// The heading σ the filter reported there, rad.
    pub heading_std_rad: f64,
}

impl StartSample {
    /// Whether the error is within three reported standard deviations.
    pub fn within_3_sigma(&self) -> bool {
        self.heading_error_rad.abs() <= 3.0 * self.heading_std_rad
    }
}

/// What one method did over the runs of one self-initialised scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct SelfStart {
    /// The method.
    pub method: Method,
    /// The scenario (one of [`SELF_START_SCENARIOS`]).
    pub scenario: &'static str,
    /// Each run's start.
    pub starts: Vec<StartSample>,
    /// The attitude NEES averaged over the runs at each second after the start (its `times_s`
    /// are seconds since the start).
    pub attitude: NeesSeries,
    /// The heading error 5 s after the start, rad, per run.
    pub heading_error_5s_rad: Vec<f64>,
}

/// Runs each of `methods` self-initialised on scenario `name` once per seed of `seeds` with the
/// configuration `settings` give it ([`settings_config`]), the seeds in parallel.
pub fn self_start_monte_carlo(methods: &[Method], name: &str, seeds: &[u64], settings: Settings<'_>) -> Result<Vec<SelfStart>> {
    let scenario_name = known_scenario(SELF_START_SCENARIOS, "self-initialised scenario", name)?;
    let per_seed = crate::parallel::map_all(seeds, |&seed| {
        let sim = self_start_scenario(name, seed)?;
        let data = simulate(&sim)?;
        let config = settings_config(&sim, settings);
        methods.iter().map(|&method| run_once(method, &sim, &data, &config)).collect::<Result<Vec<_>>>()
    });
    methods
        .iter()
        .zip(super::by_method(methods.len(), per_seed)?)
        .map(|(&method, runs)| {
            let k = runs.iter().map(|r| r.attitude_nees.len()).min().unwrap_or(0);
            if k == 0 {
                return Err(Error::InvalidCall(format!("{} on {scenario_name}: no run sampled after its start", method.name())));
            }
            let mean = (0..k).map(|i| runs.iter().map(|r| r.attitude_nees[i]).sum::<f64>() / runs.len() as f64).collect();
            Ok(SelfStart {
                method,
                scenario: scenario_name,
                starts: runs.iter().map(|r| r.start).collect(),
                attitude: NeesSeries { dof: 3, runs: runs.len(), times_s: (0..k).map(|i| i as f64).collect(), mean },
                heading_error_5s_rad: runs.iter().map(|r| r.heading_error_5s_rad).collect(),
            })
        })
        .collect()
}

/// One run's samples from its start.
struct Run {
    start: StartSample,
    attitude_nees: Vec<f64>,
    heading_error_5s_rad: f64,
}

/// The heading error of the sampled estimate `m` against the true orientation `truth` (body to
/// navigation): the difference of their yaws about the navigation z axis, wrapped to (−π, π],
/// and the heading σ the estimate reports (its attitude covariance about that axis; 0 without
/// one), rad.
pub fn heading_error_and_std(m: &Marginals, truth: &Quat) -> (f64, f64) {
    let mut p = ErrCov::zeros();
    p.fixed_view_mut::<3, 3>(ATT, ATT).copy_from(&m.attitude_cov.unwrap_or_default());
    (angle_difference(yaw_of(&m.state.orientation), yaw_of(truth)), nav_yaw_variance(&m.state.orientation, &p).sqrt())
}

/// One self-initialised run of `method` (forward, the first [`LOG_S`] of the log).
fn run_once(method: Method, sim: &SimConfig, data: &SimData, config: &FilterConfig) -> Result<Run> {
    let t0 = data.imu.first().map(|s| s.t_s).ok_or_else(|| Error::InsufficientData("the run has no IMU sample".into()))?;
    let end = t0 + LOG_S;
    let imu = &data.imu[..data.imu.partition_point(|s| s.t_s <= end)];
    let ranges = &data.ranges[..data.ranges.partition_point(|r| r.t_s <= end)];
    let input =
        BatchInput { marginals_every_s: Some(MARGINALS_EVERY_S), ..BatchInput::forward(imu, ranges, &data.anchors, config) };
    let BatchOutput::Inertial { trace, init, .. } = run_method(method, &input)? else {
        return Err(Error::InvalidCall(format!("{} is not an inertial filter", method.name())));
    };
    let decided = init.map(|i| i.decided_s).ok_or_else(|| Error::InvalidCall("the run was not self-initialised".into()))?;
    let body_from_filter = sim.imu_rotation * config.mounting.imu_rotation.inverse();
    let truth_at = |t_s: f64| {
        let k = data.truth.partition_point(|x| x.t_s <= t_s).saturating_sub(1);
        data.truth[k].orientation * body_from_filter
    };
    let at = |t_s: f64| trace.marginals.iter().find(|m| m.t_s >= t_s - 1e-9);
    let heading = |m: &Marginals| heading_error_and_std(m, &truth_at(m.t_s));
    let first = at(decided).ok_or_else(|| Error::InvalidCall(format!("no sample after the start at {decided} s")))?;
    let (heading_error_rad, heading_std_rad) = heading(first);
    let start = StartSample { decided_s: decided - t0, heading_error_rad, heading_std_rad };
    let attitude_nees = (0..=AFTER_START_S)
        .map_while(|k| at(first.t_s + k as f64))
        .filter_map(|m| {
            let truth = truth_at(m.t_s);
            let error = (m.state.orientation.inverse() * truth).scaled_axis();
            nees(&error, &m.attitude_cov?, 3)
        })
        .collect();
    let heading_error_5s_rad = at(first.t_s + 5.0).map_or(f64::NAN, |m| heading(m).0);
    Ok(Run { start, attitude_nees, heading_error_5s_rad })
}

/// Interval of the marginals sampled to find a run's start, s.
const MARGINALS_EVERY_S: f64 = 0.05;
