//! What becomes of the decoded items: the counts and spans that make the read statistics and
//! the anchor table ([`Survey`], without keeping the items), the anchor indices and statistics
//! settled from them ([`settle`]), and the conversion of each item into the filters' records
//! ([`Converter`]). The whole-recording read and the streamed read share all three.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use crate::files::anchors::{read_anchor_file, AnchorTable};
use crate::mapping::topics::RawRange;
use crate::{IoError as Error, IoResult as Result, Mapping};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement, TdoaMeasurement};
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use super::reader::{Item, ItemSink, Pass};
use super::{ReadStats, SensorReadCounts};

/// One decoded record, ready for the filters: anchor ids are anchor indices, times seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RecordItem {
    /// An IMU sample.
    Imu(ImuSample),
    /// A range, with its variance when the message had one (m², else NaN).
    Range(RangeMeasurement, f64),
    /// A TDoA.
    Tdoa(TdoaMeasurement),
    /// A reading of a sensor without anchors (magnetometer, altitude, odometry, pose fix).
    Sensor(Observation),
    /// A ground-truth position (time s, position m), from the ground-truth topic.
    Truth(f64, Vec3),
}

/// Whether a decoded range can be used.
enum RangeUse {
    /// Its validity condition failed.
    Invalid,
    /// Not finite, or negative.
    BadValue,
    /// Of a tag id that is not a tag.
    UnknownTag,
    /// Usable if its anchor has a position.
    Usable,
}

fn range_use(raw: &RawRange, tag: Option<usize>) -> RangeUse {
    if !raw.valid {
        RangeUse::Invalid
    } else if !(raw.range_m.is_finite() && raw.range_m >= 0.0) {
        RangeUse::BadValue
    } else if tag.is_none() {
        RangeUse::UnknownTag
    } else {
        RangeUse::Usable
    }
}

