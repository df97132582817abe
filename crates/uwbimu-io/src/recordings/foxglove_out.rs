//! Writes an estimated trajectory as an MCAP file that Foxglove opens: JSON channels with
//! `jsonschema` schemas named `foxglove.PoseInFrame` (one per step, `/uwbimu/pose`),
//! `foxglove.PosesInFrame` (the decimated path in segments, `/uwbimu/path`) and
//! `foxglove.FrameTransform` (`map` → `base_link`, `/tf`). The header profile is "" because
//! the channels are JSON, not CDR.
//!
//! The file grows linearly with the trajectory: each path message holds only the poses since the
//! previous one (starting at its last pose, so the segments join), never the whole path again.
//! Foxglove's 3D panel shows the whole path when the topic's decay time is long enough.

use std::collections::BTreeMap;
use std::io::{Seek, Write};

use crate::{IoError as Error, IoResult as Result};
use mcap::records::MessageHeader;
use mcap::WriteOptions;
use serde_json::json;
use uwbimu_vocabulary::math::{Quat, Vec3};
use uwbimu_vocabulary::records::PosePoint;

const TIME: &str = r#"{"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}}"#;
const VEC3: &str = r#"{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}}"#;
const QUAT: &str =
    r#"{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}"#;

fn pose_schema() -> String {
    format!(r#"{{"type":"object","properties":{{"position":{VEC3},"orientation":{QUAT}}}}}"#)
}

fn schema_text(name: &str) -> String {
    let body = match name {
        "foxglove.PoseInFrame" => {
            format!(r#""timestamp":{TIME},"frame_id":{{"type":"string"}},"pose":{}"#, pose_schema())
        }
        "foxglove.PosesInFrame" => {
            format!(r#""timestamp":{TIME},"frame_id":{{"type":"string"}},"poses":{{"type":"array","items":{}}}"#, pose_schema())
        }
        _ => format!(
            r#""timestamp":{TIME},"parent_frame_id":{{"type":"string"}},"child_frame_id":{{"type":"string"}},"translation":{VEC3},"rotation":{QUAT}"#
        ),
    };
    format!(r#"{{"title":"{name}","type":"object","properties":{{{body}}}}}"#)
}

/// Non-negative seconds as MCAP nanoseconds.
fn nanos_of(t_s: f64) -> u64 {
    (t_s.max(0.0) * 1e9).round() as u64
}

/// MCAP nanoseconds as a Foxglove `{sec, nsec}` time.
fn stamp_of(ns: u64) -> serde_json::Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

fn pose_json(p: &Vec3, q: &Quat) -> serde_json::Value {
    json!({"position": {"x": p.x, "y": p.y, "z": p.z}, "orientation": {"x": q.i, "y": q.j, "z": q.k, "w": q.w}})
}

/// Writes an estimated trajectory to an MCAP sink one point at a time, in constant memory: each
/// [`push`](Self::push) writes the point's pose and transform at once, and a path segment every
/// `path_period_s`; [`finish`](Self::finish) publishes the last segment and closes the file.
/// The bytes are those of [`write_trajectory_mcap`] on the same points.
pub struct TrajectoryMcapWriter<W: Write + Seek> {
    mcap: mcap::Writer<W>,
    label: String,
    pose_channel: u16,
    path_channel: u16,
    tf_channel: u16,
    sequence: u32,
    path_period_s: f64,
    path_spacing_s: f64,
    /// Poses of the segment being gathered; its first is the last pose of the previous one.
    path: Vec<serde_json::Value>,
    last_path_pose_s: f64,
    last_path_message_s: f64,
    /// The log time of the last pushed point when that point published no path message: the
    /// final segment [`Self::finish`] publishes.
    unpublished_path_ns: Option<u64>,
}

impl<W: Write + Seek> TrajectoryMcapWriter<W> {
    /// Starts the MCAP file on `sink` (header, schemas, channels). `label` names the output in
    /// errors; a path segment is published every `path_period_s` (and at the end) with poses
    /// spaced at least `path_spacing_s` apart.
    ///
    /// # Errors
    /// [`Error::Mcap`] if writing fails.
    pub fn new(sink: W, label: &str, path_period_s: f64, path_spacing_s: f64) -> Result<Self> {
        let err = |source: mcap::McapError| Error::Mcap { path: label.to_string(), source };
        let mut mcap = WriteOptions::new().profile("").create(sink).map_err(err)?;
        let mut channel = |name: &str, topic: &str| -> Result<u16> {
            let schema = mcap.add_schema(name, "jsonschema", schema_text(name).as_bytes()).map_err(err)?;
            mcap.add_channel(schema, topic, "json", &BTreeMap::new()).map_err(err)
        };
        let pose_channel = channel("foxglove.PoseInFrame", "/uwbimu/pose")?;
        let path_channel = channel("foxglove.PosesInFrame", "/uwbimu/path")?;
        let tf_channel = channel("foxglove.FrameTransform", "/tf")?;
        Ok(Self {
            mcap,
            label: label.to_string(),
            pose_channel,
            path_channel,
            tf_channel,
            sequence: 0,
            path_period_s,
            path_spacing_s,
            path: Vec::new(),
            last_path_pose_s: f64::NEG_INFINITY,
            last_path_message_s: f64::NEG_INFINITY,
            unpublished_path_ns: None,
        })
    }

    /// Writes one point (time s, position m, orientation; identity when absent): its pose and
    /// transform, and a path segment when `path_period_s` has passed since the previous one.
    /// Times are expected in non-decreasing order.
    ///
    /// # Errors
    /// [`Error::Mcap`] or [`Error::Io`] if writing fails.
    pub fn push(&mut self, (t, p, q): &PosePoint) -> Result<()> {
        let q = q.unwrap_or_else(Quat::identity);
        let ns = nanos_of(*t);
        let stamp = stamp_of(ns);
        self.put(self.pose_channel, ns, &json!({"timestamp": stamp, "frame_id": "map", "pose": pose_json(p, &q)}))?;
        self.put(
            self.tf_channel,
            ns,
            &json!({"timestamp": stamp, "parent_frame_id": "map", "child_frame_id": "base_link",
                    "translation": {"x": p.x, "y": p.y, "z": p.z}, "rotation": {"x": q.i, "y": q.j, "z": q.k, "w": q.w}}),
        )?;
        if t - self.last_path_pose_s >= self.path_spacing_s {
            self.path.push(pose_json(p, &q));
            self.last_path_pose_s = *t;
        }
        if t - self.last_path_message_s >= self.path_period_s {
            self.publish_path(ns)?;
            self.last_path_message_s = *t;
            self.unpublished_path_ns = None;
        } else {
            self.unpublished_path_ns = Some(ns);
        }
        Ok(())
    }

    /// Publishes the final path segment (at the last point, unless that point published one)
    /// and writes the MCAP summary and footer; returns the sink.
    ///
    /// # Errors
    /// [`Error::Mcap`] or [`Error::Io`] if writing fails.
    pub fn finish(mut self) -> Result<W> {
        if let Some(ns) = self.unpublished_path_ns.take() {
            self.publish_path(ns)?;
        }
        self.mcap.finish().map_err(|source| Error::Mcap { path: self.label.clone(), source })?;
        Ok(self.mcap.into_inner())
    }

    /// Publishes the gathered path segment at `ns`; the next one starts at its last pose, so the
    /// segments join.
    fn publish_path(&mut self, ns: u64) -> Result<()> {
        self.put(self.path_channel, ns, &json!({"timestamp": stamp_of(ns), "frame_id": "map", "poses": self.path}))?;
        self.path.drain(..self.path.len().saturating_sub(1));
        Ok(())
    }

    /// Writes `message` as the next message of `channel_id` at `ns`.
    fn put(&mut self, channel_id: u16, ns: u64, message: &serde_json::Value) -> Result<()> {
        self.sequence += 1;
        let header = MessageHeader { channel_id, sequence: self.sequence, log_time: ns, publish_time: ns };
        let bytes = serde_json::to_vec(message).map_err(|e| Error::io(&self.label, e.into()))?;
        self.mcap.write_to_known_channel(&header, &bytes).map_err(|source| Error::Mcap { path: self.label.clone(), source })
    }
}

/// Writes `trajectory` (time s, position m, orientation; identity when absent) to `sink`
/// through a [`TrajectoryMcapWriter`]. `label` names the output in errors; a path segment is
/// published every `path_period_s` (and at the end) with poses spaced at least `path_spacing_s`
/// apart.
///
/// # Errors
/// [`Error::Mcap`] or [`Error::Io`] if writing fails.
pub fn write_trajectory_mcap<W: Write + Seek>(
    sink: W,
    label: &str,
    trajectory: &[PosePoint],
    path_period_s: f64,
    path_spacing_s: f64,
) -> Result<()> {
    let mut writer = TrajectoryMcapWriter::new(sink, label, path_period_s, path_spacing_s)?;
    for point in trajectory {
        writer.push(point)?;
    }
    writer.finish().map(drop)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use std::io::Cursor;

    use super::*;

    fn time_of(t_s: f64) -> (u64, serde_json::Value) {
        let ns = (t_s.max(0.0) * 1e9).round() as u64;
        (ns, json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000}))
    }

    /// `write_trajectory_mcap` as it was before [`TrajectoryMcapWriter`], kept to hold the
    /// streaming writer to the same bytes.
    fn old_write_trajectory_mcap<W: Write + Seek>(
        sink: W,
        label: &str,
        trajectory: &[PosePoint],
        path_period_s: f64,
        path_spacing_s: f64,
    ) -> Result<()> {
        let err = |source: mcap::McapError| Error::Mcap { path: label.to_string(), source };
        let mut w = WriteOptions::new().profile("").create(sink).map_err(err)?;
        let mut channel = |name: &str, topic: &str| -> Result<u16> {
            let schema = w.add_schema(name, "jsonschema", schema_text(name).as_bytes()).map_err(err)?;
            w.add_channel(schema, topic, "json", &BTreeMap::new()).map_err(err)
        };
        let pose_ch = channel("foxglove.PoseInFrame", "/uwbimu/pose")?;
        let path_ch = channel("foxglove.PosesInFrame", "/uwbimu/path")?;
        let tf_ch = channel("foxglove.FrameTransform", "/tf")?;
        let mut sequence = 0u32;
        let mut path: Vec<serde_json::Value> = Vec::new();
        let (mut last_path_pose, mut last_path_msg) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        for (k, (t, p, q)) in trajectory.iter().enumerate() {
            let q = q.unwrap_or_else(Quat::identity);
            let (ns, stamp) = time_of(*t);
            let mut put = |channel_id: u16, v: serde_json::Value| -> Result<()> {
                sequence += 1;
                let header = MessageHeader { channel_id, sequence, log_time: ns, publish_time: ns };
                let bytes = serde_json::to_vec(&v).map_err(|e| Error::io(label, e.into()))?;
                w.write_to_known_channel(&header, &bytes).map_err(err)
            };
            put(pose_ch, json!({"timestamp": stamp, "frame_id": "map", "pose": pose_json(p, &q)}))?;
            put(
                tf_ch,
                json!({"timestamp": stamp, "parent_frame_id": "map", "child_frame_id": "base_link",
                       "translation": {"x": p.x, "y": p.y, "z": p.z}, "rotation": {"x": q.i, "y": q.j, "z": q.k, "w": q.w}}),
            )?;
            if t - last_path_pose >= path_spacing_s {
                path.push(pose_json(p, &q));
                last_path_pose = *t;
            }
            if t - last_path_msg >= path_period_s || k + 1 == trajectory.len() {
                put(path_ch, json!({"timestamp": stamp, "frame_id": "map", "poses": path}))?;
                last_path_msg = *t;
                // The next segment starts where this one ends.
                path.drain(..path.len().saturating_sub(1));
            }
        }
        w.finish().map_err(err)?;
        Ok(())
    }

    /// `mcap` with its summary section's records sorted and its summary CRC left out: the MCAP
    /// library writes the summary's schemas and channels in hash-map order, which changes from
    /// one writer to the next. Everything before the summary is kept byte for byte.
    fn canonical(mcap: &[u8]) -> (Vec<u8>, Vec<&[u8]>) {
        const MAGIC: usize = 8;
        const FOOTER: usize = 1 + 8 + 8 + 8 + 4;
        let footer = mcap.len() - MAGIC - FOOTER;
        let summary_start = u64::from_le_bytes(mcap[footer + 9..footer + 17].try_into().unwrap()) as usize;
        let mut records = Vec::new();
        let mut at = summary_start;
        while at < footer {
            let len = u64::from_le_bytes(mcap[at + 1..at + 9].try_into().unwrap()) as usize;
            records.push(&mcap[at..at + 9 + len]);
            at += 9 + len;
        }
        records.sort_unstable();
        ([&mcap[..summary_start], &mcap[footer..footer + FOOTER - 4]].concat(), records)
    }

    fn trajectory(n: usize, dt_s: f64, oriented: bool) -> Vec<PosePoint> {
        (0..n)
            .map(|k| {
                let t = 0.3 + k as f64 * dt_s;
                let q = oriented.then(|| Quat::from_euler_angles(0.1, -0.2, 0.05 * t));
                (t, Vec3::new(t.cos(), 2.0 * t.sin(), 0.1 * t), q)
            })
            .collect()
    }

    #[test]
    fn the_streaming_writer_writes_the_bytes_of_the_whole_trajectory_writer() {
        // (points, time step): two points 0.5 s apart leave the last segment to `finish`, 1.5 s
        // apart publish it at the last push.
        for (n, dt_s) in [(0, 0.01), (1, 0.01), (2, 0.5), (2, 1.5), (1000, 0.01), (1000, 0.013)] {
            for oriented in [false, true] {
                let points = trajectory(n, dt_s, oriented);
                let mut old = Cursor::new(Vec::new());
                old_write_trajectory_mcap(&mut old, "t", &points, 1.0, 0.2).unwrap();
                let mut new = Cursor::new(Vec::new());
                write_trajectory_mcap(&mut new, "t", &points, 1.0, 0.2).unwrap();
                assert_eq!(old.get_ref().len(), new.get_ref().len());
                assert!(canonical(old.get_ref()) == canonical(new.get_ref()), "{n} points {dt_s} s apart, oriented: {oriented}");
            }
        }
    }
}
