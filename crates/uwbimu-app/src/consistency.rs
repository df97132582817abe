//! Monte Carlo consistency checks: a method run on simulated scenarios with the configuration set
//! to the simulator's true noise, its errors against the truth normalised by the covariance it
//! reports (NEES of position, velocity and attitude) and its innovations by their predicted
//! variance (NIS), each tested against the χ² distribution it has when the filter is consistent
//! ([`NeesSeries`], [`NisStats`]; Bar-Shalom, Li & Kirubarajan 2001, §5.4). The oracle is the
//! simulator's truth and its noise model, not a figure the code produced.
//!
//! **The scenarios** ([`SCENARIOS`], each built by [`scenario`]): a vehicle on the
//! `hall_vehicle` figure-8 (0.4 m high, four anchors in a 10 m × 8 m hall at 0.8–2.2 m) unless
//! said otherwise, IMU at 100 Hz, UWB σ = 0.1 m.
//!
//! | scenario | start | IMU | UWB | what it tests |
//! |---|---|---|---|---|
//! | `moving_start` | at 0.98 m/s on a straight stretch | consumer, 0.005 m/s²/√Hz | 5 Hz from 0.5 s after the IMU | a log started in motion, the IMU before UWB |
//! | `still_start` | 2 s still, then the figure-8 | consumer | 10 Hz | a start at rest |
//! | `uwb_2hz` | as `moving_start` | consumer | 2 Hz | low-rate UWB |
//! | `uwb_50hz` | as `moving_start` | consumer | 50 Hz | high-rate UWB |
//! | `tactical_imu` | as `moving_start` | tactical grade, 0.0005 m/s²/√Hz, 5e-5 rad/s/√Hz | 5 Hz | a small process noise |
//! | `staggered` | as `moving_start` | consumer | 10 Hz, eight cuboid anchors 3 ms apart, 1 ms jitter | the epoch rule with ranges at different times |
//! | `heading_uncertain` | as `moving_start`, heading σ 0.2 rad | as `moving_start` | as `moving_start` | the linearisation while a poorly known heading converges |
//! | `coplanar_altitude` | as `moving_start` | consumer | 5 Hz, the four anchors coplanar at 2.2 m; a 25 Hz altitude, σ 0.05 m | the altitude model where the ranges barely fix the height |
//! | `outage_odometry` | as `moving_start` | consumer | 5 Hz, out from 10 s to 30 s; a 50 Hz wheel speed (body x), σ 0.05 m/s | the odometry model carrying a 20 s outage |
//! | `two_tags` | as `moving_start`, heading σ 0.2 rad | consumer | 5 Hz from two tags 0.6 m apart along body x, taking turns | the heading made observable by the tags' geometry |
//! | `outage_pose_fix` | as `moving_start` | consumer | 5 Hz, out from 10 s to 30 s; 2 Hz pose fixes at a lever arm of (0.2, 0.1, 0.3) m, σ 0.05 m and 0.05 rad in yaw | the pose-fix models (position at a lever arm, yaw) carrying a 20 s outage |
//!
//! The last four carry an input besides the IMU and one tag's ranges ([`scenario_inputs`]); a
//! method is run on them only when it takes that input.
//!
//! **A run** is the first [`LOG_S`] of the scenario's log. The filter is given the truth at the
//! first IMU sample plus an error drawn from the initial covariance it is told
//! ([`initial_uncertainty`]: position 0.3 m, velocity 0.1 m/s, attitude 0.05 rad about each axis,
//! the heading 0.2 rad in `heading_uncertain`, as [`InitialState`]'s default; the biases start at
//! zero with the configured σ, which is the distribution the simulator draws them from), as
//! Bar-Shalom's test assumes; its configuration is the simulator's noise ([`Settings::Matched`])
//! or the library defaults ([`Settings::Defaults`], for the comparison of the two). The forward
//! filter's estimate is sampled every [`SAMPLE_INTERVAL_S`] with the covariance of its error
//! blocks ([`uwbimu_estimation::pipeline::Marginals`]); `uwb_ls`'s fixes at the same times (the
//! last fix at or before each) with their least-squares covariance.

