//! The named methods of the batch API and the function that runs one of them over whole arrays.

use uwbimu_estimation::filters::InertialFilter;
use uwbimu_estimation::gate::Gate;
use uwbimu_estimation::init::SelfInit;
use uwbimu_estimation::multilateration::{uwb_ls, Fix, LsConfig};
use uwbimu_estimation::pipeline::{run_streams, self_initialize, smoothed_steps, Event, Progress, StepRecord, Streams, Trace};
use uwbimu_estimation::planar::{PlanarFilter, PlanarKind};
use uwbimu_estimation::units::check_imu_units;
use uwbimu_vocabulary::config::{FilterConfig, InitialState, SmoothingConfig};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::sensors::{merge, Clock, Observation, SensorKind};

use crate::outlier_smoothing::{leave_out_long_ranges, ResidualWalk};
use crate::select::ModelChoice;

/// What a method takes besides IMU samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// Ranges to anchors.
    Ranges,
    /// Ranges from several tags (a `tag` column beyond 0), each at its lever arm.
    Tags,
    /// A sensor of the registry ([`uwbimu_vocabulary::sensors`]).
    Sensor(SensorKind),
}

impl Input {
    /// The input's name in Python (`METHODS[name]["takes"]`) and the docs: `ranges`, or the
    /// sensor's name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ranges => "ranges",
            Self::Tags => "tags",
            Self::Sensor(kind) => kind.info().name,
        }
    }
}

/// Whether and when the batch API RTS-smooths a method's run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Smoothing {
    /// Never: the method has no inertial 15-state record to smooth.
    Never,
    /// When asked (`smooth=True`, `--smooth`).
    OnRequest,
    /// Unless a forward pass is asked for.
    ByDefault,
}

impl Smoothing {
    /// The smoothing's name in Python (`METHODS[name]["smoothing"]`) and the docs.
    pub fn name(self) -> &'static str {
        match self {
            Self::Never => "never",
            Self::OnRequest => "on_request",
            Self::ByDefault => "by_default",
        }
    }
}

/// One row of the method registry (the `methods!` declaration in this module): everything the library says about a method
/// besides how it runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MethodInfo {
    /// The name the batch API, replay files and the CLI take.
    pub name: &'static str,
    /// The measurements it takes besides IMU samples.
    pub takes: &'static [Input],
    /// When it is smoothed.
    pub smoothing: Smoothing,
    /// Its streaming class in Python (`uwbimu_rs.<class>`), if it has one.
    pub streaming_class: Option<&'static str>,
    /// Whether the batch method chooses its range-error model, NLOS skew and range noise on the
    /// log ([`crate::select`]); a row says `chooses_model: true`, the others leave it out.
    pub chooses_model: bool,
    /// Its doc comment (one line per doc line): the composition and where it comes from.
    pub doc: &'static str,
}

