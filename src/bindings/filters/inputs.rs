//! The arrays of a call read and validated: IMU, ranges and anchors ([`Inputs`]), the other
//! sensors' observations, and one batch log with its configuration ([`Log`]).

use numpy::PyUntypedArrayMethods;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_app::methods::BatchInput;
use uwbimu_vocabulary::anchor_ids::AnchorIds;
use uwbimu_vocabulary::config::{FilterConfig, InitialState, MAX_TAGS};
use uwbimu_vocabulary::error::Error;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::sensors::{merge, Observation, SensorKind};
use uwbimu_vocabulary::validate;

use super::super::convert::{array, rows, table};
use super::super::errors::PyResult;
use super::args::vec3_arg;
use super::config::read_config;
use super::state::read_optional_initial;

const IMU_LAYOUT: &str = "(N, 7) = t, ax, ay, az, gx, gy, gz";
const RANGES_LAYOUT: &str = "(M, 3) = t, anchor index, range, or (M, 4) = t, anchor index, range, tag";
const ANCHORS_LAYOUT: &str = "(K, 3) = x, y, z";

/// Reads and validates the sensor arrays of keyword arguments `sensors` (`{keyword: array}`, the
/// keywords of the sensor registry; a None value is no data) into one time-ordered sequence;
/// with anchors by hardware id (`ids`), the anchor columns hold ids. An unknown keyword raises
/// `ValueError` listing the sensors' keywords.
pub(crate) fn read_observations(
    sensors: Option<&Bound<'_, PyDict>>,
    anchor_count: usize,
    ids: Option<&AnchorIds>,
) -> PyResult<Vec<Observation>> {
    let mut sets = Vec::new();
    for (key, value) in sensors.into_iter().flat_map(|d| d.iter()) {
        let keyword: String = key.extract()?;
        let kind = SensorKind::ALL.iter().copied().find(|k| k.info().keyword == keyword).ok_or_else(|| {
            Error::unknown_option("keyword argument", &keyword, SensorKind::ALL.iter().map(|k| k.info().keyword))
        })?;
        if value.is_none() {
            continue;
        }
        let info = kind.info();
        let mut table = rows(&array(&value, info.keyword)?, info.keyword, info.layouts)?;
        if let Some(ids) = ids {
            ids.to_rows(info.keyword, &mut table, info.anchor_columns)?;
        }
        let table: Vec<&[f64]> = table.iter().map(Vec::as_slice).collect();
        sets.push(kind.observations(&table, anchor_count)?);
    }
    let sets: Vec<&[Observation]> = sets.iter().map(Vec::as_slice).collect();
    Ok(merge(&sets))
}

/// One log as the batch functions take it: validated arrays, configuration and initial state.
pub(crate) struct Log {
    inputs: Inputs,
    config: FilterConfig,
    initial: Option<InitialState>,
    observations: Vec<Observation>,
}

impl Log {
    /// Reads and validates the arrays, then the configuration and the optional initial state
    /// (no other sensor: [`Log::with_sensors`]).
    pub(crate) fn read(
        imu: &Bound<'_, PyAny>,
        ranges: &Bound<'_, PyAny>,
        anchors: &Bound<'_, PyAny>,
        initial: Option<&Bound<'_, PyAny>>,
        config: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let inputs = read_inputs(imu, ranges, anchors)?;
        Ok(Self { inputs, config: read_config(config)?, initial: read_optional_initial(initial)?, observations: Vec::new() })
    }

    /// The log with the arrays of the other sensors, keyword arguments `sensors`
    /// ([`read_observations`]).
    pub(super) fn with_sensors(self, sensors: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let observations = read_observations(sensors, self.inputs.anchors.len(), self.inputs.anchor_ids.as_ref())?;
        Ok(Self { observations, ..self })
    }

    /// The batch input over the log.
    pub(crate) fn batch(&self, smooth: bool) -> BatchInput<'_> {
        BatchInput {
            imu: &self.inputs.imu,
            ranges: &self.inputs.ranges,
            anchors: &self.inputs.anchors,
            initial: self.initial.as_ref(),
            config: &self.config,
            smooth,
            observations: &self.observations,
            progress: None,
            marginals_every_s: None,
        }
    }
}

/// Validated arrays of one batch call.
pub(crate) struct Inputs {
    pub(crate) imu: Vec<ImuSample>,
    pub(crate) ranges: Vec<RangeMeasurement>,
    pub(crate) anchors: Vec<Vec3>,
    /// The anchors' hardware ids when they were given by id ([`read_anchors`]).
    pub(crate) anchor_ids: Option<AnchorIds>,
}

/// The `anchors` argument: a `(K, 3)` array of positions, whose rows are the anchor indices, or
/// a dict `{id: [x, y, z]}` of anchors by hardware id (rows in the dict's order), whose ids the
/// anchor columns of ranges and TDoA and the streaming calls then hold.
pub(super) fn read_anchors(obj: &Bound<'_, PyAny>) -> PyResult<(Vec<Vec3>, Option<AnchorIds>)> {
    let Ok(by_id) = obj.cast::<PyDict>() else {
        return Ok((validate::anchors(&table::<3>(&array(obj, "anchors")?, "anchors", ANCHORS_LAYOUT)?)?, None));
    };
    let (mut ids, mut rows) = (Vec::with_capacity(by_id.len()), Vec::with_capacity(by_id.len()));
    for (key, position) in by_id.iter() {
        let id = key.extract::<f64>().ok().or_else(|| key.extract::<String>().ok()?.trim().parse().ok());
        let Some(id) = id else {
            let reason = "an anchor id is a whole number (the dict maps hardware ids to [x, y, z])".into();
            return Err(Error::BadArgument { call: "anchors", arg: format!("key {key}"), reason }.into());
        };
        ids.push(id);
        rows.push(vec3_arg("anchors", &position, "anchors")?.into());
    }
    Ok((validate::anchors(&rows)?, Some(AnchorIds::new(&ids)?)))
}

pub(crate) fn read_inputs(imu: &Bound<'_, PyAny>, ranges: &Bound<'_, PyAny>, anchors: &Bound<'_, PyAny>) -> PyResult<Inputs> {
    let (anchors, anchor_ids) = read_anchors(anchors)?;
    let imu = validate::imu(&table::<7>(&array(imu, "imu")?, "imu", IMU_LAYOUT)?)?;
    let ranges = array(ranges, "ranges")?;
    let ranges = match ranges.shape() {
        [_, 4] => {
            let mut table = table::<4>(&ranges, "ranges", RANGES_LAYOUT)?;
            if let Some(ids) = &anchor_ids {
                ids.to_rows("ranges", &mut table, &[1])?;
            }
            validate::tagged_ranges(&table, anchors.len(), MAX_TAGS)?
        }
        _ => {
            let mut table = table::<3>(&ranges, "ranges", RANGES_LAYOUT)?;
            if let Some(ids) = &anchor_ids {
                ids.to_rows("ranges", &mut table, &[1])?;
            }
            validate::ranges(&table, anchors.len())?
        }
    };
    Ok(Inputs { imu, ranges, anchors, anchor_ids })
}
