//! The one time-ordered loop over [`Event`]s — IMU samples, ranges and observations (magnetometer
//! samples, TDoA) — shared by the batch API, the CLI and the streaming classes (which drive the
//! same [`Pipeline`] call for call, so streaming equals batch bit for bit).
//!
//! Events are taken in time order. An IMU sample is predicted at once; an observation is applied
//! at its own time ([`crate::filters::Filter::observe`]). Ranges are gathered into epochs
//! by the epoch rule of
//! [`crate::epoch`]; an epoch is applied jointly when it closes — when it holds every anchor, when
//! a range does not fit it, or when an IMU sample passes its window — at the reference time
//! `max(time of its last range, filter time)`, each range first aligned to that time along its
//! predicted rate ([`crate::epoch::align_to_reference`]). The batch merges its streams by time
//! ([`run_streams`]); at equal times the IMU sample goes first, then the other sensors in the
//! order of their rank in the registry ([`uwbimu_vocabulary::sensors`]), ranges last; a step is recorded after every IMU sample and the events at its time. Ranges
//! before the first IMU sample are counted and skipped, observations before it skipped (the
//! filter has no time yet); events after the last IMU sample are not applied.
//!
//! Every event passes the plausibility gate first ([`crate::gate`]): what it rejects is counted
//! in [`Health`] and flagged in the next step's [`StepRecord::status`]; a rejected IMU sample
//! still has its step, propagated with the last sample held, so a run records one step per IMU
//! sample from its first accepted one on. A numerical failure in a
//! step (an innovation variance or a factorisation that is not positive definite, a state or
//! covariance that is no longer finite) never ends a run: the state and covariance from before
//! the step are put back, the covariance repaired ([`crate::repair`]), the measurement skipped and
//! the repair counted and flagged. [`Stream`] adds what a robot loop needs: late data put back in
//! order within a window, and self-initialisation on the data as it arrives; [`FixedLag`] the
//! estimate smoothed over the last seconds of the run, in bounded memory.

mod batch;
mod estimator;
mod event;
mod event_loop;
mod fixed_lag;
mod marginals;
mod progress;
mod records;
mod smoothing;
mod stream;
mod tally;

pub use batch::{run, run_streams, Streams};
pub use estimator::Estimator;
pub use event::Event;
pub use event_loop::Pipeline;
pub use fixed_lag::{FixedLag, FIXED_LAG_BLOCK_FRACTION};
pub use marginals::Marginals;
pub use progress::Progress;
pub use records::{
    Health, MapObjective, Measured, StepRecord, Trace, UpdateRecord, STATUS_LATE, STATUS_REJECTED, STATUS_REPAIRED,
};
pub use smoothing::{run_smoothed, smooth_recording, smoothed_nodes, smoothed_steps};
pub use stream::{self_initialize, Builder, Stream, StreamOptions};
