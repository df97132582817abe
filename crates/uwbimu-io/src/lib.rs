//! The formats of uwbimu_rs, a crate of their own: it knows the measurement vocabulary
//! (`uwbimu_vocabulary`) and nothing above it — no estimator, no runner — and the compiler keeps
//! it so. A folder per job:
//!
//! - [`ros`]: ROS 2 messages — the ros2msg schema parser, the generic CDR decoder, the type
//!   definitions, the payload encoders and the ROS 2 outputs (pose, odometry);
//! - [`recordings`]: MCAP files — the streaming reader, the whole-recording reader
//!   ([`read_recording`]), the recording writer, the Foxglove trajectory writer and the reader of
//!   anchor-to-anchor ranges;
//! - [`mapping`]: how a recording's topics become measurements — the mapping ([`Mapping`]), field
//!   paths, per-topic decoders, the io of each sensor of the registry (a row each,
//!   [`mapping::topics::SensorIo`]) and the bounded reorder window;
//! - [`files`]: the other files — anchor tables, ground-truth files, atomic writes, the spill of
//!   records to disk, the `[live]` table of the replay file;
//! - [`serial`]: the Nooploop LinkTrack frames and the DWM1001 UART TLV `dwm_loc_get` response.

mod error;
pub mod files;
pub mod mapping;
pub mod recordings;
pub mod ros;
pub mod serial;

pub use error::{IoError, IoResult};
pub use mapping::{
    AnchorFrom, AnchorMapping, AnchorRangeMapping, GroundTruthMapping, Mapping, TimeSource, UwbMapping, ANCHOR_RANGE_DEFAULT,
    ANCHOR_RANGE_I_DEFAULT, ANCHOR_RANGE_J_DEFAULT,
};
pub use recordings::recording::{
    read_recording, read_recording_file, stream_recording_file, survey_recording_file, AnchorLayout, MessageDecoder, ReadStats,
    RecordItem, Recording, RecordingSurvey, SensorReadCounts, TopicCounts, TopicRole, TopicStats,
};