/// Declares the method registry: one row per method — variant, name, how it runs, what it takes,
/// its smoothing and whether it chooses its model, with its doc; an inertial method's filter is also its streaming class.
/// From the rows come [`Method`], [`Method::ALL`], [`Method::info`] (names, parsing,
/// capabilities, error lists), the dispatch of [`run_method`], and the macro
/// [`for_each_streaming_filter!`](crate::for_each_streaming_filter) with which the Python
/// bindings declare and register one class per streaming filter. Adding a method is adding a row.
macro_rules! methods {
    ($d:tt $(
        $(#[doc = $doc:literal])+
        $variant:ident {
            name: $name:literal,
            run: $run:ident $(($ty:ident))?,
            takes: [$($input:ident),+],
            smoothing: $smoothing:ident
            $(, chooses_model: $chooses:literal)? $(,)?
        }
    ),+ $(,)?) => {
        /// A method name accepted by the batch API, one per row of the registry.
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub enum Method {
            $($(#[doc = $doc])+ $variant,)+
        }

        impl Method {
            /// Every method, in registry order (the order of `uwbimu_rs.FILTERS`).
            pub const ALL: &'static [Method] = &[$(Method::$variant),+];

            /// The method's registry row.
            pub const fn info(self) -> &'static MethodInfo {
                match self {
                    $(Method::$variant => &MethodInfo {
                        name: $name,
                        takes: &[$(methods!(@input $input)),+],
                        smoothing: Smoothing::$smoothing,
                        streaming_class: methods!(@class $run $($ty)?),
                        chooses_model: methods!(@chooses $($chooses)?),
                        doc: concat!($($doc, "\n"),+),
                    },)+
                }
            }
        }

        /// Runs `method` on measurements already calibrated (see [`run_method`]).
        fn dispatch(method: Method, input: &BatchInput<'_>) -> Result<BatchOutput> {
            match method {
                $(Method::$variant => methods!(@run input, $run $($ty)?),)+
            }
        }

        /// Replays a recording streamed from its file with `method` ([`crate::replay::streamed`]);
        /// `uwb_ls` is not streamed (it needs no IMU: the whole-recording replay serves it).
        #[cfg(feature = "io")]
        pub(crate) fn dispatch_streamed(
            method: Method,
            input: &crate::replay::streamed::StreamedInput<'_>,
            on_step: &mut dyn FnMut(&uwbimu_estimation::pipeline::StepRecord) -> crate::io::IoResult<()>,
        ) -> crate::io::IoResult<crate::replay::streamed::StreamedReplay> {
            match method {
                $(Method::$variant => methods!(@stream method, input, on_step, $run $($ty)?),)+
            }
        }

        /// Calls `$callback!(run [Type], [extra…], "doc", …)` once for every method: `run` how it
        /// runs (`inertial`, `planar`, `multilateration`), `Type` its filter in
        /// `uwbimu_estimation::filters` when it is inertial (its streaming class), `extra` the
        /// tokens given after the callback's name (the Python bindings declare and register one
        /// class per inertial method with it, named as the type).
        #[macro_export]
        macro_rules! for_each_streaming_filter {
            ($d callback:ident $d($d extra:tt)*) => {
                $($d callback!($run $($ty)?, [$d($d extra)*], $($doc),+);)+
            };
        }
    };
    (@input Ranges) => { Input::Ranges };
    (@input Tags) => { Input::Tags };
    (@input $sensor:ident) => { Input::Sensor(SensorKind::$sensor) };
    (@chooses) => { false };
    (@chooses $chooses:literal) => { $chooses };
    (@class inertial $ty:ident) => { Some(stringify!($ty)) };
    (@class $run:ident $($ty:ident)?) => { None };
    (@run $input:ident, multilateration) => {{
        let ls = LsConfig::from_filter_config($input.config);
        Ok(BatchOutput::Multilateration(uwb_ls(&plausible_ranges($input), $input.anchors, &ls)))
    }};
    (@run $input:ident, inertial $ty:ident) => {
        run_inertial(|i| uwbimu_estimation::filters::$ty::new($input.anchors.to_vec(), i, $input.config.clone()), $input)
    };
    (@run $input:ident, planar $kind:ident) => { run_planar(PlanarKind::$kind, $input) };
    (@stream $method:ident, $input:ident, $on_step:ident, multilateration) => {
        Err(Error::InvalidCall(format!("{} is not streamed: replay the whole recording", $method.name())).into())
    };
    (@stream $method:ident, $input:ident, $on_step:ident, inertial $ty:ident) => {{
        use uwbimu_estimation::filters::InertialFilter as _;
        let kind = crate::replay::streamed::FilterKind {
            build: uwbimu_estimation::filters::$ty::new,
            core: |f: &mut uwbimu_estimation::filters::$ty| Some(f.core_mut()),
            smoothing: |f: &uwbimu_estimation::filters::$ty| f.config().smoothing,
        };
        crate::replay::streamed::run($method, $input, &kind, $on_step)
    }};
    (@stream $method:ident, $input:ident, $on_step:ident, planar $kind:ident) => {{
        let kind = crate::replay::streamed::FilterKind {
            build: |anchors, initial, config| PlanarFilter::new(PlanarKind::$kind, anchors, initial, &config),
            core: |_: &mut PlanarFilter| None,
            smoothing: |_: &PlanarFilter| SmoothingConfig::default(),
        };
        crate::replay::streamed::run($method, $input, &kind, $on_step)
    }};
}

methods! {$
    /// UWB-only least squares per epoch (Liu et al. 2019 eqs. (8)–(13), then Gauss–Newton).
    UwbLs { name: "uwb_ls", run: multilateration, takes: [Ranges], smoothing: Never },
    /// The tightly coupled EKF of Li & Wang (2020).
    Ekf { name: "ekf", run: inertial(Ekf), takes: [Ranges, Tags, Tdoa, Altitude, Odometry], smoothing: OnRequest },
    /// The iterated EKF (Li & Wang 2020, Algorithm 1 without re-weighting).
    Iekf { name: "iekf", run: inertial(Iekf), takes: [Ranges, Tags, Tdoa, Altitude, Odometry], smoothing: OnRequest },
    /// The robust EKF of Li & Wang (2020) (χ² inflation against the prior).
    Rekf { name: "rekf", run: inertial(Rekf), takes: [Ranges, Tags, Tdoa, Altitude, Odometry], smoothing: OnRequest },
    /// The robust iterated EKF of Li & Wang (2020) (Algorithm 1).
    Riekf { name: "riekf", run: inertial(Riekf), takes: [Ranges, Tags, Tdoa, Altitude, Odometry], smoothing: OnRequest },
    /// RIEKF with zero-velocity, pseudo-velocity and plane constraints (Li & Wang 2020, CRIEKF).
    Criekf { name: "criekf", run: inertial(Criekf), takes: [Ranges, Tags, Tdoa, Altitude, Odometry], smoothing: OnRequest },
    /// The complementary Kalman filter of the ARCKF paper (Sensors 2018).
    Ckf { name: "ckf", run: inertial(Ckf), takes: [Ranges, Tags, Tdoa, Altitude, Odometry], smoothing: OnRequest },
    /// The adaptive-robust complementary Kalman filter of the ARCKF paper (Sensors 2018).
    Arckf { name: "arckf", run: inertial(Arckf), takes: [Ranges, Tags, Tdoa, Altitude, Odometry], smoothing: OnRequest },
    /// The adaptive complementary Kalman filter with gravity and geomagnetic aiding (the ACKF paper).
    Ackf {
        name: "ackf",
        run: inertial(Ackf),
        takes: [Ranges, Tags, Tdoa, Magnetometer, Altitude, Odometry],
        smoothing: OnRequest,
    },
    /// The loosely coupled error-state filter of Liu et al. (2019).
    Eskf { name: "eskf", run: inertial(Eskf), takes: [Ranges], smoothing: OnRequest },
    /// The Sage–Husa adaptive ESKF of Liu et al. (2019).
    Shaf { name: "shaf", run: inertial(Shaf), takes: [Ranges], smoothing: OnRequest },
    /// The Sage–Husa fuzzy adaptive ESKF of Liu et al. (2019).
    Shfaf { name: "shfaf", run: inertial(Shfaf), takes: [Ranges], smoothing: OnRequest },
    /// The 15-state error-state UKF (Wang et al. 2018 eqs. (11)–(14) on the INS error state).
    Ukf { name: "ukf", run: inertial(Ukf), takes: [Ranges, Tags, Tdoa, Altitude, Odometry], smoothing: OnRequest },
    /// The robust 15-state error-state UKF (ours): ukf's update with rekf's χ² inflation.
    Rukf { name: "rukf", run: inertial(Rukf), takes: [Ranges, Tags, Tdoa, Altitude, Odometry], smoothing: OnRequest },
    /// The planar 4-state EKF of Wang et al. (2018) (eqs. (5)–(10)).
    Ekf2d { name: "ekf2d", run: planar(Ekf), takes: [Ranges], smoothing: Never },
    /// The planar 4-state UKF of Wang et al. (2018) (eqs. (11)–(14)).
    Ukf2d { name: "ukf2d", run: planar(Ukf), takes: [Ranges], smoothing: Never },
    /// The planar errors-complementary EKF of Wang et al. (2018), eqs. (15)–(18).
    ///
    /// Ranges pass through a moving average first.
    Cekf2d { name: "cekf2d", run: planar(Cekf), takes: [Ranges], smoothing: Never },
    /// The recommended method for real logs (ours), smoothed unless a forward pass is asked for.
    ///
    /// RIEKF with its range test skewed against long ranges and the zero-velocity constraint while
    /// still ([`uwbimu_estimation::filters::Best`]), re-acquisition on divergence and
    /// self-initialisation when no initial state is given. Before it runs it chooses its
    /// range-error model, NLOS skew and range noise on the log by held-out anchors
    /// ([`crate::select`]).
    Best { name: "best", run: inertial(Best), takes: [Ranges, Tags, Tdoa, Altitude, Odometry], smoothing: ByDefault, chooses_model: true },
}

impl Method {
    /// The method's name.
    pub fn name(self) -> &'static str {
        self.info().name
    }

    /// The first line of the method's doc: one sentence that says what it is (every row's doc
    /// starts with one; `tests::every_summary_is_a_sentence`).
    pub fn summary(self) -> &'static str {
        self.info().doc.lines().next().unwrap_or_default().trim()
    }

    /// Every method name, in registry order.
    pub fn names() -> impl Iterator<Item = &'static str> {
        Self::ALL.iter().map(|m| m.name())
    }

    /// Whether the method's run can be RTS-smoothed: the inertial 15-state filters (not
    /// `uwb_ls` and the planar filters).
    pub fn smoothable(self) -> bool {
        self.info().smoothing != Smoothing::Never
    }

    /// Whether the batch API smooths the method's run when the caller does not say (`best`).
    pub fn smooths_by_default(self) -> bool {
        self.info().smoothing == Smoothing::ByDefault
    }

    /// Whether to smooth: as `asked`, else the method's default ([`Method::smooths_by_default`]).
    pub fn smooth(self, asked: Option<bool>) -> bool {
        asked.unwrap_or(self.smooths_by_default())
    }

    /// Whether the batch method chooses its range-error model, NLOS skew and range noise on the
    /// log ([`crate::select`]; its registry row).
    pub fn chooses_its_model(self) -> bool {
        self.info().chooses_model
    }

    /// Whether the method takes `input`.
    pub fn takes(self, input: Input) -> bool {
        self.info().takes.contains(&input)
    }

    /// Whether the method takes TDoA (the tightly coupled inertial filters; the loosely coupled
    /// ones fuse a per-epoch fix from ranges, the planar ones and `uwb_ls` take ranges only).
    pub fn takes_tdoa(self) -> bool {
        self.takes(Input::Sensor(SensorKind::Tdoa))
    }

    /// The names of the methods for which `keep` holds, comma-separated (for error messages).
    pub fn names_where(keep: impl Fn(Self) -> bool) -> String {
        Self::ALL.iter().filter(|m| keep(**m)).map(|m| m.name()).collect::<Vec<_>>().join(", ")
    }

    /// Parses a method name; the error lists the allowed names.
    pub fn parse(name: &str) -> Result<Self> {
        Self::ALL
            .iter()
            .copied()
            .find(|m| m.name() == name)
            .ok_or_else(|| Error::unknown_option("method", name, Self::ALL.iter().map(|m| m.name())))
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
        /// What the unit check of the IMU found suspicious ([`check_imu_units`]).
        warnings: Vec<String>,
        /// The model the method chose on the log ([`crate::select`]; `best` with
        /// `model_selection.enabled`), None for the others.
        model: Option<Box<ModelChoice>>,
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
    /// Initial state (None: self-initialisation, [`uwbimu_estimation::init`]).
    pub initial: Option<&'a InitialState>,
    /// Filter settings.
    pub config: &'a FilterConfig,
    /// Also RTS-smooth the run (inertial filters only).
    pub smooth: bool,
    /// The measurements of the other sensors of the registry (TDoA, magnetometer, ...), validated
    /// and merged in time order ([`uwbimu_vocabulary::sensors::merge`]); each kind must be one the
    /// method takes.
    pub observations: &'a [Observation],
    /// Counts the IMU samples the run has processed and marks its smoothing pass, for a progress
    /// bar on another thread (None: not counted).
    pub progress: Option<&'a Progress>,
    /// Sample the forward estimate with the covariance of its position, velocity and attitude
    /// errors into the trace every this many seconds ([`Trace::marginals`]; None: not sampled),
    /// for consistency checks ([`crate::consistency`]).
    pub marginals_every_s: Option<f64>,
}