mod self_start;
mod stats;

pub use self_start::{
    heading_error_and_std, self_start_inputs, self_start_monte_carlo, self_start_scenario, SelfStart, StartSample, AFTER_START_S,
    SELF_START_SCENARIOS,
};
pub use stats::{chi2_mean_interval, NeesSeries, NisStats};

use nalgebra::{Cholesky, Matrix2};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use uwbimu_estimation::pipeline::Marginals;
use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{quat_exp, Mat3, Vec3};
use uwbimu_vocabulary::records::TruthSample;
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use crate::generality::Settings;
use crate::methods::run_method;
use crate::model_choice::ModelChoice;
use crate::registry::{Input, Method};
use crate::run::{BatchInput, BatchOutput};
use crate::sim::{
    cuboid8, hall_anchors, matched_config, simulate, AltimeterConfig, ImuNoise, OdometerConfig, Outage, PoseFixSimConfig,
    SimConfig, SimData, Trajectory, UwbConfig,
};

/// The scenarios of [`scenario`], in the order of the module table.
pub const SCENARIOS: &[&str] = &[
    "moving_start",
    "still_start",
    "uwb_2hz",
    "uwb_50hz",
    "tactical_imu",
    "staggered",
    "heading_uncertain",
    "coplanar_altitude",
    "outage_odometry",
    "two_tags",
    "outage_pose_fix",
];

/// Height of the coplanar anchors of `coplanar_altitude`, m.
pub const COPLANAR_HEIGHT_M: f64 = 2.2;

/// The inputs of scenario `name` besides the IMU and one tag's ranges (a method runs on it only
/// if it takes them).
pub fn scenario_inputs(name: &str) -> &'static [Input] {
    match name {
        "coplanar_altitude" => &[Input::Sensor(SensorKind::Altitude)],
        "outage_odometry" => &[Input::Sensor(SensorKind::Odometry)],
        "two_tags" => &[Input::Tags],
        "outage_pose_fix" => &[Input::Sensor(SensorKind::PoseFix)],
        _ => &[],
    }
}

/// Whether `method` takes every input of scenario `name`.
pub fn runs_on(method: Method, name: &str) -> bool {
    scenario_inputs(name).iter().all(|i| method.takes(*i))
}

/// Separation of the two tags of `two_tags` along body x, m.
pub const TWO_TAGS_SEPARATION_M: f64 = 0.6;

/// Length of a run's log, s (the simulated run is cut there).
pub const LOG_S: f64 = 40.0;

/// Interval between the samples of a run's estimate, s.
pub const SAMPLE_INTERVAL_S: f64 = 1.0;

/// Time after the start left out of a run's RMSE, s (the initial error drawn is still being
/// corrected).
pub const RMSE_SETTLE_S: f64 = 5.0;

/// Height of the body origin on every scenario's figure-8, m.
pub const PLANE_HEIGHT_M: f64 = 0.4;

/// Time into the `hall_vehicle` figure-8 (2 s still, 37 s laps) at which the moving logs start:
/// the crossing at the centre, where the path is straight and the speed 0.98 m/s.
const MOVING_START_S: f64 = 20.5;

/// Time after the first IMU sample at which UWB starts in the moving logs, s.
const UWB_DELAY_S: f64 = 0.5;

/// Stream of the initial-error draws (the simulator's own streams are 1–5).
const STREAM_INITIAL: u64 = 11;

