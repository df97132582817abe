#![doc = include_str!("../README.md")]

pub mod columns;
pub mod config;
pub mod crlb;
pub mod epoch;
pub mod error;
pub mod filters;
#[cfg(feature = "sim")]
pub mod generality;
pub mod init;
pub mod ins;
#[cfg(feature = "io")]
pub mod io;
pub mod math;
pub mod methods;
pub mod metrics;
pub mod models;
pub mod multilateration;
pub mod pipeline;
pub mod planar;
pub mod ranging;
pub mod records;
#[cfg(feature = "io")]
pub mod replay;
pub mod robust;
#[cfg(feature = "sim")]
pub mod sim;
pub mod smoother;
pub mod state;
pub mod update;
pub mod validate;

#[cfg(feature = "python")]
mod bindings;

pub use error::{Error, Result};