/// Runs `method` over one recording. A non-empty `config.range_calibration` (Wang et al. 2018 §2.2) and a
/// non-zero `ranging.time_offset_s` are applied to the measurements first, for every method.
pub fn run_method(method: Method, input: &BatchInput<'_>) -> Result<BatchOutput> {
    check_inputs(method, false, input.observations.iter().map(Observation::kind))?;
    let tagged = input.ranges.iter().enumerate().filter(|(_, r)| r.tag != 0);
    check_tags(method, input.config, tagged.map(|(row, r)| (format!("ranges row {row}"), r.tag)))?;
    let offset = input.config.ranging.time_offset_s;
    if offset != 0.0 {
        let span = |t: f64| input.imu.first().is_some_and(|a| t >= a.t_s) && input.imu.last().is_some_and(|b| t <= b.t_s);
        let shift = |t: f64| Some(t + offset).filter(|&t| span(t));
        let ranges: Vec<_> = input.ranges.iter().filter_map(|r| shift(r.t_s).map(|t_s| RangeMeasurement { t_s, ..*r })).collect();
        let shifted: Vec<Observation> = input
            .observations
            .iter()
            .filter_map(|o| match o.kind().info().clock {
                Clock::Uwb => shift(o.t_s()).map(|t_s| o.at(t_s)),
                Clock::Imu => Some(*o),
            })
            .collect();
        let observations = merge(&[&shifted]);
        let mut config = input.config.clone();
        config.ranging.time_offset_s = 0.0;
        return run_method(method, &BatchInput { ranges: &ranges, observations: &observations, config: &config, ..*input });
    }
    if !input.config.range_calibration.is_empty() {
        let calibrated = input.config.range_calibration.apply(input.ranges, input.anchors.len())?;
        return run_calibrated(method, &BatchInput { ranges: &calibrated, ..*input });
    }
    run_calibrated(method, input)
}

