//! MCAP files in and out: the streaming reader ([`mcap_read`]), the whole-recording reader and
//! survey (`recording`, its items at the crate root: [`crate::read_recording`], …), the
//! recording writer ([`recording_out`]), the Foxglove trajectory writer ([`foxglove_out`]) and
//! the reader of anchor-to-anchor ranges ([`anchor_ranges`]).

pub mod anchor_ranges;
pub mod foxglove_out;
pub mod mcap_read;
pub(crate) mod recording;
pub mod recording_out;
