//! The batch order of a streamed replay's events: the range time offset and calibration of the
//! configuration applied as they arrive ([`UwbClock`], as the batch runner applies them), then a
//! heap that releases each event once no later input can come before it.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use uwbimu_estimation::pipeline::Event;
use uwbimu_io::IoResult as Result;
use uwbimu_vocabulary::config::FilterConfig;

use crate::uwb_clock::UwbClock;

/// Puts the events of the reader (in time order) into the batch order after the range time
/// offset: an event is released once no later input can come before it, i.e. once an input
/// `|offset|` newer than it has arrived ([`Event::rank`] breaks ties as the batch merge does).
/// Shifted measurements outside the IMU span are dropped, as the batch run drops them, and so is
/// everything after the last IMU sample.
pub(super) struct Ordered<'c> {
    heap: BinaryHeap<Reverse<Held>>,
    clock: UwbClock<'c>,
    imu_end_s: f64,
    newest_s: f64,
    arrivals: u64,
}

struct Held {
    t_s: f64,
    rank: u8,
    arrival: u64,
    event: Event,
}

impl Held {
    fn key(&self) -> (f64, u8, u64) {
        (self.t_s, self.rank, self.arrival)
    }
}

impl PartialEq for Held {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == std::cmp::Ordering::Equal
    }
}
impl Eq for Held {}
impl PartialOrd for Held {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Held {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        let (a, b) = (self.key(), other.key());
        a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2))
    }
}

impl<'c> Ordered<'c> {
    pub(super) fn new(config: &'c FilterConfig, imu_span_s: (f64, f64)) -> Self {
        Self {
            heap: BinaryHeap::new(),
            clock: UwbClock::new(config, Some(imu_span_s)),
            imu_end_s: imu_span_s.1,
            newest_s: f64::NEG_INFINITY,
            arrivals: 0,
        }
    }

    /// Takes the reader's next event (at its own time `t_s`), then releases what it can into `out`.
    pub(super) fn push(&mut self, event: Event, out: &mut Vec<Event>) -> Result<()> {
        self.newest_s = self.newest_s.max(event.t_s());
        let shifted = match event {
            Event::Imu(_) => Some(event),
            Event::Range(r) => self.clock.range(&r)?.map(Event::Range),
            Event::Observation(o) => self.clock.observation(&o).map(Event::Observation),
        };
        if let Some(event) = shifted.filter(|e| e.t_s() <= self.imu_end_s) {
            self.arrivals += 1;
            self.heap.push(Reverse(Held { t_s: event.t_s(), rank: event.rank(), arrival: self.arrivals, event }));
        }
        self.release(self.newest_s - self.clock.offset_s().abs(), out);
        Ok(())
    }

    /// Releases the events before `bound_s` (all with +∞) in order into `out`.
    pub(super) fn release(&mut self, bound_s: f64, out: &mut Vec<Event>) {
        while self.heap.peek().is_some_and(|h| h.0.t_s < bound_s) {
            if let Some(Reverse(h)) = self.heap.pop() {
                out.push(h.event);
            }
        }
    }
}