/// Runs `method` on measurements already calibrated; a method that chooses its model
/// ([`Method::chooses_its_model`]) first chooses it ([`crate::select::choose`]) unless
/// `model_selection.enabled` is off, and runs with the choice (with the input configuration when
/// the selection fails, saying why in the reported choice).
pub(crate) fn run_calibrated(method: Method, input: &BatchInput<'_>) -> Result<BatchOutput> {
    check_inputs(method, input.smooth, [])?;
    if !(method.chooses_its_model() && input.config.model_selection.enabled) {
        return dispatch(method, input);
    }
    let choice = choose_or_keep(method, input);
    let mut output = dispatch(method, &BatchInput { config: &choice.config, ..*input })?;
    if let BatchOutput::Inertial { model, .. } = &mut output {
        *model = Some(Box::new(choice));
    }
    Ok(output)
}

/// Fails when `method` is asked to smooth and cannot, or is given measurements of a sensor
/// (`kinds`, one per measurement or per sensor) it does not take; the message lists the methods
/// that can.
pub(crate) fn check_inputs(method: Method, smooth: bool, kinds: impl IntoIterator<Item = SensorKind>) -> Result<()> {
    if let Some(kind) = kinds.into_iter().find(|k| !method.takes(Input::Sensor(*k))) {
        let label = kind.info().label;
        return Err(Error::InvalidCall(format!(
            "{label} given, but {} does not take {label} (these do: {})",
            method.name(),
            Method::names_where(|m| m.takes(Input::Sensor(kind)))
        )));
    }
    if smooth && !method.smoothable() {
        return Err(Error::unknown_option(
            "smoothing method",
            method.name(),
            Method::ALL.iter().filter(|m| m.smoothable()).map(|m| m.name()),
        ));
    }
    Ok(())
}

