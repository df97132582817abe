//! Streaming MCAP reading with the `mcap` crate's sans-io [`LinearReader`]: chunked or not,
//! indexed or not, zstd / lz4 / uncompressed; bytes are pulled through `std::io::Read`, so memory
//! stays bounded by one chunk and a truncated file is never a SIGBUS (no mmap).
//! Chunks are decompressed here (zstd, lz4), bounded by their declared size; chunk and
//! data-section CRCs are checked.
//!
//! A file that ends early — a recorder that died before writing the footer, or a last chunk cut
//! short — is read up to its last complete record and reported as [`McapEnd::Truncated`], as
//! `mcap recover` does; corruption inside the file (a CRC mismatch, a bad length) stays an error.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::Read;
use std::path::Path;
use std::sync::Arc;

use crate::{IoError as Error, IoResult as Result};
use mcap::records::{ChunkHeader, Record};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

/// A schema record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SchemaInfo {
    /// Schema name (e.g. `sensor_msgs/msg/Imu`).
    pub name: String,
    /// Schema encoding (e.g. `ros2msg`, `jsonschema`).
    pub encoding: String,
    /// Schema text or bytes.
    pub data: Vec<u8>,
}

/// A channel record with its schema.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelInfo {
    /// Channel id.
    pub id: u16,
    /// Topic name.
    pub topic: String,
    /// Message encoding (e.g. `cdr`, `json`).
    pub message_encoding: String,
    /// The schema (None for schemaless channels).
    pub schema: Option<Arc<SchemaInfo>>,
}

/// One thing of interest in the file, in file order.
#[derive(Debug)]
pub enum McapEvent<'a> {
    /// A channel was declared (before its first message).
    Channel(&'a ChannelInfo),
    /// A message.
    Message {
        /// Its channel.
        channel: &'a ChannelInfo,
        /// MCAP log time, ns.
        log_time_ns: u64,
        /// The serialised payload.
        data: &'a [u8],
    },
    /// A metadata record.
    Metadata {
        /// Record name (e.g. `uwbimu.anchors`).
        name: &'a str,
        /// Its key/value pairs.
        entries: &'a BTreeMap<String, String>,
    },
}

/// How a read MCAP stream ended.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum McapEnd {
    /// The footer was read: the file is complete.
    #[default]
    Complete,
    /// The file ends before its footer; everything up to `intact_bytes` (the end of the last
    /// complete record) was read, the rest is lost.
    Truncated {
        /// Bytes of the file read as complete records.
        intact_bytes: u64,
        /// The file's size, bytes.
        size: u64,
    },
}

impl McapEnd {
    /// Bytes after the last complete record (0 for a complete file).
    pub fn lost_bytes(&self) -> u64 {
        match self {
            Self::Complete => 0,
            Self::Truncated { intact_bytes, size } => size.saturating_sub(*intact_bytes),
        }
    }

    /// The warning a replay prints for a truncated file (None when complete).
    pub fn warning(&self, label: &str) -> Option<String> {
        match self {
            Self::Complete => None,
            Self::Truncated { intact_bytes, size } => Some(format!(
                "{label} ends before its footer (the recorder stopped?): read up to the last complete record, \
                 {intact_bytes} of {size} bytes; the {} bytes after it are lost",
                self.lost_bytes()
            )),
        }
    }
}

/// Largest record or decompressed chunk accepted, bytes (guards allocations on corrupt lengths).
const MIN_RECORD_LIMIT: u64 = 64 << 20;
/// Upper bound on any record, bytes.
const MAX_RECORD_LIMIT: u64 = 1 << 30;

fn format_error(label: &str, e: impl std::fmt::Display) -> Error {
    Error::Format { what: label.to_string(), reason: e.to_string() }
}

/// Schemas and channels seen so far, and the record dispatch.
struct Registry {
    schemas: HashMap<u16, Arc<SchemaInfo>>,
    channels: HashMap<u16, ChannelInfo>,
}

impl Registry {
    fn record(&mut self, record: Record<'_>, label: &str, on_event: &mut impl FnMut(McapEvent<'_>) -> Result<()>) -> Result<()> {
        match record {
            Record::Schema { header, data } => {
                let info = SchemaInfo { name: header.name, encoding: header.encoding, data: data.into_owned() };
                self.schemas.insert(header.id, Arc::new(info));
            }
            Record::Channel(c) => {
                let schema =
                    match c.schema_id {
                        0 => None,
                        id => Some(self.schemas.get(&id).cloned().ok_or_else(|| {
                            format_error(label, format!("channel `{}` refers to undeclared schema {id}", c.topic))
                        })?),
                    };
                let info = ChannelInfo { id: c.id, topic: c.topic, message_encoding: c.message_encoding, schema };
                if self.channels.get(&c.id) != Some(&info) {
                    on_event(McapEvent::Channel(&info))?;
                    self.channels.insert(c.id, info);
                }
            }
            Record::Message { header, data } => {
                let channel = self
                    .channels
                    .get(&header.channel_id)
                    .ok_or_else(|| format_error(label, format!("message on undeclared channel {}", header.channel_id)))?;
                on_event(McapEvent::Message { channel, log_time_ns: header.log_time, data: &data })?;
            }
            Record::Metadata(m) => on_event(McapEvent::Metadata { name: &m.name, entries: &m.metadata })?,
            _ => {}
        }
        Ok(())
    }
}

