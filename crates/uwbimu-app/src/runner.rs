//! The sequence of a run, written once ([`run_log`]): check what the method is given, let a
//! method that chooses its model choose it, run the first pass (from the given initial state or
//! self-initialised, smoothed when asked), then the passes after the first
//! ([`after_first_pass`]: outlier passes, then MAP passes) and record what they did. Where the
//! log comes from and where the passes are kept is the runner's ([`LogRunner`]): whole arrays in
//! memory for the batch API (`crate::run`), or the file read again with the steps spilled to
//! disk for the streamed replay (`crate::replay::streamed`). The filter a runner builds is named
//! by a [`FilterKind`], the same for both.

use std::ops::Deref;
use std::sync::Arc;

use uwbimu_estimation::filters::{InertialCore, NamedFilter};
use uwbimu_estimation::planar::{PlanarFilter, PlanarKind};
use uwbimu_estimation::smoother::Guide;
use uwbimu_vocabulary::config::{FilterConfig, InitialState, SmoothingConfig};
use uwbimu_vocabulary::error::{Error, Result as CoreResult};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::RangeMeasurement;
use uwbimu_vocabulary::sensors::SensorKind;

use crate::model_choice::ModelChoice;
use crate::registry::{Input, Method};
use crate::smoothing_passes::{after_first_pass, AfterFirstPass, PassRunner};

/// How one kind of run reads its log and keeps its passes, step by step, for [`run_log`]; the
/// passes after the first are its [`PassRunner`] part.
pub(crate) trait LogRunner: PassRunner {
    /// The ranges of the first pass, in stream order, as the passes after it index them.
    type Ranges: Deref<Target = [RangeMeasurement]>;

    /// The configuration the run is given (before any model choice).
    fn given_config(&self) -> &FilterConfig;

    /// Fails when `method` is given what it does not take ([`check_inputs`], [`check_tags`]) or a
    /// log it cannot run.
    fn check(&self, method: Method) -> Result<(), Self::Error>;

    /// The model `method` chooses on the first `model_selection.window_s` of the log
    /// ([`crate::model_window::ModelWindow`]); the configuration as given, saying why, when the
    /// log cannot be scored; None when this runner does not choose (a candidate of the model
    /// selection runs as configured).
    fn choose(&mut self, method: Method) -> Result<Option<ModelChoice>, Self::Error>;

    /// The first pass with the configuration of `model` (None: the one given), from the given
    /// initial state or self-initialised, RTS-smoothed when the run is.
    fn first_pass(&mut self, model: Option<ModelChoice>) -> Result<Self::Pass, Self::Error>;

    /// What the passes after `first` need — the ranges of the run and the smoothing settings its
    /// filter runs with (its composition's where the configuration leaves them unset) — or None
    /// when there are none: the run is not smoothed, or its filter has nothing to smooth.
    fn later_passes(&mut self, first: &mut Self::Pass) -> Result<Option<(Self::Ranges, SmoothingConfig)>, Self::Error>;

    /// The last pass kept, with what the passes after the first did recorded in its health.
    fn keep(&mut self, done: AfterFirstPass<Self::Pass>) -> Self::Pass;
}

/// Runs `method` through `runner` in the one order every runner takes: check, choose the model
/// (when the method chooses its model with `model_selection.enabled`), the first pass, the
/// passes after it. Returns the last pass kept.
///
/// # Errors
/// The runner's, as each step gives them.
pub(crate) fn run_log<R: LogRunner>(method: Method, runner: &mut R) -> Result<R::Pass, R::Error> {
    runner.check(method)?;
    let chooses = method.chooses_its_model() && runner.given_config().model_selection.enabled;
    let model = if chooses { runner.choose(method)? } else { None };
    let mut first = runner.first_pass(model)?;
    let Some((ranges, smoothing)) = runner.later_passes(&mut first)? else { return Ok(first) };
    let done = after_first_pass(runner, first, &ranges, &smoothing)?;
    Ok(runner.keep(done))
}

/// Fails when `method` is asked to smooth and cannot, or is given measurements of a sensor
/// (`kinds`, one per measurement or per sensor) it does not take; the message lists the methods
/// that can.
pub(crate) fn check_inputs(method: Method, smooth: bool, kinds: impl IntoIterator<Item = SensorKind>) -> CoreResult<()> {
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
pub(crate) fn check_tags(
    method: Method,
    config: &FilterConfig,
    tagged: impl IntoIterator<Item = (String, usize)>,
) -> CoreResult<()> {
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

/// Builds a run's filter for the anchors, from the initial state, with the configuration.
pub(crate) type BuildFilter<E> = Arc<dyn Fn(Vec<Vec3>, &InitialState, FilterConfig) -> CoreResult<E> + Send + Sync>;

/// The filter of a run: how to build it and what of it the runners use, the inertial filters'
/// INS core and configuration (None for the planar filters, which have nothing to smooth).
pub(crate) struct FilterKind<E> {
    /// Builds the filter.
    pub build: BuildFilter<E>,
    /// Its INS core, to record and smooth.
    pub core: fn(&mut E) -> Option<&mut InertialCore>,
    /// The configuration it runs with (its composition's settings filled in where the given one
    /// leaves them unset).
    pub config: fn(&E) -> Option<&FilterConfig>,
    /// Guides it in a pass of the MAP smoother; false when it takes no guide
    /// ([`uwbimu_estimation::filters::InertialFilter::set_guide`]).
    pub guide: fn(&mut E, Option<Arc<Guide>>) -> bool,
}

impl<F: NamedFilter> FilterKind<F> {
    /// The inertial filter `F`.
    pub(crate) fn inertial() -> Self {
        Self {
            build: Arc::new(F::build),
            core: |f: &mut F| Some(f.core_mut()),
            config: |f: &F| Some(f.config()),
            guide: |f: &mut F, g| f.set_guide(g),
        }
    }
}

impl FilterKind<PlanarFilter> {
    /// The planar filter of `kind` (Wang et al. 2018).
    pub(crate) fn planar(kind: PlanarKind) -> Self {
        Self {
            build: Arc::new(move |anchors, initial: &InitialState, config: FilterConfig| {
                PlanarFilter::new(kind, anchors, initial, &config)
            }),
            core: |_: &mut PlanarFilter| None,
            config: |_: &PlanarFilter| None,
            guide: |_: &mut PlanarFilter, _| false,
        }
    }
}
