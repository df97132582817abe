//! Bindings of the DWM1001 UART TLV `dwm_loc_get` decoder ([`uwbimu_io::serial::dwm1001`]): the
//! `DwmDecoder` class (bytes in, responses out as dicts) and `encode_dwm_loc_get` (a response for
//! tests and simulated modules).

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use uwbimu_io::serial::dwm1001::{encode_loc_get, DwmLocation, DwmPosition, DwmRange, DwmStream};
use uwbimu_vocabulary::error::Error;

use super::convert::fields_dict;
use super::errors::PyResult;

/// A position tuple from Python: x, y, z (m) and quality factor.
type PositionTuple = (f64, f64, f64, u8);

/// A DWM1001 `dwm_loc_get` stream decoder (wraps [`DwmStream`]): `feed(data)` returns the
/// responses completed by `data` as dicts, `counts` what was decoded and skipped.
#[pyclass(name = "DwmDecoder", module = "uwbimu_rs._native")]
pub struct PyDwmDecoder(DwmStream);

fn xyz(p: &DwmPosition) -> Vec<f64> {
    vec![p.x_m, p.y_m, p.z_m]
}

fn location_dict<'py>(py: Python<'py>, loc: &DwmLocation) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("status", loc.status)?;
    d.set_item("position", loc.position.as_ref().map(xyz))?;
    d.set_item("position_quality", loc.position.as_ref().map(|p| p.quality))?;
    let ranges = PyList::empty(py);
    for r in &loc.ranges {
        let rd = PyDict::new(py);
        rd.set_item("anchor_id", r.anchor_id)?;
        rd.set_item("range", r.range_m)?;
        rd.set_item("quality", r.quality)?;
        rd.set_item("anchor_position", r.anchor_position.as_ref().map(xyz))?;
        ranges.append(rd)?;
    }
    d.set_item("ranges", ranges)?;
    Ok(d)
}

#[pymethods]
impl PyDwmDecoder {
    /// An empty decoder.
    #[new]
    fn new() -> Self {
        Self(DwmStream::new())
    }

    /// Appends `data` (bytes read from the port, cut anywhere) and returns the responses it
    /// completed, oldest first, each a dict (see the stub for the keys).
    fn feed<'py>(&mut self, py: Python<'py>, data: &[u8]) -> PyResult<Bound<'py, PyList>> {
        let mut responses = Vec::new();
        self.0.push_into(data, &mut responses);
        let out = PyList::empty(py);
        for r in &responses {
            out.append(location_dict(py, r)?)?;
        }
        Ok(out)
    }

    /// What was decoded and skipped so far (a dict of ints).
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        fields_dict(py, &self.0.counts())
    }

    /// Bytes held back: the start of a response not yet complete.
    #[getter]
    fn buffered(&self) -> usize {
        self.0.buffered_len()
    }

    fn __repr__(&self) -> String {
        let c = self.0.counts();
        format!(
            "DwmDecoder(responses={}, errors={}, bytes_skipped={}, buffered={})",
            c.responses,
            c.errors,
            c.bytes_skipped,
            self.0.buffered_len()
        )
    }
}

fn position(p: PositionTuple) -> DwmPosition {
    DwmPosition { x_m: p.0, y_m: p.1, z_m: p.2, quality: p.3 }
}

/// Encodes one successful `dwm_loc_get` response as bytes: the node's `position`
/// `(x, y, z, quality)` (m; `None` leaves the position frame out) and `ranges`, each
/// `(anchor_id, range_m, quality, anchor_position)` with `anchor_position` `(x, y, z, quality)` or
/// `None`, in a `0x49` block (`tag`) or a `0x48` block. Values are rounded to whole millimetres;
/// raises ValueError for more ranges than a block holds (12 tag, 19 anchor).
#[pyfunction]
#[pyo3(signature = (position, ranges, *, tag=true))]
fn encode_dwm_loc_get<'py>(
    py: Python<'py>,
    position: Option<PositionTuple>,
    ranges: Vec<(u64, f64, u8, Option<PositionTuple>)>,
    tag: bool,
) -> PyResult<Bound<'py, PyBytes>> {
    let loc = DwmLocation {
        status: 0,
        position: position.map(self::position),
        ranges: ranges
            .into_iter()
            .map(|(anchor_id, range_m, quality, p)| DwmRange {
                anchor_id,
                range_m,
                quality,
                anchor_position: p.map(self::position),
            })
            .collect(),
    };
    let bytes = encode_loc_get(&loc, tag).map_err(|e| Error::InvalidCall(e.to_string()))?;
    Ok(PyBytes::new(py, &bytes))
}

/// Registers the class and the function.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDwmDecoder>()?;
    m.add_function(wrap_pyfunction!(encode_dwm_loc_get, m)?)?;
    Ok(())
}