/// The scenario `name` of [`SCENARIOS`] with every random draw seeded by `seed` (see the module
/// table). Unknown name → [`Error::UnknownOption`] listing them.
pub fn scenario(name: &str, seed: u64) -> Result<SimConfig> {
    let figure_eight = |laps: u32| Trajectory::figure_eight(Vec3::new(5.0, 4.0, PLANE_HEIGHT_M), 3.5, 4.5, 37.0, laps, 2.0);
    let consumer = ImuNoise { accel_noise_density: 0.005, ..ImuNoise::consumer_mems() };
    let moving = |rate_hz: f64, imu_noise: ImuNoise| -> Result<SimConfig> {
        Ok(SimConfig {
            trajectory: figure_eight(2)?,
            imu_noise,
            uwb: UwbConfig {
                rate_hz,
                outages: vec![Outage { start_s: MOVING_START_S, end_s: MOVING_START_S + UWB_DELAY_S }],
                ..UwbConfig::default()
            },
            start_s: MOVING_START_S,
            seed,
            ..SimConfig::default()
        })
    };
    let tactical = ImuNoise {
        accel_noise_density: 5e-4,
        gyro_noise_density: 5e-5,
        accel_bias_std: 0.005,
        gyro_bias_std: 1e-4,
        accel_bias_walk: 1e-5,
        gyro_bias_walk: 1e-6,
    };
    let sim = match name {
        "still_start" => SimConfig {
            trajectory: figure_eight(1)?,
            uwb: UwbConfig { rate_hz: 10.0, ..UwbConfig::default() },
            seed,
            ..SimConfig::default()
        },
        "uwb_2hz" => moving(2.0, ImuNoise::consumer_mems())?,
        "uwb_50hz" => moving(50.0, ImuNoise::consumer_mems())?,
        "tactical_imu" => moving(5.0, tactical)?,
        "moving_start" | "heading_uncertain" => moving(5.0, consumer)?,
        "two_tags" => {
            let base = moving(5.0, consumer)?;
            SimConfig { more_tags_m: vec![base.lever_arm_m + Vec3::new(TWO_TAGS_SEPARATION_M, 0.0, 0.0)], ..base }
        }
        "staggered" => {
            let base = moving(10.0, ImuNoise::consumer_mems())?;
            SimConfig { anchors: cuboid8(), uwb: UwbConfig { stagger_s: 3e-3, jitter_s: 1e-3, ..base.uwb.clone() }, ..base }
        }
        "coplanar_altitude" => {
            let base = moving(5.0, consumer)?;
            let anchors = base.anchors.iter().map(|a| Vec3::new(a.x, a.y, COPLANAR_HEIGHT_M)).collect();
            SimConfig { anchors, altimeter: Some(AltimeterConfig::default()), ..base }
        }
        "outage_odometry" => {
            let mut base = moving(5.0, consumer)?;
            base.uwb.outages.push(Outage { start_s: MOVING_START_S + 10.0, end_s: MOVING_START_S + 30.0 });
            SimConfig { odometer: Some(OdometerConfig::default()), ..base }
        }
        "outage_pose_fix" => {
            let mut base = moving(5.0, consumer)?;
            base.uwb.outages.push(Outage { start_s: MOVING_START_S + 10.0, end_s: MOVING_START_S + 30.0 });
            let fixes = PoseFixSimConfig {
                rate_hz: 2.0,
                std_m: 0.05,
                yaw_std_rad: Some(0.05),
                lever_arm_m: Vec3::new(0.2, 0.1, 0.3),
                gaps: Vec::new(),
            };
            SimConfig { pose_fix: Some(fixes), ..base }
        }
        _ => return Err(Error::unknown_option("consistency scenario", name, SCENARIOS.iter().copied())),
    };
    debug_assert_eq!(sim.anchors.len(), if name == "staggered" { 8 } else { hall_anchors().len() });
    Ok(sim)
}