/// Refuses ranges from a tag the configuration gives no lever arm for, and ranges from several
/// tags for a method that fuses one; `tagged` gives the tags beyond 0 with where they are
/// ("ranges row 12"), and the message says where and what to do.
pub(crate) fn check_tags(method: Method, config: &FilterConfig, tagged: impl IntoIterator<Item = (String, usize)>) -> Result<()> {
    let tags = config.mounting.lever_arm.tags();
    for (place, tag) in tagged {
        if tag >= tags {
            return Err(Error::InvalidCall(format!(
                "{place} is from tag {tag}, but mounting.lever_arm gives {tags} tag(s): give one [x, y, z] per tag, tag 0 first"
            )));
        }
        if tag != 0 && !method.takes(Input::Tags) {
            return Err(Error::InvalidCall(format!(
                "ranges from tag {tag}, but {} fuses one tag (these fuse several: {})",
                method.name(),
                Method::names_where(|m| m.takes(Input::Tags))
            )));
        }
    }
    Ok(())
}

/// The model `method` chooses on `input` ([`crate::select::choose`]); on a log the selection
/// cannot score (no self-initialisation in its window, a failing fold) the input configuration,
/// saying why: choosing never costs a run.
pub(crate) fn choose_or_keep(method: Method, input: &BatchInput<'_>) -> ModelChoice {
    crate::select::choose(method, input).unwrap_or_else(|e| {
        let mut config = input.config.clone();
        config.model_selection.enabled = false;
        ModelChoice { config, candidates: Vec::new(), chosen: 0, reason: format!("no selection: {e}") }
    })
}

