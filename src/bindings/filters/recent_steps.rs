//! The newest steps of a streaming filter ([`RecentSteps`]), which its `steps()` returns as the
//! frame `run_filter` would.

use std::collections::VecDeque;

use uwbimu_estimation::pipeline::{Estimator, StepRecord, Stream};

/// At most `capacity` of the newest [`StepRecord`]s of a stream, the oldest dropped (and counted)
/// beyond it; none recorded with a capacity of 0. The records move in after every call that
/// feeds the stream ([`RecentSteps::collect`]) and out with [`RecentSteps::take`], so the memory
/// stays bounded however long the stream runs.
#[derive(Debug, Default)]
pub(super) struct RecentSteps {
    kept: VecDeque<StepRecord>,
    capacity: usize,
    incoming: Vec<StepRecord>,
    dropped: u64,
}

impl RecentSteps {
    /// Keeps up to `capacity` steps, none with a capacity of 0: moved in from a stream that
    /// records them ([`Stream::record_steps`], [`RecentSteps::collect`]) or given
    /// ([`RecentSteps::keep`], a stream's fixed-lag rows).
    pub(super) fn new(capacity: usize) -> Self {
        Self { kept: VecDeque::new(), capacity, incoming: Vec::new(), dropped: 0 }
    }

    /// Moves the steps `stream` recorded since the last call in, dropping the oldest beyond the
    /// capacity.
    pub(super) fn collect<E: Estimator>(&mut self, stream: &mut Stream<E>) {
        if self.capacity == 0 {
            return;
        }
        stream.move_steps(&mut self.incoming);
        self.keep_incoming();
    }

    /// Moves `steps` in (leaving it empty), dropping the oldest beyond the capacity.
    pub(super) fn keep(&mut self, steps: &mut Vec<StepRecord>) {
        std::mem::swap(&mut self.incoming, steps);
        self.keep_incoming();
        std::mem::swap(&mut self.incoming, steps);
    }

    fn keep_incoming(&mut self) {
        if self.capacity == 0 {
            self.incoming.clear();
            return;
        }
        for step in self.incoming.drain(..) {
            if self.kept.len() == self.capacity {
                self.kept.pop_front();
                self.dropped += 1;
            }
            self.kept.push_back(step);
        }
    }

    /// The kept steps, oldest first, leaving none.
    pub(super) fn take(&mut self) -> Vec<StepRecord> {
        self.kept.drain(..).collect()
    }

    /// Steps dropped so far because `take` came too late for the capacity.
    pub(super) fn dropped(&self) -> u64 {
        self.dropped
    }
}
