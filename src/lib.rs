#![doc = include_str!("../README.md")]

pub mod app;
pub mod estimation;
pub mod vocabulary;

pub use app::{calibrate, columns, methods, metrics, offsets, tune};
#[cfg(feature = "sim")]
pub use app::{generality, sim};
#[cfg(feature = "io")]
pub use app::{io, replay};
pub use estimation::{
    crlb, epoch, filters, init, ins, models, multilateration, pipeline, planar, ranging, robust, smoother, update,
};
pub use vocabulary::{config, error, math, records, state, validate};

#[cfg(feature = "python")]
mod bindings;

pub use error::{Error, Result};
