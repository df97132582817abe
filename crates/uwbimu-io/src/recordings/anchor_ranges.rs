//! Reads a log of anchor-to-anchor ranges through the `[mapping.anchor_ranges]` of a [`Mapping`]
//! ([`read_anchor_ranges`]): the anchor survey's input, as anchor rows (ids) and pairs of rows.
//! Only those topics are decoded; a survey log needs no IMU, UWB range or anchor position.
//! Unusable ranges (not finite, negative, of one anchor with itself) and ranges naming an id
//! outside the rows are dropped and counted, never fatal.

use std::cmp::Ordering;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::Path;

use uwbimu_vocabulary::records::AnchorPair;

use crate::files::anchors::read_anchor_file;
use crate::mapping::topics::{AnchorRangeDecoder, RawAnchorRange, ANCHOR_RANGE_MSG_NAME};
use crate::recordings::mcap_read::{read_mcap, McapEnd, McapEvent};
use crate::recordings::recording::topic_list;
use crate::{IoError as Error, IoResult as Result, Mapping, TopicRole, TopicStats};

/// What reading a log of anchor-to-anchor ranges found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AnchorRangeStats {
    /// Every channel, in file order (role [`TopicRole::AnchorRanges`] for those read).
    pub topics: Vec<TopicStats>,
    /// Ranges decoded from the anchor-range topics.
    pub decoded: usize,
    /// Ranges kept as pairs.
    pub used: usize,
    /// Ranges that were not finite or negative, or of one anchor with itself (dropped).
    pub bad_value: usize,
    /// Ranges naming an anchor id outside the rows (dropped).
    pub unknown_anchor: usize,
    /// Those ids.
    pub unknown_ids: BTreeSet<String>,
    /// Where the anchor rows came from: `anchor_ranges.anchor_ids`, `anchors.positions`,
    /// `anchors.file` or `the pairs`.
    pub rows_from: &'static str,
    /// Whether the file was complete or ended early ([`McapEnd`]; its messages up to the last
    /// complete record are used).
    pub end: McapEnd,
}

/// The anchor-to-anchor ranges of a log, ready for
/// `uwbimu_estimation::anchor_survey::survey_anchors`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AnchorRanges {
    /// The id of each anchor row (row `k` has id `anchor_ids[k]`; row 0 is the survey's origin).
    pub anchor_ids: Vec<String>,
    /// The usable ranges, in file order, their anchors as rows of `anchor_ids`.
    pub pairs: Vec<AnchorPair>,
    /// What was read and dropped.
    pub stats: AnchorRangeStats,
}

/// Reads the anchor-to-anchor ranges of an MCAP stream (`size` bytes; `label` names it in
/// errors) through `mapping.anchor_ranges`; `progress` gets the bytes read so far. The anchor
/// rows are as [`crate::AnchorRangeMapping`] says. A file that ends early is read up to its
/// last complete record (`stats.end` says so). The list of pairs may be empty (every range
/// dropped: the statistics say why).
///
/// # Errors
/// [`Error::Format`] / [`Error::Io`] / [`Error::Mcap`] for unreadable or corrupt input (a file
/// truncated before any complete message too); [`Error::Mapping`] for a named topic that is not
/// in the file, no anchor-range topic at all, or field paths that do not fit its schema; the
/// errors of reading the mapping's anchor file.
pub fn read_anchor_ranges<R: std::io::Read>(
    source: R,
    size: u64,
    label: &str,
    mapping: &Mapping,
    progress: impl FnMut(u64),
) -> Result<AnchorRanges> {
    let m = &mapping.anchor_ranges;
    let mut stats = AnchorRangeStats::default();
    let mut decoders: BTreeMap<u16, AnchorRangeDecoder> = BTreeMap::new();
    let mut raw: Vec<RawAnchorRange> = Vec::new();
    let mut messages = 0usize;
    stats.end = read_mcap(
        source,
        size,
        label,
        |event| {
            match event {
                McapEvent::Channel(c) => {
                    let read = if m.topics.is_empty() { AnchorRangeDecoder::recognises(c) } else { m.topics.contains(&c.topic) };
                    if read {
                        decoders.insert(c.id, AnchorRangeDecoder::new(c, m)?);
                    }
                    let role = if read { TopicRole::AnchorRanges } else { TopicRole::Ignored };
                    match stats.topics.iter_mut().find(|t| t.topic == c.topic) {
                        Some(t) => t.role = role,
                        None => stats.topics.push(TopicStats {
                            topic: c.topic.clone(),
                            schema: c.schema.as_ref().map_or(String::new(), |s| s.name.clone()),
                            encoding: c.message_encoding.clone(),
                            count: 0,
                            role,
                        }),
                    }
                }
                McapEvent::Message { channel, data, .. } => {
                    messages += 1;
                    if let Some(t) = stats.topics.iter_mut().find(|t| t.topic == channel.topic) {
                        t.count += 1;
                    }
                    if let Some(d) = decoders.get(&channel.id) {
                        d.decode(data, &mut raw).map_err(|e| match e {
                            Error::Format { what, reason } => {
                                Error::Format { what: format!("topic `{}`: {what}", channel.topic), reason }
                            }
                            other => other,
                        })?;
                    }
                }
                McapEvent::Metadata { .. } => {}
            }
            Ok(())
        },
        progress,
    )?;
    if stats.end != McapEnd::Complete && messages == 0 {
        return Err(Error::Format {
            what: label.to_string(),
            reason: "unexpected end of file (truncated?) before any complete message".into(),
        });
    }
    check_topics(mapping, &stats.topics)?;
    stats.decoded = raw.len();
    let (anchor_ids, rows_from) = rows(mapping, &raw)?;
    stats.rows_from = rows_from;
    let index: HashMap<&str, usize> = anchor_ids.iter().enumerate().map(|(k, id)| (id.as_str(), k)).collect();
    let mut pairs = Vec::with_capacity(raw.len());
    for r in &raw {
        if !usable(r) {
            stats.bad_value += 1;
            continue;
        }
        match (index.get(r.anchor_i.as_str()), index.get(r.anchor_j.as_str())) {
            (Some(&i), Some(&j)) => pairs.push(AnchorPair { i, j, range_m: r.range_m }),
            _ => {
                stats.unknown_anchor += 1;
                for id in [&r.anchor_i, &r.anchor_j] {
                    if !index.contains_key(id.as_str()) {
                        stats.unknown_ids.insert(id.clone());
                    }
                }
            }
        }
    }
    stats.used = pairs.len();
    Ok(AnchorRanges { anchor_ids, pairs, stats })
}