/// The initial uncertainty of a run of scenario `name` (the state itself is zero): the standard
/// deviations the filter is told and its initial error is drawn from. [`InitialState`]'s
/// defaults but for the heading, 0.05 rad (a start pose known to 3°), except in
/// `heading_uncertain` and `two_tags`, which keep the default 0.2 rad.
pub fn initial_uncertainty(name: &str) -> InitialState {
    let nominal = InitialState::default();
    if matches!(name, "heading_uncertain" | "two_tags") {
        return nominal;
    }
    InitialState { orientation_std: Vec3::repeat(0.05), ..nominal }
}

/// The filter configuration of a run of `sim` under `settings` ([`Settings::Matched`]: the
/// simulator's true noise, [`matched_config`]). Told the true noise, a method that chooses its
/// range-error model has nothing to choose: model selection is off under [`Settings::Matched`]
/// ([`choice_with_true_noise`] checks that the choice would keep the configuration), and stays
/// as configured otherwise (on with the defaults: `best` chooses as a user's run does). The plane
/// constraint (`criekf`) gets the height the vehicle drives at, [`PLANE_HEIGHT_M`], unless the
/// settings set one, as a user of it would measure it: unset, the plane is the initial height,
/// taken as exact, and the error drawn into the initial state would hold the whole track off by
/// that much.
pub fn settings_config(sim: &SimConfig, settings: Settings<'_>) -> FilterConfig {
    let mut config = settings.config(&matched_config(sim));
    config.constraints.plane_height.get_or_insert(PLANE_HEIGHT_M);
    if settings == Settings::Matched {
        config.model_selection.enabled = false;
    }
    config
}

/// The initial state of a run: the truth at the first IMU sample plus an error drawn with `rng`
/// from the covariance `uncertainty`'s standard deviations give (position, velocity, and attitude
/// about the navigation axes), which the state keeps.
pub fn drawn_initial(truth: &TruthSample, uncertainty: &InitialState, rng: &mut ChaCha8Rng) -> InitialState {
    let nominal = uncertainty.clone();
    let mut draw = |std: &Vec3| Vec3::from_fn(|i, _| std[i] * Distribution::<f64>::sample(&StandardNormal, &mut *rng));
    let (dp, dv, dtheta_nav) = (draw(&nominal.position_std), draw(&nominal.velocity_std), draw(&nominal.orientation_std));
    InitialState {
        position: truth.position - dp,
        velocity: truth.velocity - dv,
        // The truth is the estimate turned by the error: q = Exp(δθ_nav) ⊗ q̂.
        orientation: quat_exp(&(-dtheta_nav)) * truth.orientation,
        ..nominal
    }
}

/// What one method did over the Monte Carlo runs of one scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Consistency {
    /// The method.
    pub method: Method,
    /// The scenario (one of [`SCENARIOS`]).
    pub scenario: &'static str,
    /// NEES of the position (3 dof; 2 for the planar filters, which estimate x and y).
    pub position: NeesSeries,
    /// NEES of the velocity (as the position); None for `uwb_ls`, which has none.
    pub velocity: Option<NeesSeries>,
    /// NEES of the attitude (3 dof); None for filters without an attitude state.
    pub attitude: Option<NeesSeries>,
    /// NIS of the scalar updates (the tightly coupled and unscented filters); None where the
    /// updates report no prior innovation.
    pub nis: Option<NisStats>,
    /// Horizontal RMSE of each run after [`RMSE_SETTLE_S`], m.
    pub rmse_m: Vec<f64>,
}

impl Consistency {
    /// The mean over the runs of [`Consistency::rmse_m`], m.
    pub fn mean_rmse_m(&self) -> f64 {
        self.rmse_m.iter().sum::<f64>() / self.rmse_m.len().max(1) as f64
    }
}

/// One run's samples: per sample time the NEES of each block (None where the filter has none),
/// its NIS values and its horizontal RMSE.
struct RunSamples {
    times_s: Vec<f64>,
    nees: [Vec<Option<f64>>; 3],
    dofs: [usize; 3],
    nis: Vec<f64>,
    rmse_m: f64,
}

