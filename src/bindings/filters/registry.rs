//! The registries as the module's tables: `METHODS` (the filter methods) and `SENSORS`.

use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_app::methods::Method;
use uwbimu_vocabulary::sensors::SensorKind;

use super::super::errors::PyResult;

/// The sensor registry as a dict by name: `keyword`, `label`, `columns` (the accepted layouts),
/// `rank`, `doc` (the row's doc comment).
pub(super) fn sensors_table<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let table = PyDict::new(py);
    for kind in SensorKind::ALL {
        let info = kind.info();
        let row = PyDict::new(py);
        row.set_item("keyword", info.keyword)?;
        row.set_item("label", info.label)?;
        row.set_item("columns", info.layouts.iter().map(|l| l.to_vec()).collect::<Vec<_>>())?;
        row.set_item("rank", info.rank)?;
        row.set_item("doc", info.doc.lines().map(str::trim).collect::<Vec<_>>().join(" "))?;
        table.set_item(info.name, row)?;
    }
    Ok(table)
}

/// The registry as Python sees it: `{name: {"takes": [...], "smoothing": "never" | "on_request" |
/// "by_default", "streaming_class": str | None, "chooses_model": bool, "summary": str}}`, in
/// registry order (the summary is the first sentence of the row's doc).
pub(super) fn methods_table<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let table = PyDict::new(py);
    for method in Method::ALL {
        let info = method.info();
        let row = PyDict::new(py);
        row.set_item("takes", method.inputs().map(|i| i.name()).collect::<Vec<_>>())?;
        row.set_item("smoothing", info.smoothing.name())?;
        row.set_item("streaming_class", info.streaming_class())?;
        row.set_item("chooses_model", method.chooses_its_model())?;
        row.set_item("summary", method.summary())?;
        table.set_item(info.name, row)?;
    }
    Ok(table)
}
