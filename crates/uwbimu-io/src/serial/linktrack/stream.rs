//! The stream decoder: frames out of a serial byte stream cut anywhere, with resynchronisation.

use super::frames::{checksum, decode_frame, node_frame2_len};
use super::{
    LinkTrackFrame, FRAME_HEADER, NODE_FRAME2_FIXED_LEN, NODE_FRAME2_MARK, NODE_FRAME2_MAX_LEN, NODE_FRAME2_MIN_LEN,
    TAG_FRAME0_LEN, TAG_FRAME0_MARK,
};
use crate::serial::resync::{push_frames, Framing, Scan};

/// Bytes appended to the buffer per step of [`LinkTrackStream::push`]: the buffer never holds
/// more than this plus one incomplete frame.
const CHUNK: usize = NODE_FRAME2_MAX_LEN;

/// What a [`LinkTrackStream`] has seen since it was made. Every byte pushed is, in the end, part
/// of a decoded frame, skipped, or still buffered: `bytes_received` = bytes of decoded frames +
/// `bytes_skipped` + [`LinkTrackStream::buffered_len`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct LinkTrackCounts {
    /// Bytes pushed in.
    pub bytes_received: u64,
    /// Frames decoded and handed out (all kinds).
    pub frames: u64,
    /// Of `frames`, the `NodeFrame2` ones.
    pub node_frame2: u64,
    /// Of `frames`, the `TagFrame0` ones.
    pub tag_frame0: u64,
    /// Candidate frames (header, known mark, plausible length) whose last byte was not their
    /// checksum.
    pub checksum_errors: u64,
    /// Header bytes followed by a function mark this decoder does not read (other LinkTrack
    /// frames, or a `0x55` among other bytes).
    pub unknown_frames: u64,
    /// `NodeFrame2` candidates whose length field is outside the possible range or disagrees
    /// with their node count.
    pub bad_lengths: u64,
    /// Bytes dropped while looking for the next frame: garbage, the first byte of each rejected
    /// candidate, the bytes of frames of other kinds.
    pub bytes_skipped: u64,
}

/// Decodes LinkTrack frames (`NodeFrame2`, `TagFrame0`) from a byte stream delivered in pieces
/// of any size, as a serial port gives them.
///
/// Each [`push`](Self::push) appends bytes to an internal buffer and hands out every complete
/// frame found, in order. A frame starts at a `0x55` byte followed by a supported function mark;
/// its length is fixed (`TagFrame0`) or read from its length field (`NodeFrame2`, which must lie
/// in 120..=3435 and equal `120 + 13 n` for its node count `n`). A candidate whose length is
/// implausible, whose checksum fails, or whose mark is unknown costs one byte: the decoder skips
/// the `0x55` and searches again from the next byte, so a frame after a corrupt or truncated one
/// is still found. Bytes before a header are skipped. Nothing panics on any input, and the buffer
/// holds at most one incomplete frame (≤ 3434 bytes) between calls; [`LinkTrackCounts`] records
/// what was decoded and skipped.
#[derive(Debug, Clone, Default)]
pub struct LinkTrackStream {
    buf: Vec<u8>,
    counts: LinkTrackCounts,
}

impl LinkTrackStream {
    /// An empty decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends `bytes` and calls `out` with every frame completed, in stream order. Bytes of an
    /// incomplete frame at the end stay buffered for the next call.
    pub fn push(&mut self, bytes: &[u8], out: &mut impl FnMut(LinkTrackFrame)) {
        self.counts.bytes_received += bytes.len() as u64;
        let skipped = push_frames(&mut self.buf, bytes, CHUNK, &mut Frames { counts: &mut self.counts, out });
        self.counts.bytes_skipped += skipped;
        debug_assert!(self.buf.len() < NODE_FRAME2_MAX_LEN, "buffer above one frame");
    }

    /// [`push`](Self::push), appending the frames to `frames`.
    pub fn push_into(&mut self, bytes: &[u8], frames: &mut Vec<LinkTrackFrame>) {
        self.push(bytes, &mut |f| frames.push(f));
    }

    /// The counts so far.
    pub fn counts(&self) -> LinkTrackCounts {
        self.counts
    }

    /// Bytes held back: the start of a frame not yet complete.
    pub fn buffered_len(&self) -> usize {
        self.buf.len()
    }

    /// Drops the buffered bytes (e.g. after reopening the port); the counts stay.
    pub fn clear(&mut self) {
        self.buf.clear();
    }
}

/// The LinkTrack part of the scan: the stream's counts and where its frames go.
struct Frames<'a, F> {
    counts: &'a mut LinkTrackCounts,
    out: &'a mut F,
}

impl<F: FnMut(LinkTrackFrame)> Framing for Frames<'_, F> {
    const START: u8 = FRAME_HEADER;

    /// Classifies the bytes from a header byte, counting a rejection's reason.
    fn classify(&mut self, rest: &[u8]) -> Scan {
        let Some(&mark) = rest.get(1) else {
            return Scan::Incomplete;
        };
        let len = match mark {
            TAG_FRAME0_MARK => TAG_FRAME0_LEN,
            NODE_FRAME2_MARK => {
                let [Some(&lo), Some(&hi)] = [rest.get(2), rest.get(3)] else {
                    return Scan::Incomplete;
                };
                let declared = usize::from(u16::from_le_bytes([lo, hi]));
                let count_ok = match rest.get(NODE_FRAME2_FIXED_LEN - 1) {
                    Some(&count) => declared == node_frame2_len(usize::from(count)),
                    None => true, // not known yet
                };
                if !(NODE_FRAME2_MIN_LEN..=NODE_FRAME2_MAX_LEN).contains(&declared) || !count_ok {
                    self.counts.bad_lengths += 1;
                    return Scan::Reject;
                }
                declared
            }
            _ => {
                self.counts.unknown_frames += 1;
                return Scan::Reject;
            }
        };
        let Some(frame) = rest.get(..len) else {
            return Scan::Incomplete;
        };
        match frame.split_last() {
            Some((&last, body)) if last == checksum(body) => Scan::Whole(len),
            _ => {
                self.counts.checksum_errors += 1;
                Scan::Reject
            }
        }
    }
    /// Decodes a frame that passed [`Self::classify`], counts it and hands it out.
    fn take(&mut self, frame: &[u8]) -> bool {
        match decode_frame(frame) {
            Ok(frame) => {
                self.counts.frames += 1;
                match frame {
                    LinkTrackFrame::NodeFrame2(_) => self.counts.node_frame2 += 1,
                    LinkTrackFrame::TagFrame0(_) => self.counts.tag_frame0 += 1,
                }
                (self.out)(frame);
                true
            }
            // Unreachable after `classify`'s checks; treat as a rejected start.
            Err(_) => {
                self.counts.bad_lengths += 1;
                false
            }
        }
    }
}