/// Widens `span` to hold `t`.
fn widen(span: &mut Option<(i64, i64)>, t: i64) {
    *span = Some(span.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
}

/// The union of two spans.
fn union(a: Option<(i64, i64)>, b: Option<(i64, i64)>) -> Option<(i64, i64)> {
    match (a, b) {
        (Some((a0, a1)), Some((b0, b1))) => Some((a0.min(b0), a1.max(b1))),
        (a, None) => a,
        (None, b) => b,
    }
}

/// Whether an IMU sample at `t` repeats the previous one's time (it is dropped); notes `t`.
fn repeats(last: &mut Option<i64>, t: i64) -> bool {
    let repeated = *last == Some(t);
    *last = Some(t);
    repeated
}

/// The usable TDoA of one anchor pair: how many, and their time span (ns).
type PairTally = (usize, Option<(i64, i64)>);

/// The ranges of one anchor id.
#[derive(Debug, Clone, Copy, Default)]
struct RangeTally {
    invalid: usize,
    bad_value: usize,
    usable: usize,
    span: Option<(i64, i64)>,
}

/// Counts and spans of the items of a pass, and the anchor positions the range messages carry
/// (first per id, in time order): everything the statistics need, in memory bounded by the
/// number of anchors.
#[derive(Debug, Default)]
pub(super) struct Survey {
    from_ranges: AnchorTable,
    ranges: BTreeMap<String, RangeTally>,
    tdoa: BTreeMap<(String, String), PairTally>,
    tdoa_bad_value: usize,
    unknown_tag: usize,
    unknown_tag_ids: BTreeSet<String>,
    per_tag: BTreeMap<usize, usize>,
    sensors: BTreeMap<SensorKind, (SensorReadCounts, Option<(i64, i64)>)>,
    last_imu: Option<i64>,
    imu: usize,
    imu_duplicates: usize,
    imu_span: Option<(i64, i64)>,
    imu_non_finite: Option<i64>,
    truth: usize,
}

impl Survey {
    /// Counts `item`, stamped `t_ns`.
    fn note(&mut self, t_ns: i64, item: &Item) {
        match item {
            Item::Imu(accel, gyro) => {
                if repeats(&mut self.last_imu, t_ns) {
                    self.imu_duplicates += 1;
                } else if !accel.iter().chain(gyro.iter()).all(|v| v.is_finite()) {
                    self.imu_non_finite.get_or_insert(t_ns);
                } else {
                    self.imu += 1;
                    widen(&mut self.imu_span, t_ns);
                }
            }
            Item::Range(raw, tag) => {
                if let Some(p) = raw.anchor_position.filter(|p| p.iter().all(|v| v.is_finite())) {
                    self.from_ranges.set_if_unknown(&raw.anchor_id, p);
                }
                if !self.ranges.contains_key(&raw.anchor_id) {
                    self.ranges.insert(raw.anchor_id.clone(), RangeTally::default());
                }
                let Some(tally) = self.ranges.get_mut(&raw.anchor_id) else { return };
                match range_use(raw, *tag) {
                    RangeUse::Invalid => tally.invalid += 1,
                    RangeUse::BadValue => tally.bad_value += 1,
                    RangeUse::UnknownTag => {
                        self.unknown_tag += 1;
                        self.unknown_tag_ids.insert(raw.tag_id.clone().unwrap_or_default());
                    }
                    RangeUse::Usable => {
                        *self.per_tag.entry(tag.unwrap_or_default()).or_default() += 1;
                        tally.usable += 1;
                        widen(&mut tally.span, t_ns);
                    }
                }
            }
            Item::Tdoa(raw) => {
                if !raw.tdoa_m.is_finite() || raw.anchor_i == raw.anchor_j {
                    self.tdoa_bad_value += 1;
                } else {
                    let pair = self.tdoa.entry((raw.anchor_i.clone(), raw.anchor_j.clone())).or_default();
                    pair.0 += 1;
                    widen(&mut pair.1, t_ns);
                }
            }
            Item::Sensor((o, usable)) => {
                let (counts, span) = self.sensors.entry(o.kind()).or_default();
                if *usable {
                    counts.used += 1;
                    widen(span, t_ns);
                } else {
                    counts.invalid += 1;
                }
            }
            Item::Truth(_) => self.truth += 1,
        }
    }
}

impl Survey {
    /// IMU samples used.
    pub(super) fn imu_count(&self) -> usize {
        self.imu
    }

    /// Times of the first and last IMU sample used, s.
    pub(super) fn imu_span_s(&self) -> Option<(f64, f64)> {
        self.imu_span.map(|(a, b)| (a as f64 * 1e-9, b as f64 * 1e-9))
    }

    /// Ground-truth items of the topic.
    pub(super) fn truth_count(&self) -> usize {
        self.truth
    }

    /// TDoA used: those whose two anchors are in `layout`.
    pub(super) fn tdoa_used(&self, layout: &AnchorLayout) -> usize {
        self.tdoa
            .iter()
            .filter(|((i, j), _)| layout.index_of(i).is_some() && layout.index_of(j).is_some())
            .map(|(_, (n, _))| n)
            .sum()
    }
}

impl ItemSink for Survey {
    fn item(&mut self, t_ns: i64, item: Item) -> Result<()> {
        self.note(t_ns, &item);
        Ok(())
    }
}

/// The anchors the filters get: ids and positions in filter-index order, and the index of each id.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AnchorLayout {
    /// Anchor ids, one per anchor index.
    pub ids: Vec<String>,
    /// Anchor positions, m.
    pub positions: Vec<Vec3>,
    index: HashMap<String, usize>,
}

