//! The formats of uwbimu_rs, a crate of their own: it knows the measurement vocabulary
//! (`uwbimu_vocabulary`) and nothing above it — no estimator, no runner — and the compiler keeps
//! it so. MCAP logs in and out: streaming reading ([`mcap_read`]), the ros2msg schema parser
//! ([`msg_schema`]) and generic CDR decoder ([`cdr`]), field-path mappings ([`field_path`],
//! [`Mapping`]), per-topic decoders ([`topics`]), anchor tables ([`anchors`]), the bounded
//! reorder window ([`reorder`]), the whole-recording reader ([`read_recording`]), the reader of
//! anchor-to-anchor ranges ([`anchor_ranges`]), ground-truth files ([`truth_file`]) and the
//! writers: Foxglove trajectories ([`foxglove_out`]), recordings
//! ([`recording_out`]), message payloads ([`payloads`]), ROS 2 outputs ([`ros_out`]); the spill
//! of records to disk ([`spill`]); the Nooploop LinkTrack serial frames ([`linktrack`])
//! and the DWM1001 UART TLV `dwm_loc_get` response ([`dwm1001`]).

pub mod anchor_ranges;
pub mod anchors;
pub mod atomic_file;
pub mod cdr;
pub mod dwm1001;
mod error;
pub mod field_path;
pub mod foxglove_out;
pub mod linktrack;
pub mod live_settings;
mod mapping;
pub mod mcap_read;
pub mod msg_schema;
pub mod payloads;
mod recording;
pub mod recording_out;
pub mod reorder;
mod resync;
pub mod ros_out;
pub mod ros_types;
pub mod spill;
pub mod topics;
pub mod truth_file;

pub use error::{IoError, IoResult};
pub use mapping::{
    AltitudeMapping, AnchorFrom, AnchorMapping, AnchorRangeMapping, GroundTruthMapping, Mapping, OdometryMapping, TdoaMapping,
    TimeSource, UwbMapping, ANCHOR_RANGE_DEFAULT, ANCHOR_RANGE_I_DEFAULT, ANCHOR_RANGE_J_DEFAULT, BODY_AXES,
    TDOA_ANCHOR_I_DEFAULT, TDOA_ANCHOR_J_DEFAULT, TDOA_DEFAULT,
};
pub use recording::{
    read_recording, read_recording_file, stream_recording_file, survey_recording_file, AnchorLayout, MessageDecoder, ReadStats,
    RecordItem, Recording, RecordingSurvey, SensorReadCounts, TopicCounts, TopicRole, TopicStats,
};
