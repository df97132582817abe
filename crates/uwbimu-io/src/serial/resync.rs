//! The resynchronising scan the serial-stream decoders share ([`crate::serial::linktrack`],
//! [`crate::serial::dwm1001`]): bytes arrive in pieces cut anywhere, frames start at a known byte,
//! and a candidate that turns out not to be a frame costs one byte before the search goes on.

/// What the bytes from a start byte are, as a protocol's [`Framing::classify`] says.
pub(crate) enum Scan {
    /// A whole frame of this many bytes.
    Whole(usize),
    /// Not a frame start: skip one byte.
    Reject,
    /// Possibly a frame, not all of it here yet.
    Incomplete,
}

/// One protocol's part of the scan: what a candidate is, and what to do with a whole frame.
pub(crate) trait Framing {
    /// The byte every frame starts with.
    const START: u8;

    /// Classifies the bytes from a start byte to the end of the buffer.
    fn classify(&mut self, bytes: &[u8]) -> Scan;

    /// Takes a whole frame; false rejects it as a start (it then costs one byte).
    fn take(&mut self, frame: &[u8]) -> bool;
}

/// Appends `bytes` to `buf` in pieces of at most `chunk` bytes, after each one handing every
/// whole frame to `framing` and dropping what is not a frame; leaves only the start of an
/// incomplete frame in `buf`. Returns the bytes skipped (garbage and rejected starts).
pub(crate) fn push_frames<F: Framing>(buf: &mut Vec<u8>, bytes: &[u8], chunk: usize, framing: &mut F) -> u64 {
    let mut skipped = 0;
    for piece in bytes.chunks(chunk) {
        buf.extend_from_slice(piece);
        let mut pos = 0;
        while pos < buf.len() {
            let Some(start) = buf[pos..].iter().position(|&b| b == F::START) else {
                skipped += (buf.len() - pos) as u64;
                pos = buf.len();
                break;
            };
            skipped += start as u64;
            pos += start;
            match framing.classify(&buf[pos..]) {
                Scan::Incomplete => break,
                Scan::Whole(len) if framing.take(&buf[pos..pos + len]) => pos += len,
                Scan::Whole(_) | Scan::Reject => {
                    skipped += 1;
                    pos += 1;
                }
            }
        }
        buf.drain(..pos);
    }
    skipped
}