/// [`read_anchor_ranges`] on a file path.
///
/// # Errors
/// As [`read_anchor_ranges`]; [`Error::Io`] if the file cannot be opened.
pub fn read_anchor_ranges_file(path: &Path, mapping: &Mapping, progress: impl FnMut(u64)) -> Result<AnchorRanges> {
    let label = path.display().to_string();
    let io = |e: std::io::Error| Error::io(label.clone(), e);
    let file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    read_anchor_ranges(std::io::BufReader::with_capacity(1 << 16, file), size, &label, mapping, progress)
}

/// Whether a range can be used: finite, not negative, between two different anchors.
fn usable(r: &RawAnchorRange) -> bool {
    r.range_m.is_finite() && r.range_m >= 0.0 && r.anchor_i != r.anchor_j
}

/// Every named topic is in the file, and some topic was read.
fn check_topics(mapping: &Mapping, topics: &[TopicStats]) -> Result<()> {
    let missing = |what: String| Error::Mapping {
        field: "anchor_ranges.topics".into(),
        reason: format!("{what}; topics in the file: {}", topic_list(topics)),
    };
    if let Some(t) = mapping.anchor_ranges.topics.iter().find(|t| !topics.iter().any(|s| &s.topic == *t)) {
        return Err(missing(format!("topic `{t}` not found")));
    }
    if !topics.iter().any(|t| t.role == TopicRole::AnchorRanges) {
        return Err(missing(format!(
            "no anchor-to-anchor range topic (name one in anchor_ranges.topics with its field paths, or record {ANCHOR_RANGE_MSG_NAME})"
        )));
    }
    Ok(())
}

/// The anchor rows and where they came from (see [`crate::AnchorRangeMapping`]).
fn rows(mapping: &Mapping, raw: &[RawAnchorRange]) -> Result<(Vec<String>, &'static str)> {
    if let Some(ids) = &mapping.anchor_ranges.anchor_ids {
        return Ok((ids.clone(), "anchor_ranges.anchor_ids"));
    }
    let (mut ids, from): (Vec<String>, &'static str) = if let Some(p) = &mapping.anchors.positions {
        (p.keys().cloned().collect(), "anchors.positions")
    } else if let Some(f) = &mapping.anchors.file {
        (read_anchor_file(f)?.into_keys().collect(), "anchors.file")
    } else {
        let seen: BTreeSet<&str> =
            raw.iter().filter(|r| usable(r)).flat_map(|r| [r.anchor_i.as_str(), r.anchor_j.as_str()]).collect();
        (seen.into_iter().map(str::to_string).collect(), "the pairs")
    };
    ids.sort_by(|a, b| natural_order(a, b));
    Ok((ids, from))
}

/// Orders ids as a person would: runs of digits by their number (`A2` before `A10`), the rest as
/// text; ties (`A01`, `A1`) as text.
fn natural_order(a: &str, b: &str) -> Ordering {
    let (ra, rb) = (runs(a), runs(b));
    for (x, y) in ra.iter().zip(&rb) {
        let digits = |s: &str| s.bytes().all(|c| c.is_ascii_digit());
        let order = if digits(x) && digits(y) {
            let (x, y) = (x.trim_start_matches('0'), y.trim_start_matches('0'));
            x.len().cmp(&y.len()).then_with(|| x.cmp(y))
        } else {
            x.cmp(y)
        };
        if order != Ordering::Equal {
            return order;
        }
    }
    ra.len().cmp(&rb.len()).then_with(|| a.cmp(b))
}

/// `s` cut into runs of ASCII digits and runs of anything else.
fn runs(s: &str) -> Vec<&str> {
    let b = s.as_bytes();
    let mut out = Vec::new();
    let mut start = 0;
    for k in 1..=b.len() {
        if k == b.len() || b[k].is_ascii_digit() != b[k - 1].is_ascii_digit() {
            out.push(&s[start..k]);
            start = k;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_sort_as_a_person_reads_them() {
        let mut ids = vec!["A10", "A2", "b", "11", "4", "A1", "A01", "9"];
        ids.sort_by(|a, b| natural_order(a, b));
        assert_eq!(ids, ["4", "9", "11", "A01", "A1", "A2", "A10", "b"]);
        assert_eq!(runs("ä12b"), ["ä", "12", "b"]);
        assert!(runs("").is_empty());
    }
}
