//! The named methods of the batch API and the function that runs one of them over whole arrays:
//! [`run_method`] applies the range time offset and calibration of the configuration, lets a
//! method that chooses its model choose it ([`crate::select`]) and runs it; [`run_many`] runs many
//! recordings. The registry of the methods (`registry.rs`: [`Method`], [`Run`], [`Input`],
//! [`MethodInfo`], [`Smoothing`]) and the runner under these functions (`run.rs`: [`BatchInput`],
//! [`BatchOutput`], the dispatch to the filters) are private modules of their own, below the model
//! selection that `run_method` calls; this module is their public path.

use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::sensors::{merge, Observation};

use crate::model_choice::ModelChoice;
pub use crate::registry::{Input, Method, MethodInfo, Run, Smoothing, DEFAULT_METHOD};
use crate::run::run_batch;
pub use crate::run::{BatchInput, BatchOutput};
use crate::uwb_clock::UwbClock;

/// Runs `method` over one recording. A non-empty `config.range_calibration` (Wang et al. 2018 §2.2) and a
/// non-zero `ranging.time_offset_s` are applied to the measurements first, for every method; then
/// the run takes the one sequence of a run (`runner::run_log`), in which a method that
/// chooses its model ([`Method::chooses_its_model`]) chooses it (`choose_or_keep`) unless
/// `model_selection.enabled` is off.
pub fn run_method(method: Method, input: &BatchInput<'_>) -> Result<BatchOutput> {
    let config = input.config;
    if config.ranging.time_offset_s == 0.0 && config.range_calibration.is_empty() {
        return run_batch(method, input, Some(choose_or_keep));
    }
    config.range_calibration.check_anchors(input.anchors.len())?;
    let mut clock = UwbClock::new(config, input.imu.first().zip(input.imu.last()).map(|(a, b)| (a.t_s, b.t_s)));
    let ranges = input.ranges.iter().filter_map(|r| clock.range(r).transpose()).collect::<Result<Vec<_>>>()?;
    let shifted: Vec<Observation>;
    let observations = if clock.offset_s() == 0.0 {
        input.observations
    } else {
        shifted = merge(&[&input.observations.iter().filter_map(|o| clock.observation(o)).collect::<Vec<_>>()]);
        &shifted
    };
    let mut config = config.clone();
    config.ranging.time_offset_s = 0.0;
    run_batch(method, &BatchInput { ranges: &ranges, observations, config: &config, ..*input }, Some(choose_or_keep))
}

/// The model `method` chooses on `input` ([`crate::select::choose`]); on a log the selection
/// cannot score (no self-initialisation in its window, a failing fold) the input configuration,
/// saying why: choosing never costs a run.
pub(crate) fn choose_or_keep(method: Method, input: &BatchInput<'_>) -> ModelChoice {
    crate::select::choose(method, input).unwrap_or_else(|e| ModelChoice::kept(input.config, e))
}

/// Runs `method` over many recordings, in parallel on all cores with the `parallel` feature
/// (rayon), else one after the other; one result per input, in order.
pub fn run_many(method: Method, inputs: &[BatchInput<'_>]) -> Vec<Result<BatchOutput>> {
    crate::parallel::map_all(inputs, |input| run_method(method, input))
}
