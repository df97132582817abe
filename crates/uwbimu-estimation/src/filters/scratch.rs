//! Scratch buffers a filter reuses from one call to the next.

/// A vector whose contents live only during one call of its owner (an epoch's measurements, say)
/// and whose capacity is kept: a clone is empty with the same capacity, so a cloned filter's
/// first update allocates no more than the original's next one (none once sized).
#[derive(Debug, Default)]
pub(crate) struct Scratch<T>(Vec<T>);

impl<T> Scratch<T> {
    /// Empty, with room for `capacity` items.
    pub(crate) fn with_capacity(capacity: usize) -> Self {
        Self(Vec::with_capacity(capacity))
    }

    /// The buffer, emptied, for one call (its capacity kept); hand it back with
    /// [`Scratch::put_back`].
    pub(crate) fn take_cleared(&mut self) -> Vec<T> {
        let mut buffer = std::mem::take(&mut self.0);
        buffer.clear();
        buffer
    }

    /// Keeps `buffer` (and its capacity) for the next call.
    pub(crate) fn put_back(&mut self, buffer: Vec<T>) {
        self.0 = buffer;
    }
}

impl<T> Clone for Scratch<T> {
    /// An empty buffer with the same capacity (the contents belong to a call, not to the owner).
    fn clone(&self) -> Self {
        Self::with_capacity(self.0.capacity())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clone_keeps_the_capacity_and_drops_the_contents() {
        let mut s = Scratch::with_capacity(4);
        let mut b = s.take_cleared();
        b.extend([1.0, 2.0, 3.0]);
        s.put_back(b);
        let mut c = s.clone();
        let b = c.take_cleared();
        assert!(b.is_empty());
        assert_eq!(b.capacity(), 4);
    }
}
