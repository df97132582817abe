//! Bindings of the Nooploop LinkTrack frame decoder ([`uwbimu_io::serial::linktrack`]): the
//! `LinkTrackDecoder` class (bytes in, frames out as dicts) and `encode_linktrack_node_frame2`
//! (a `NodeFrame2` for tests and simulated devices).

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use uwbimu_io::serial::linktrack::{encode_node_frame2, LinkTrackFrame, LinkTrackStream, NodeFrame2, NodeRange2, TagFrame0};
use uwbimu_vocabulary::error::Error;

use super::convert::fields_dict;
use super::errors::PyResult;

/// The role byte of an anchor in LinkTrack frames.
const ROLE_ANCHOR: u8 = 1;

/// A LinkTrack serial stream decoder (wraps [`LinkTrackStream`]): `feed(data)` returns the frames
/// completed by `data` as dicts, `counts` what was decoded and skipped.
#[pyclass(name = "LinkTrackDecoder", module = "uwbimu_rs._native")]
pub struct PyLinkTrackDecoder(LinkTrackStream);

/// The fields both frame kinds share, into `d`.
#[allow(clippy::too_many_arguments)]
fn common_fields(
    d: &Bound<'_, PyDict>,
    kind: &str,
    role: u8,
    id: u8,
    local_time_ms: u32,
    system_time_ms: u32,
    position: &[f64; 3],
    velocity: &[f64; 3],
    gyro: &[f64; 3],
    accel: &[f64; 3],
    angle: &[f64; 3],
    quaternion: &[f64; 4],
    eop: &[f64; 3],
    voltage: f64,
) -> PyResult<()> {
    d.set_item("kind", kind)?;
    d.set_item("id", id)?;
    d.set_item("role", role)?;
    d.set_item("local_time_ms", local_time_ms)?;
    d.set_item("system_time_ms", system_time_ms)?;
    d.set_item("position", position.to_vec())?;
    d.set_item("velocity", velocity.to_vec())?;
    d.set_item("gyro", gyro.to_vec())?;
    d.set_item("accel", accel.to_vec())?;
    d.set_item("angle", angle.to_vec())?;
    d.set_item("quaternion", quaternion.to_vec())?;
    d.set_item("eop", eop.to_vec())?;
    d.set_item("voltage", voltage)?;
    Ok(())
}

fn node_frame2_dict<'py>(py: Python<'py>, f: &NodeFrame2) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    common_fields(
        &d,
        "node_frame2",
        f.role,
        f.id,
        f.local_time_ms,
        f.system_time_ms,
        &f.position_m,
        &f.velocity_mps,
        &f.gyro_rad_s,
        &f.accel_mps2,
        &f.angle_deg,
        &f.quaternion_wxyz,
        &f.eop_m,
        f.voltage_v,
    )?;
    let nodes = PyList::empty(py);
    for n in &f.nodes {
        let nd = PyDict::new(py);
        nd.set_item("id", n.id)?;
        nd.set_item("role", n.role)?;
        nd.set_item("range", n.range_m)?;
        nd.set_item("fp_rssi", n.fp_rssi_dbm)?;
        nd.set_item("rx_rssi", n.rx_rssi_dbm)?;
        nd.set_item("system_time_ms", n.system_time_ms)?;
        nodes.append(nd)?;
    }
    d.set_item("nodes", nodes)?;
    Ok(d)
}

fn tag_frame0_dict<'py>(py: Python<'py>, f: &TagFrame0) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    common_fields(
        &d,
        "tag_frame0",
        f.role,
        f.id,
        f.local_time_ms,
        f.system_time_ms,
        &f.position_m,
        &f.velocity_mps,
        &f.gyro_rad_s,
        &f.accel_mps2,
        &f.angle_deg,
        &f.quaternion_wxyz,
        &f.eop_m,
        f.voltage_v,
    )?;
    d.set_item("distances", f.distances_m.to_vec())?;
    Ok(d)
}