/// Decompresses a chunk's records (bounded by `limit` and by the declared size) and checks the
/// CRC. Done here rather than in the `mcap` crate's streaming decompressor, which spins forever on
/// a chunk whose declared uncompressed size exceeds what its compressed data holds.
fn chunk_records(header: &ChunkHeader, data: &[u8], limit: usize, label: &str) -> Result<Vec<u8>> {
    let size = usize::try_from(header.uncompressed_size).ok().filter(|&n| n <= limit).ok_or_else(|| {
        format_error(label, format!("chunk declares {} uncompressed bytes (corrupt?)", header.uncompressed_size))
    })?;
    let bad = |e: &dyn std::fmt::Display| format_error(label, format!("{} chunk: {e}", header.compression));
    let out = match header.compression.as_str() {
        "" => data.to_vec(),
        "zstd" => zstd::bulk::decompress(data, size).map_err(|e| bad(&e))?,
        "lz4" => {
            let mut out = Vec::with_capacity(size);
            lz4::Decoder::new(data).map_err(|e| bad(&e))?.take(size as u64 + 1).read_to_end(&mut out).map_err(|e| bad(&e))?;
            out
        }
        other => return Err(format_error(label, format!("unsupported chunk compression `{other}`"))),
    };
    if out.len() != size {
        return Err(bad(&format!("holds {} bytes, its header says {size}", out.len())));
    }
    if header.uncompressed_crc != 0 {
        let calculated = crc32fast::hash(&out);
        if calculated != header.uncompressed_crc {
            return Err(format_error(
                label,
                format!("chunk CRC mismatch (stored {:08x}, calculated {calculated:08x})", header.uncompressed_crc),
            ));
        }
    }
    Ok(out)
}

/// Reads an MCAP stream of `size` bytes from `source`, calling `on_event` for channels, messages
/// and metadata in file order and `progress` with the bytes read so far. `label` names the source
/// in errors. Returns how the stream ended: complete, or truncated after its last complete record
/// (see the module doc).
///
/// # Errors
/// [`Error::Format`] for anything that is not a well-formed MCAP file (bad magic, a file that
/// ends before any record after the magic, CRC mismatch, unknown compression, a message on an
/// undeclared channel);
/// [`Error::Io`] for read failures; errors of `on_event` as they are.
pub fn read_mcap<R: Read>(
    mut source: R,
    size: u64,
    label: &str,
    mut on_event: impl FnMut(McapEvent<'_>) -> Result<()>,
    mut progress: impl FnMut(u64),
) -> Result<McapEnd> {
    if size == 0 {
        return Err(format_error(label, "the file is empty (not an MCAP file)"));
    }
    let limit = size.saturating_mul(16).clamp(MIN_RECORD_LIMIT, MAX_RECORD_LIMIT) as usize;
    let options = LinearReaderOptions::default()
        .with_emit_chunks(true)
        .with_validate_data_section_crc(true)
        .with_record_length_limit(limit);
    let mut reader = LinearReader::new_with_options(options);
    let mut registry = Registry { schemas: HashMap::new(), channels: HashMap::new() };
    let mut read_total = 0u64;
    // The end of the last complete record (bytes read minus what the reader still holds).
    let mut intact = 0u64;
    let mut records = 0u64;
    while let Some(event) = reader.next_event() {
        let event = match event {
            Err(mcap::McapError::UnexpectedEof) if records > 0 => {
                return Ok(McapEnd::Truncated { intact_bytes: intact, size });
            }
            other => other.map_err(|e| format_error(label, describe(&e)))?,
        };
        match event {
            LinearReadEvent::ReadRequest(need) => {
                // Never ask for more than what is left of the file (corrupt lengths).
                let want = need.min((size.saturating_sub(read_total)).max(1) as usize).clamp(1, 1 << 20);
                let n = source.read(reader.insert(want)).map_err(|e| Error::io(label.to_string(), e))?;
                reader.notify_read(n);
                read_total += n as u64;
                progress(read_total);
            }
            LinearReadEvent::Record { opcode, data } => {
                records += 1;
                intact = read_total;
                match mcap::parse_record(opcode, data).map_err(|e| format_error(label, describe(&e)))? {
                    Record::Chunk { header, data } => {
                        let records = chunk_records(&header, &data, limit, label)?;
                        let mut pos = 0usize;
                        while pos < records.len() {
                            let head = records
                                .get(pos..pos + 9)
                                .ok_or_else(|| format_error(label, "chunk ends inside a record header"))?;
                            let len = u64::from_le_bytes(head[1..9].try_into().unwrap_or([0; 8]));
                            let end =
                                usize::try_from(len).ok().and_then(|l| (pos + 9).checked_add(l)).filter(|&e| e <= records.len());
                            let end = end.ok_or_else(|| format_error(label, "chunk ends inside a record (corrupt length)"))?;
                            let record = mcap::parse_record(head[0], &records[pos + 9..end])
                                .map_err(|e| format_error(label, describe(&e)))?;
                            registry.record(record, label, &mut on_event)?;
                            pos = end;
                        }
                    }
                    record => registry.record(record, label, &mut on_event)?,
                }
            }
        }
    }
    Ok(McapEnd::Complete)
}

/// A message for an `mcap` error that says what it means to a user.
fn describe(e: &mcap::McapError) -> String {
    match e {
        mcap::McapError::BadMagic => "bad magic: not an MCAP file".into(),
        mcap::McapError::UnexpectedEof => "unexpected end of file (truncated?)".into(),
        other => other.to_string(),
    }
}

/// [`read_mcap`] on a file.
///
/// # Errors
/// [`Error::Io`] if the file cannot be opened; otherwise as [`read_mcap`].
pub fn read_mcap_file(
    path: &Path,
    on_event: impl FnMut(McapEvent<'_>) -> Result<()>,
    progress: impl FnMut(u64),
) -> Result<McapEnd> {
    let label = path.display().to_string();
    let io = |e: std::io::Error| Error::io(label.clone(), e);
    let file = File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    read_mcap(std::io::BufReader::with_capacity(1 << 16, file), size, &label, on_event, progress)
}
