//! Bounded reorder window: merges items arriving roughly in time order into one strictly
//! time-ordered stream. An item is held until an item `window_ns` newer has arrived; an item
//! older than what was already released is counted as late and dropped, never used out of order.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// A heap entry ordered by (time, arrival number) only.
struct Entry<T> {
    t_ns: i64,
    seq: u64,
    item: T,
}

impl<T> PartialEq for Entry<T> {
    fn eq(&self, other: &Self) -> bool {
        (self.t_ns, self.seq) == (other.t_ns, other.seq)
    }
}
impl<T> Eq for Entry<T> {}
impl<T> PartialOrd for Entry<T> {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl<T> Ord for Entry<T> {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.t_ns, self.seq).cmp(&(other.t_ns, other.seq))
    }
}

/// The reorder buffer.
pub struct ReorderBuffer<T> {
    window_ns: i64,
    heap: BinaryHeap<Reverse<Entry<T>>>,
    newest_ns: i64,
    released_ns: i64,
    seq: u64,
    /// Items that arrived more than the window behind and were dropped.
    pub late: usize,
    /// Items that arrived out of order but within the window (put back in order).
    pub reordered: usize,
}

impl<T> ReorderBuffer<T> {
    /// A buffer holding items for `window_ns` nanoseconds.
    pub fn new(window_ns: i64) -> Self {
        Self { window_ns, heap: BinaryHeap::new(), newest_ns: i64::MIN, released_ns: i64::MIN, seq: 0, late: 0, reordered: 0 }
    }

    /// Adds an item stamped `t_ns`; calls `emit` for every item that is now older than the window.
    pub fn push(&mut self, t_ns: i64, item: T, mut emit: impl FnMut(i64, T)) {
        if t_ns < self.released_ns {
            self.late += 1;
            return;
        }
        if t_ns < self.newest_ns {
            self.reordered += 1;
        }
        self.newest_ns = self.newest_ns.max(t_ns);
        self.heap.push(Reverse(Entry { t_ns, seq: self.seq, item }));
        self.seq += 1;
        let horizon = self.newest_ns.saturating_sub(self.window_ns);
        while self.heap.peek().is_some_and(|e| e.0.t_ns < horizon) {
            if let Some(Reverse(e)) = self.heap.pop() {
                self.released_ns = e.t_ns;
                emit(e.t_ns, e.item);
            }
        }
    }

    /// Releases everything still held, in order.
    pub fn finish(&mut self, mut emit: impl FnMut(i64, T)) {
        while let Some(Reverse(e)) = self.heap.pop() {
            self.released_ns = e.t_ns;
            emit(e.t_ns, e.item);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reorders_inside_the_window_and_drops_late_items() {
        let mut b = ReorderBuffer::new(10);
        let mut out = Vec::new();
        for t in [0, 5, 3, 20, 12, 40, 1, 35] {
            b.push(t, t, |t, _| out.push(t));
        }
        b.finish(|t, _| out.push(t));
        assert_eq!(out, vec![0, 3, 5, 12, 20, 35, 40]);
        assert_eq!((b.late, b.reordered), (1, 3));
    }
}
