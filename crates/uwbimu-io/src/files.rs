//! The files besides recordings: anchor tables ([`anchors`]), ground-truth files
//! ([`truth_file`]), writes that never leave a half-written file ([`atomic_file`]), records
//! spilled to an unnamed temporary file ([`spill`]) and the `[live]` table of the replay file
//! ([`live_settings`]).

pub mod anchors;
pub mod atomic_file;
pub mod live_settings;
pub mod spill;
pub mod truth_file;
