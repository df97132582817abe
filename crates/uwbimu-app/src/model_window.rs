//! The events a method that chooses its model ([`Method::chooses_its_model`]) keeps from the
//! start of its input, and the choice on them ([`ModelWindow::choose`]): the choice the batch run
//! makes on the same events as arrays ([`crate::methods::choose_or_keep`]). The streamed replay
//! (`replay::streamed`) keeps its first `model_selection.window_s` here, the streaming choice
//! ([`crate::streaming_choice`]) its first `choose_after_s`.

use uwbimu_estimation::pipeline::Event;
use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::sensors::{merge, Observation};

use crate::methods::{choose_or_keep, BatchInput, Method};
use crate::model_choice::ModelChoice;

/// Events of every kind (IMU samples, ranges of every tag, the other sensors' observations) in
/// the order they were kept.
#[derive(Debug, Clone, Default)]
pub(crate) struct ModelWindow {
    events: Vec<Event>,
}

impl ModelWindow {
    /// Keeps `event` after the others.
    pub(crate) fn push(&mut self, event: Event) {
        self.events.push(event);
    }

    /// The kept events, in the order they were kept.
    pub(crate) fn events(&self) -> &[Event] {
        &self.events
    }

    /// The model `method` chooses on the kept events with `anchors`, `initial` (None:
    /// self-initialisation) and `config`: [`choose_or_keep`] on them as the arrays of a batch run,
    /// each kind in time order (at equal times in the order kept; the observations by sensor
    /// rank, [`merge`]). It never fails: a window the selection cannot score keeps `config` and
    /// says why.
    pub(crate) fn choose(
        &self,
        method: Method,
        anchors: &[Vec3],
        initial: Option<&InitialState>,
        config: &FilterConfig,
    ) -> ModelChoice {
        let (mut imu, mut ranges, mut observations) = (Vec::<ImuSample>::new(), Vec::<RangeMeasurement>::new(), Vec::new());
        for e in &self.events {
            match e {
                Event::Imu(s) => imu.push(*s),
                Event::Range(r) => ranges.push(*r),
                Event::Observation(o) => observations.push(*o),
            }
        }
        // Stable sorts: the order of arrival where it is already the time order (the streamed
        // replay's window, which keeps the events in the batch order) stays as it is.
        imu.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        ranges.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        let observations: Vec<Observation> = merge(&[&observations]);
        let batch = BatchInput {
            imu: &imu,
            ranges: &ranges,
            anchors,
            initial,
            config,
            smooth: false,
            observations: &observations,
            progress: None,
            marginals_every_s: None,
        };
        choose_or_keep(method, &batch)
    }
}
