//! Layer 2 of uwbimu_rs, estimation: the pieces (measurement models, noise policies, the Kalman step, the INS
//! mechanization, the epoch rule, range calibration) and what is built from them (the filters,
//! the planar filters, the event pipeline, multilateration, self-initialisation, the smoother,
//! the CRLB). Uses only the vocabulary.

pub mod anchor_survey;
pub mod crlb;
pub mod epoch;
pub mod filters;
pub mod gate;
pub mod init;
pub mod ins;
pub mod invariant;
pub mod models;
pub mod multilateration;
pub mod pipeline;
pub mod planar;
pub mod ranging;
pub mod repair;
pub mod robust;
pub mod smoother;
pub mod units;
pub mod update;
