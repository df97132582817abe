//! Batches of independent runs: on all cores with the `parallel` feature (rayon), else one after
//! the other. Either way one result per item, in order.

/// `f` over every item of `items`, in order.
pub fn map_all<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync + Send) -> Vec<R> {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        items.par_iter().map(f).collect()
    }
    #[cfg(not(feature = "parallel"))]
    {
        items.iter().map(f).collect()
    }
}