/// Runs `method` over many recordings, in parallel on all cores with the `parallel` feature
/// (rayon), else one after the other; one result per input, in order.
pub fn run_many(method: Method, inputs: &[BatchInput<'_>]) -> Vec<Result<BatchOutput>> {
    crate::parallel::map_all(inputs, |input| run_method(method, input))
}

/// The ranges of `input` that pass the plausibility gate ([`Gate`]): `uwb_ls` does not run the
/// pipeline, whose gate the other methods pass.
fn plausible_ranges(input: &BatchInput<'_>) -> Vec<RangeMeasurement> {
    let gate = Gate::new(input.anchors, &input.config.gate);
    input.ranges.iter().filter(|r| gate.check(&Event::Range(**r)).is_none()).copied().collect()
}

/// The given initial state, or the self-initialisation's ([`self_initialize`]: the decision a
/// self-initialising streaming filter reaches on the same data).
pub(crate) fn initial_state(input: &BatchInput<'_>) -> Result<(InitialState, Option<Box<SelfInit>>)> {
    Ok(match input.initial {
        Some(i) => (i.clone(), None),
        None => {
            let s = self_initialize(&input.streams(), input.anchors, input.config)?;
            (s.initial.clone(), Some(Box::new(s)))
        }
    })
}

impl BatchInput<'_> {
    /// The input streams (IMU, ranges, the other sensors).
    pub fn streams(&self) -> Streams<'_> {
        Streams {
            imu: self.imu,
            ranges: self.ranges,
            observations: self.observations,
            progress: self.progress,
            marginals_every_s: self.marginals_every_s,
        }
    }
}

/// Runs a planar filter of Wang et al. 2018 (initialised like the inertial filters: x, y, velocity, yaw
/// and gyro bias from the initial state).
fn run_planar(kind: PlanarKind, input: &BatchInput<'_>) -> Result<BatchOutput> {
    let warnings = check_imu_units(input.imu, input.config.gate.refuse_unit_slips)?;
    let (initial, init) = initial_state(input)?;
    let mut filter = PlanarFilter::new(kind, input.anchors.to_vec(), &initial, input.config)?;
    let trace = run_streams(&mut filter, &Streams { observations: &[], ..input.streams() })?;
    Ok(BatchOutput::Inertial { trace, init, smoothed: None, warnings, model: None })
}