#[pymethods]
impl PyLinkTrackDecoder {
    /// An empty decoder.
    #[new]
    fn new() -> Self {
        Self(LinkTrackStream::new())
    }

    /// Appends `data` (bytes read from the port, cut anywhere) and returns the frames it
    /// completed, oldest first, each a dict (see the stub for the keys).
    fn feed<'py>(&mut self, py: Python<'py>, data: &[u8]) -> PyResult<Bound<'py, PyList>> {
        let mut frames = Vec::new();
        self.0.push_into(data, &mut frames);
        let out = PyList::empty(py);
        for f in &frames {
            match f {
                LinkTrackFrame::NodeFrame2(f) => out.append(node_frame2_dict(py, f)?)?,
                LinkTrackFrame::TagFrame0(f) => out.append(tag_frame0_dict(py, f)?)?,
            }
        }
        Ok(out)
    }

    /// What was decoded and skipped so far (a dict of ints).
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        fields_dict(py, &self.0.counts())
    }

    /// Bytes held back: the start of a frame not yet complete.
    #[getter]
    fn buffered(&self) -> usize {
        self.0.buffered_len()
    }

    fn __repr__(&self) -> String {
        let c = self.0.counts();
        format!(
            "LinkTrackDecoder(frames={}, checksum_errors={}, bytes_skipped={}, buffered={})",
            c.frames,
            c.checksum_errors,
            c.bytes_skipped,
            self.0.buffered_len()
        )
    }
}

/// Encodes one LinkTrack `NodeFrame2` (what a tag sends, with its ranges to anchors) as bytes,
/// checksum included. `nodes` holds `(anchor_id, range_m, fp_rssi_dbm, rx_rssi_dbm)` per anchor
/// (role anchor, measured at `system_time_ms`); the vectors left out are zeros, the quaternion
/// identity. Values are rounded to the wire's steps.
#[pyfunction]
#[pyo3(signature = (id, local_time_ms, gyro, accel, nodes, *, role=2, system_time_ms=0, position=None, velocity=None, quaternion=None, angle=None, eop=None, voltage=5.0))]
#[allow(clippy::too_many_arguments)]
fn encode_linktrack_node_frame2<'py>(
    py: Python<'py>,
    id: u8,
    local_time_ms: u32,
    gyro: [f64; 3],
    accel: [f64; 3],
    nodes: Vec<(u8, f64, f64, f64)>,
    role: u8,
    system_time_ms: u32,
    position: Option<[f64; 3]>,
    velocity: Option<[f64; 3]>,
    quaternion: Option<[f64; 4]>,
    angle: Option<[f64; 3]>,
    eop: Option<[f64; 3]>,
    voltage: f64,
) -> PyResult<Bound<'py, PyBytes>> {
    let frame = NodeFrame2 {
        role,
        id,
        local_time_ms,
        system_time_ms,
        eop_m: eop.unwrap_or_default(),
        position_m: position.unwrap_or_default(),
        velocity_mps: velocity.unwrap_or_default(),
        gyro_rad_s: gyro,
        accel_mps2: accel,
        angle_deg: angle.unwrap_or_default(),
        quaternion_wxyz: quaternion.unwrap_or([1.0, 0.0, 0.0, 0.0]),
        voltage_v: voltage,
        nodes: nodes
            .into_iter()
            .map(|(id, range_m, fp_rssi_dbm, rx_rssi_dbm)| NodeRange2 {
                role: ROLE_ANCHOR,
                id,
                range_m,
                fp_rssi_dbm,
                rx_rssi_dbm,
                system_time_ms,
            })
            .collect(),
    };
    let bytes = encode_node_frame2(&frame).map_err(|e| Error::InvalidCall(e.to_string()))?;
    Ok(PyBytes::new(py, &bytes))
}

/// Registers the class and the function.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLinkTrackDecoder>()?;
    m.add_function(wrap_pyfunction!(encode_linktrack_node_frame2, m)?)?;
    Ok(())
}