/// Runs each of `methods` on scenario `name` once per seed of `seeds` under `settings` and
/// gathers the NEES and NIS of each method's runs, in the order of `methods`. Each seed is
/// simulated once for all methods, the seeds in parallel. Fails when a run fails or the runs of a
/// method sample different times (they share the scenario's clock).
pub fn monte_carlo(methods: &[Method], name: &str, seeds: &[u64], settings: Settings<'_>) -> Result<Vec<Consistency>> {
    let scenario_name = known_scenario(SCENARIOS, "consistency scenario", name)?;
    let per_seed = crate::parallel::map_all(seeds, |&seed| {
        let run = SeedRun::new(name, seed, settings)?;
        methods.iter().map(|&method| run_once(method, &run)).collect::<Result<Vec<_>>>()
    });
    let by_method = by_method(methods.len(), per_seed)?;
    methods.iter().zip(by_method).map(|(&method, runs)| gather(method, scenario_name, runs)).collect()
}

/// `name` as the entry of `names`, the scenarios of a Monte Carlo runner (`what` they are); an
/// unknown name is an error listing them.
fn known_scenario(names: &[&'static str], what: &'static str, name: &str) -> Result<&'static str> {
    names.iter().copied().find(|s| *s == name).ok_or_else(|| Error::unknown_option(what, name, names.iter().copied()))
}

/// The runs of each of `methods` methods from the runs of each seed (each seed's in the order of
/// the methods): per method, its runs in the order of the seeds. The first failed seed's error.
fn by_method<R>(methods: usize, per_seed: Vec<Result<Vec<R>>>) -> Result<Vec<Vec<R>>> {
    let mut by_method: Vec<Vec<R>> = (0..methods).map(|_| Vec::with_capacity(per_seed.len())).collect();
    for runs in per_seed {
        for (slot, run) in by_method.iter_mut().zip(runs?) {
            slot.push(run);
        }
    }
    Ok(by_method)
}

/// The runs of `method` on `scenario` gathered into its [`Consistency`].
fn gather(method: Method, scenario: &'static str, runs: Vec<RunSamples>) -> Result<Consistency> {
    let first = runs.first().ok_or_else(|| Error::InsufficientData("no seed given".into()))?;
    let k = runs.iter().map(|r| r.times_s.len()).min().unwrap_or(0);
    if k == 0 || runs.iter().any(|r| r.times_s[..k] != first.times_s[..k]) {
        return Err(Error::InvalidCall(format!("the runs of {} on {scenario} sampled different times", method.name())));
    }
    let series = |block: usize| -> Option<NeesSeries> {
        let mut mean = vec![0.0; k];
        for r in &runs {
            for (m, v) in mean.iter_mut().zip(&r.nees[block][..k]) {
                *m += (*v)? / runs.len() as f64;
            }
        }
        Some(NeesSeries { dof: first.dofs[block], runs: runs.len(), times_s: first.times_s[..k].to_vec(), mean })
    };
    let position = series(0).ok_or_else(|| Error::InvalidCall(format!("{} gave no position NEES", method.name())))?;
    let epochs: usize = runs.iter().map(|r| r.nis.len()).sum();
    let nis = (epochs > 0).then(|| NisStats { epochs, mean: runs.iter().flat_map(|r| &r.nis).sum::<f64>() / epochs as f64 });
    Ok(Consistency {
        method,
        scenario,
        position,
        velocity: series(1),
        attitude: series(2),
        nis,
        rmse_m: runs.iter().map(|r| r.rmse_m).collect(),
    })
}

/// One seed of a scenario as every method's run of it sees it: the simulated log, the
/// configuration `settings` give ([`settings_config`]) and the initial state drawn for the seed.
struct SeedRun {
    sim: SimConfig,
    data: SimData,
    config: FilterConfig,
    initial: InitialState,
    /// Time of the first IMU sample, s.
    t0_s: f64,
}