impl AnchorLayout {
    /// The layout of the anchors the mapping itself gives (`anchors.positions`, else
    /// `anchors.file`), in id order as a whole-file read orders them; None when it gives none.
    ///
    /// # Errors
    /// As [`read_anchor_file`].
    pub fn of_mapping(mapping: &Mapping) -> Result<Option<Self>> {
        let given = match (&mapping.anchors.positions, &mapping.anchors.file) {
            (Some(p), _) => p.iter().map(|(k, v)| (k.clone(), Vec3::from(*v))).collect::<BTreeMap<_, _>>(),
            (None, Some(f)) => read_anchor_file(f)?,
            (None, None) => return Ok(None),
        };
        let mut layout = Self::default();
        for (id, p) in given {
            layout.index.insert(id.clone(), layout.positions.len());
            layout.positions.push(p);
            layout.ids.push(id);
        }
        Ok(Some(layout))
    }

    /// The filter index of anchor `id` (None: no known position).
    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.index.get(id).copied()
    }
}

/// Anchor positions by the mapping's priority: the mapping's own, its anchor file, the
/// `uwbimu.anchors` metadata, the anchor topic, else the range messages'. Returns the table and
/// where it came from.
fn anchor_table<S>(mapping: &Mapping, pass: &Pass<S>, from_ranges: &AnchorTable) -> Result<(AnchorTable, &'static str)> {
    let m = &mapping.anchors;
    let (given, source): (Option<BTreeMap<String, Vec3>>, &'static str) = if let Some(p) = &m.positions {
        (Some(p.iter().map(|(k, v)| (k.clone(), Vec3::from(*v))).collect()), "mapping")
    } else if let Some(f) = &m.file {
        (Some(read_anchor_file(f)?), "file")
    } else if let Some(md) = &pass.metadata_anchors {
        (Some(md.clone()), "metadata uwbimu.anchors")
    } else if !pass.topic_anchors.is_empty() {
        (Some(pass.topic_anchors.clone()), "anchor topic")
    } else {
        (None, "range messages")
    };
    let table = match given {
        Some(g) => {
            let mut table = AnchorTable::default();
            for (id, p) in g {
                table.set_if_unknown(&id, p);
            }
            table
        }
        None => from_ranges.clone(),
    };
    if !table.any_position() {
        return Err(Error::Mapping {
            field: "anchors".into(),
            reason: "no anchor positions: give anchors.file / anchors.positions, an `uwbimu.anchors` metadata record, \
                     an anchors.topic, or uwb.anchor_position"
                .into(),
        });
    }
    Ok((table, source))
}

/// The anchors and the complete read statistics of a pass that went through a [`Survey`]
/// (`survey`, with `pass` for the rest): what the filters get, and what was used and dropped.
///
/// # Errors
/// [`Error::Mapping`] without anchor positions; [`Error::Format`] for a non-finite IMU sample.
pub(super) fn settle<S>(mapping: &Mapping, pass: &Pass<S>, survey: &Survey) -> Result<(AnchorLayout, ReadStats)> {
    let (table, source) = anchor_table(mapping, pass, &survey.from_ranges)?;
    let mut layout = AnchorLayout::default();
    for (i, id) in table.ids().iter().enumerate() {
        if let Some(p) = table.position(i) {
            layout.index.insert(id.clone(), layout.positions.len());
            layout.positions.push(p);
            layout.ids.push(id.clone());
        }
    }
    let mut stats = pass.stats.clone();
    stats.anchor_source = source;
    let mut span = survey.imu_span;
    for (id, tally) in &survey.ranges {
        let counts = stats.per_anchor.entry(id.clone()).or_default();
        counts.invalid += tally.invalid;
        counts.bad_value += tally.bad_value;
        if layout.index_of(id).is_some() {
            counts.used += tally.usable;
            span = union(span, tally.span);
        } else {
            stats.unknown_anchor += tally.usable;
        }
    }
    stats.tdoa_bad_value = survey.tdoa_bad_value;
    stats.unknown_tag = survey.unknown_tag;
    stats.unknown_tag_ids = survey.unknown_tag_ids.clone();
    stats.ranges_per_tag = survey.per_tag.clone();
    for (kind, (counts, sensor_span)) in &survey.sensors {
        stats.sensors.insert(*kind, *counts);
        span = union(span, *sensor_span);
    }
    for ((i, j), (count, pair_span)) in &survey.tdoa {
        if layout.index_of(i).is_some() && layout.index_of(j).is_some() {
            span = union(span, *pair_span);
        } else {
            stats.tdoa_unknown_anchor += count;
            for id in [i, j] {
                if layout.index_of(id).is_none() {
                    stats.tdoa_unknown_ids.insert(id.clone());
                }
            }
        }
    }
    if let Some(t) = survey.imu_non_finite {
        return Err(Error::Format { what: "IMU".into(), reason: format!("non-finite sample at t = {t} ns") });
    }
    stats.imu_duplicates = survey.imu_duplicates;
    stats.span_ns = span;
    Ok((layout, stats))
}

