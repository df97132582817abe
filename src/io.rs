//! MCAP logs in and out: streaming reading ([`mcap_read`]), the ros2msg schema parser
//! ([`msg_schema`]) and generic CDR decoder ([`cdr`]), field-path mappings ([`field_path`],
//! [`mapping`]), per-topic decoders ([`topics`]), anchor tables ([`anchors`]), the bounded
//! reorder window ([`reorder`]), the whole-recording reader ([`recording`]) and ground-truth files
//! ([`truth_file`]).

pub mod anchors;
pub mod cdr;
pub mod field_path;
pub mod mapping;
pub mod mcap_read;
pub mod msg_schema;
pub mod recording;
pub mod reorder;
pub mod replay_config;
pub mod topics;
pub mod truth_file;

pub use mapping::{Mapping, TimeSource};
pub use recording::{read_recording, read_recording_file, ReadStats, Recording};
pub use replay_config::ReplayConfig;
