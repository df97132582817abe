//! Python function for surveying anchors from anchor-to-anchor ranges
//! ([`uwbimu_estimation::anchor_survey`]).

use numpy::{IntoPyArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_estimation::anchor_survey::{survey_anchors as survey, SurveyPriors};
use uwbimu_vocabulary::error::Error;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::AnchorPair;

use super::convert::{array, matrices_array, points_array, table};
use super::errors::PyResult;

/// Column names of a pair table.
const PAIRS_LAYOUT: &str = "(M, 3) = anchor i, anchor j, range";

/// Surveys the anchors from ranges measured between them: `pairs` `(M, 3)` = anchor i, anchor j
/// (whole numbers), range (m), a pair measured any number of times. `fixed` pins anchors
/// (`{index: [x, y, z]}`, at least three); `heights` `(K,)` gives known mounting heights (NaN
/// where unknown). Returns a dict: `positions` `(K, 3)`, `covariances` `(K, 3, 3)`, `residuals`
/// `(M,)`, `sigma`, `warnings` (list of str) and `frame` (str). Releases the GIL.
#[pyfunction]
#[pyo3(signature = (pairs, *, fixed=None, heights=None))]
fn survey_anchors<'py>(
    py: Python<'py>,
    pairs: &Bound<'py, PyAny>,
    fixed: Option<&Bound<'py, PyDict>>,
    heights: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let rows = table::<3>(&array(pairs, "pairs")?, "pairs", PAIRS_LAYOUT)?;
    let index = |row: usize, v: f64| -> PyResult<usize> {
        if v.fract() == 0.0 && (0.0..1e6).contains(&v) {
            Ok(v as usize)
        } else {
            Err(Error::InvalidValue { name: "pairs", row, value: v, reason: "an anchor index is a whole number >= 0" }.into())
        }
    };
    let pairs: Vec<AnchorPair> = rows
        .iter()
        .enumerate()
        .map(|(row, r)| Ok(AnchorPair { i: index(row, r[0])?, j: index(row, r[1])?, range_m: r[2] }))
        .collect::<PyResult<_>>()?;
    let heights: Vec<f64> = match heights {
        Some(h) if !h.is_none() => array(h, "heights")?.as_array().iter().copied().collect(),
        _ => Vec::new(),
    };
    let mut pinned = Vec::new();
    for (key, value) in fixed.into_iter().flat_map(|d| d.iter()) {
        let k: usize = key.extract().map_err(|_| Error::InvalidCall(format!("fixed: key {key} is not an anchor index")))?;
        let p = array(&value, "fixed")?;
        let v: Vec<f64> = p.as_array().iter().copied().collect();
        let [x, y, z] = v[..] else {
            return Err(
                Error::Shape { name: "fixed", expected: "[x, y, z] per anchor".into(), got: format!("{:?}", p.shape()) }.into()
            );
        };
        pinned.push((k, Vec3::new(x, y, z)));
    }
    let count = pairs.iter().map(|p| p.i.max(p.j) + 1).max().unwrap_or(0).max(heights.len());
    let priors = SurveyPriors { fixed: pinned, heights };
    let s = py.detach(|| survey(&pairs, count, &priors))?;
    let out = PyDict::new(py);
    out.set_item("positions", points_array(py, &s.positions)?)?;
    out.set_item("covariances", matrices_array(py, &s.covariances)?)?;
    out.set_item("residuals", s.residuals_m.into_pyarray(py))?;
    out.set_item("sigma", s.sigma_m)?;
    out.set_item("warnings", s.warnings)?;
    out.set_item("frame", s.frame)?;
    Ok(out)
}

/// Registers the function.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(survey_anchors, m)?)?;
    Ok(())
}