/// Initialises (unless `initial` is given), builds the filter with `build` and runs the pipeline.
/// A smoothed run whose filter runs with `smoothing.outlier_passes` > 0 then leaves out the ranges
/// its smoothed track calls NLOS and runs again (initialised as a log without them would be),
/// until no range is added or the passes are spent ([`crate::outlier_smoothing`]); it returns
/// the last complete pass (the one before, if a log without them cannot start), with the ranges
/// left out counted in its health.
fn run_inertial<F: InertialFilter>(build: impl Fn(&InitialState) -> Result<F>, input: &BatchInput<'_>) -> Result<BatchOutput> {
    let warnings = check_imu_units(input.imu, input.config.gate.refuse_unit_slips)?;
    let (initial, init) = initial_state(input)?;
    let (trace, smoothed, smoothing) = run_pass(&build, &initial, input)?;
    let quiet = input.progress.map(Progress::sharing_cancel);
    let residuals = |(_, smoothed, _): &mut SmoothedPass| {
        Ok(smoothed.as_deref().map(|steps| {
            let mut walk = ResidualWalk::new(input.ranges, input.anchors, input.config.mounting.lever_arm);
            steps.iter().for_each(|s| walk.push(s));
            walk.finish()
        }))
    };
    let again = |left_out: &[bool]| {
        let kept: Vec<RangeMeasurement> = input.ranges.iter().zip(left_out).filter(|(_, out)| !**out).map(|(r, _)| *r).collect();
        let again_input = BatchInput { ranges: &kept, progress: quiet.as_ref(), ..*input };
        // A log that cannot start without the ranges left out keeps the pass before.
        let rerun = initial_state(&again_input)
            .and_then(|(initial, init)| run_pass(&build, &initial, &again_input).map(|pass| (pass, init)));
        let ((trace, smoothed, _), init) = match rerun {
            Err(Error::InsufficientData(_)) => return Ok(None),
            other => other?,
        };
        let complete = smoothed.is_some() && !quiet.as_ref().is_some_and(Progress::cancelled);
        Ok(complete.then_some((trace, smoothed, init)))
    };
    let passes = smoothing.outlier_passes_or_zero();
    let ((mut trace, smoothed, init), left_out) =
        leave_out_long_ranges((trace, smoothed, init), passes, input.ranges, smoothing.outlier_sigmas, residuals, again)?;
    trace.health.smoothing_left_out = left_out;
    Ok(BatchOutput::Inertial { trace, init, smoothed, warnings, model: None })
}

/// A complete pass of [`run_inertial`]: the forward trace, its RTS-smoothed steps (None when the
/// run was not smoothed) and the self-initialisation it started from.
type SmoothedPass = (Trace, Option<Vec<StepRecord>>, Option<Box<SelfInit>>);

/// One pass of [`run_inertial`] from `initial`: the forward run, its RTS-smoothed steps when
/// smoothing was asked for (None when the run was cancelled), and the smoothing settings the
/// filter runs with (its composition's where the configuration leaves them unset).
fn run_pass<F: InertialFilter>(
    build: &impl Fn(&InitialState) -> Result<F>,
    initial: &InitialState,
    input: &BatchInput<'_>,
) -> Result<(Trace, Option<Vec<StepRecord>>, SmoothingConfig)> {
    let BatchInput { imu, ranges, smooth, observations, progress, .. } = *input;
    let mut filter = build(initial)?;
    if smooth {
        filter.core_mut().start_recording(imu.len() + ranges.len() + observations.len());
    }
    let trace = run_streams(&mut filter, &input.streams())?;
    // A cancelled run keeps its forward steps so far; it is not smoothed.
    let cancelled = || progress.is_some_and(Progress::cancelled);
    let smoothed = if smooth && !cancelled() {
        if let Some(p) = progress {
            p.start_smoothing();
        }
        match smoothed_steps(&trace, filter.core(), progress) {
            Err(Error::Interrupted { .. }) => None,
            other => Some(other?),
        }
    } else {
        None
    };
    Ok((trace, smoothed, filter.config().smoothing))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for name in Method::names() {
            assert_eq!(Method::parse(name).map(Method::name), Ok(name));
        }
        assert!(matches!(Method::parse("rieks"), Err(Error::UnknownOption { .. })));
        let e = Method::parse("rekff").unwrap_err().to_string();
        assert!(e.starts_with("unknown method `rekff` (did you mean `rekf`"), "{e}");
    }

    #[test]
    fn every_summary_is_a_sentence() {
        for m in Method::ALL {
            let s = m.summary();
            assert!(s.len() > 20 && s.ends_with('.') && s.chars().next().is_some_and(char::is_uppercase), "{s}");
        }
    }

    #[test]
    fn capabilities_follow_the_rows() {
        assert_eq!(Method::names_where(Method::smooths_by_default), "best");
        assert_eq!(Method::names_where(|m| m.takes(Input::Sensor(SensorKind::Magnetometer))), "ackf");
        assert!(!Method::UwbLs.smoothable() && !Method::Ekf2d.takes_tdoa() && Method::Best.takes_tdoa());
        // A method streams exactly when it runs a 15-state filter (the smoothable ones).
        assert!(Method::ALL.iter().all(|m| m.info().streaming_class.is_some() == m.smoothable()));
    }
}