impl SeedRun {
    fn new(name: &str, seed: u64, settings: Settings<'_>) -> Result<Self> {
        let sim = scenario(name, seed)?;
        let data = simulate(&sim)?;
        let config = settings_config(&sim, settings);
        let truth0 = data.truth.first().ok_or_else(|| Error::InsufficientData("the run has no IMU sample".into()))?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(STREAM_INITIAL);
        let initial = drawn_initial(truth0, &initial_uncertainty(name), &mut rng);
        let t0_s = truth0.t_s;
        Ok(Self { sim, data, config, initial, t0_s })
    }

    /// The measurements of the other sensors `method` takes, within the first [`LOG_S`].
    fn observations(&self, method: Method) -> Vec<Observation> {
        let mut observations = self.data.observations_for(|kind| method.takes(Input::Sensor(kind)));
        observations.truncate(observations.partition_point(|o| o.t_s() <= self.t0_s + LOG_S));
        observations
    }

    /// The forward run's input: the first [`LOG_S`] of the log from the drawn initial state, the
    /// marginals sampled every [`SAMPLE_INTERVAL_S`].
    fn input<'a>(&'a self, observations: &'a [Observation]) -> BatchInput<'a> {
        let end = self.t0_s + LOG_S;
        BatchInput {
            imu: &self.data.imu[..self.data.imu.partition_point(|s| s.t_s <= end)],
            ranges: &self.data.ranges[..self.data.ranges.partition_point(|r| r.t_s <= end)],
            anchors: &self.data.anchors,
            initial: Some(&self.initial),
            config: &self.config,
            smooth: false,
            observations,
            progress: None,
            marginals_every_s: Some(SAMPLE_INTERVAL_S),
        }
    }
}

/// The range-error model `method` chooses ([`crate::select::choose`]) on seed `seed` of the
/// consistency scenario `name` when told the simulator's true noise, on the log and from the
/// start a Monte Carlo run has: the configuration told should be kept, as there is nothing to
/// correct (which is why [`settings_config`] turns the choice off for [`Settings::Matched`]).
///
/// # Errors
/// An unknown scenario; a failed simulation or choice.
pub fn choice_with_true_noise(method: Method, name: &str, seed: u64) -> Result<ModelChoice> {
    let mut run = SeedRun::new(known_scenario(SCENARIOS, "consistency scenario", name)?, seed, Settings::Matched)?;
    run.config.model_selection.enabled = true;
    let observations = run.observations(method);
    crate::select::choose(method, &run.input(&observations))
}