/// Turns decoded items into [`RecordItem`]s with the anchor indices of an [`AnchorLayout`],
/// dropping what the statistics count as dropped (repeated IMU times, unusable ranges, TDoA and
/// readings, unknown anchors and tags), and ground-truth items when the truth comes from a file.
pub(super) struct Converter {
    last_imu: Option<i64>,
    truth_from_topic: bool,
}

impl Converter {
    /// A converter; `truth_from_topic` keeps the ground-truth items.
    pub(super) fn new(truth_from_topic: bool) -> Self {
        Self { last_imu: None, truth_from_topic }
    }

    /// The record of `item` stamped `t_ns`, with the anchor indices of `layout`, if it is used.
    pub(super) fn convert(&mut self, layout: &AnchorLayout, t_ns: i64, item: Item) -> Option<RecordItem> {
        let t_s = t_ns as f64 * 1e-9;
        match item {
            Item::Imu(accel, gyro) => {
                (!repeats(&mut self.last_imu, t_ns)).then_some(RecordItem::Imu(ImuSample { t_s, accel, gyro }))
            }
            Item::Range(raw, tag) => {
                let (RangeUse::Usable, Some(tag)) = (range_use(&raw, tag), tag) else { return None };
                let anchor = layout.index_of(&raw.anchor_id)?;
                Some(RecordItem::Range(
                    RangeMeasurement { t_s, anchor, range_m: raw.range_m, tag },
                    raw.variance_m2.unwrap_or(f64::NAN),
                ))
            }
            Item::Tdoa(raw) => {
                if !raw.tdoa_m.is_finite() || raw.anchor_i == raw.anchor_j {
                    return None;
                }
                let (anchor_i, anchor_j) = (layout.index_of(&raw.anchor_i)?, layout.index_of(&raw.anchor_j)?);
                Some(RecordItem::Tdoa(TdoaMeasurement { t_s, anchor_i, anchor_j, tdoa_m: raw.tdoa_m }))
            }
            Item::Sensor((o, usable)) => usable.then(|| RecordItem::Sensor(o.at(t_s))),
            Item::Truth(p) => self.truth_from_topic.then_some(RecordItem::Truth(t_s, p)),
        }
    }
}

/// The items of a whole-recording read, kept in time order per kind for [`Converter`] once the
/// anchors are settled, and surveyed as they come.
#[derive(Default)]
pub(super) struct Collected {
    /// IMU samples: stamp ns, specific force, rate.
    pub imu: Vec<(i64, Vec3, Vec3)>,
    /// Ranges, TDoA and the other sensors' readings as decoded, with their stamps (ns).
    pub ranging: Vec<(i64, Item)>,
    /// Ground truth from the topic: stamp ns, position.
    pub truth: Vec<(i64, Vec3)>,
    /// Their survey.
    pub survey: Survey,
}

impl ItemSink for Collected {
    fn item(&mut self, t_ns: i64, item: Item) -> Result<()> {
        self.survey.note(t_ns, &item);
        match item {
            Item::Imu(a, g) => self.imu.push((t_ns, a, g)),
            Item::Truth(p) => self.truth.push((t_ns, p)),
            ranging => self.ranging.push((t_ns, ranging)),
        }
        Ok(())
    }
}
