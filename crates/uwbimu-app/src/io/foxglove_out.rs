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

use crate::io::{IoError as Error, IoResult as Result};
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

/// Splits non-negative seconds into MCAP nanoseconds and a Foxglove `{sec, nsec}` time.
fn time_of(t_s: f64) -> (u64, serde_json::Value) {
    let ns = (t_s.max(0.0) * 1e9).round() as u64;
    (ns, json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000}))
}

fn pose_json(p: &Vec3, q: &Quat) -> serde_json::Value {
    json!({"position": {"x": p.x, "y": p.y, "z": p.z}, "orientation": {"x": q.i, "y": q.j, "z": q.k, "w": q.w}})
}

/// Writes `trajectory` (time s, position m, orientation; identity when absent) to `sink`.
/// `label` names the output in errors; a path segment is published every `path_period_s` (and
/// at the end) with poses spaced at least `path_spacing_s` apart.
///
/// # Errors
/// [`Error::Io`] if writing fails.
pub fn write_trajectory_mcap<W: Write + Seek>(
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