/// One run of `method` over the simulated run `data` of `sim` with `config` from `initial`.
fn run_once(method: Method, run: &SeedRun) -> Result<RunSamples> {
    let SeedRun { sim, data, .. } = run;
    let observations = run.observations(method);
    let input = run.input(&observations);
    let (imu, t0) = (input.imu, run.t0_s);
    let lever_arm = sim.lever_arm_m;
    match run_method(method, &input)? {
        BatchOutput::Inertial { trace, .. } => {
            let truth_at = |t_s: f64| truth_index(data, t_s).map(|k| &data.truth[k]);
            let mut samples = RunSamples::new();
            for m in &trace.marginals {
                let truth = truth_at(m.t_s).ok_or_else(|| Error::InvalidCall(format!("no truth at {} s", m.t_s)))?;
                samples.push(m, truth, t0);
            }
            // One NIS per epoch: the mean of its ranges' NIS at the prior.
            let mut epochs: Vec<(f64, f64, usize)> = Vec::new();
            for (innovation, variance, epoch_t_s) in
                trace.updates.iter().filter_map(|u| u.report.prior.map(|(e, s)| (e, s, u.epoch_t_s)))
            {
                match epochs.last_mut() {
                    Some((t, sum, n)) if *t == epoch_t_s => (*sum, *n) = (*sum + innovation * innovation / variance, *n + 1),
                    _ => epochs.push((epoch_t_s, innovation * innovation / variance, 1)),
                }
            }
            samples.nis = epochs.iter().map(|(_, sum, n)| sum / *n as f64).collect();
            let errors: Vec<f64> = trace
                .steps
                .iter()
                .filter(|s| s.t_s - t0 >= RMSE_SETTLE_S)
                .filter_map(|s| truth_at(s.t_s).map(|truth| (s.state.position - truth.position).xy().norm()))
                .collect();
            samples.rmse_m = rms(&errors);
            Ok(samples)
        }
        BatchOutput::Multilateration(fixes) => {
            let tag = |k: usize| data.truth[k].position + data.truth[k].orientation * lever_arm;
            let mut samples = RunSamples::new();
            let mut next = 0;
            let end = imu.last().map_or(t0, |s| s.t_s);
            let mut t = t0;
            while t <= end {
                while next < fixes.len() && fixes[next].0 <= t {
                    next += 1;
                }
                if let Some((t_fix, fix)) = next.checked_sub(1).map(|i| &fixes[i]) {
                    let k = truth_index(data, *t_fix).ok_or_else(|| Error::InvalidCall(format!("no truth at {t_fix} s")))?;
                    let dims = if fix.planar { 2 } else { 3 };
                    samples.times_s.push(t - t0);
                    samples.nees[0].push(nees(&(tag(k) - fix.position), &fix.covariance, dims));
                    samples.nees[1].push(None);
                    samples.nees[2].push(None);
                    samples.dofs[0] = dims;
                }
                t += SAMPLE_INTERVAL_S;
            }
            let errors: Vec<f64> = fixes
                .iter()
                .filter(|(t_s, _)| t_s - t0 >= RMSE_SETTLE_S)
                .filter_map(|(t_s, f)| truth_index(data, *t_s).map(|k| (f.position - tag(k)).xy().norm()))
                .collect();
            samples.rmse_m = rms(&errors);
            Ok(samples)
        }
    }
}

impl RunSamples {
    fn new() -> Self {
        Self {
            times_s: Vec::new(),
            nees: [Vec::new(), Vec::new(), Vec::new()],
            dofs: [3, 3, 3],
            nis: Vec::new(),
            rmse_m: f64::NAN,
        }
    }

    /// Adds the NEES of the sample `m` against `truth`, at `m.t_s − t0`.
    fn push(&mut self, m: &Marginals, truth: &TruthSample, t0: f64) {
        let x = &m.state;
        self.times_s.push(m.t_s - t0);
        self.dofs = [m.dims, m.dims, 3];
        self.nees[0].push(nees(&(truth.position - x.position), &m.position_cov, m.dims));
        self.nees[1].push(nees(&(truth.velocity - x.velocity), &m.velocity_cov, m.dims));
        let attitude_error = (x.orientation.inverse() * truth.orientation).scaled_axis();
        self.nees[2].push(m.attitude_cov.and_then(|p| nees(&attitude_error, &p, 3)));
    }
}

/// Index of the truth sample at time `t_s` (the truth is sampled at the IMU times; the last one
/// at or before `t_s`).
fn truth_index(data: &SimData, t_s: f64) -> Option<usize> {
    data.truth.partition_point(|s| s.t_s <= t_s).checked_sub(1)
}

/// `eᵀ·P⁻¹·e` over the leading `dims` (2 or 3) components; None when that block of `p` is not
/// positive definite.
fn nees(e: &Vec3, p: &Mat3, dims: usize) -> Option<f64> {
    if dims == 2 {
        let block: Matrix2<f64> = p.fixed_view::<2, 2>(0, 0).into_owned();
        let e2 = e.xy();
        return Cholesky::new(block).map(|c| e2.dot(&c.solve(&e2)));
    }
    Cholesky::new(*p).map(|c| e.dot(&c.solve(e)))
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}
