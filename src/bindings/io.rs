//! Bindings of the MCAP reader and replay: `read_mcap` (columns of IMU, ranges, TDoA, anchors,
//! ground truth), `replay` (the `uwbimu-replay` core, streamed from the file: survey,
//! self-initialise, filter, statistics; only the output columns are kept) and `read_truth` (a
//! ground-truth CSV).

use std::path::{Path, PathBuf};

use pyo3::exceptions::PyFileNotFoundError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use uwbimu_app::columns::{output_columns, step_column_names, step_row};
use uwbimu_app::methods::Method;
use uwbimu_app::replay::replay as replay_recording;
use uwbimu_app::replay::streamed::{replay_streamed, StreamedInput};
use uwbimu_app::replay::ReplaySummary;
use uwbimu_app::replay_config::ReplayConfig;
use uwbimu_io::files::truth_file::{read_truth_csv, TRUTH_COLUMNS};
use uwbimu_io::recordings::mcap_read::McapEnd;
use uwbimu_io::recordings::recording_out::{write_recording_mcap, RecordingStreams};
use uwbimu_io::{read_recording_file, survey_recording_file, IoError, Mapping, ReadStats, Recording, RecordingSurvey};
use uwbimu_vocabulary::sensors::SensorKind;

use super::convert::columns;
use super::errors::PyResult;
use super::filters::{read_config, read_inputs, read_observations, read_optional_initial};
use super::interruptible::run_interruptible;
use crate::cli::progress::Bar;

/// The replay settings from an optional TOML file with an optional mapping (JSON text) merged
/// into its `[mapping]` ([`Mapping::merged_with_json`]).
pub(super) fn settings(config_file: Option<&Path>, mapping_json: Option<&str>) -> PyResult<ReplayConfig> {
    let mut cfg = match config_file {
        Some(p) => ReplayConfig::read(p)?,
        None => ReplayConfig::from_toml("", Path::new("."))?,
    };
    if let Some(m) = mapping_json {
        cfg.mapping = cfg.mapping.merged_with_json(m)?;
    }
    Ok(cfg)
}

fn missing_file(path: &Path) -> PyErr {
    PyFileNotFoundError::new_err(format!("{}: no such file", path.display()))
}

/// Reads the recording with the GIL released; with `progress`, a bar of the bytes read on stderr.
fn read(py: Python<'_>, path: &Path, mapping: &Mapping, progress: bool) -> PyResult<Recording> {
    let rec = with_read_bar(py, path, progress, |bar| read_recording_file(path, mapping, bar))?;
    warn_if_truncated(py, path, &rec.stats)?;
    Ok(rec)
}

/// The first pass of a streamed replay ([`survey_recording_file`]), as [`read`].
fn survey(py: Python<'_>, path: &Path, mapping: &Mapping, progress: bool) -> PyResult<RecordingSurvey> {
    let survey = with_read_bar(py, path, progress, |bar| survey_recording_file(path, mapping, bar))?;
    warn_if_truncated(py, path, &survey.stats)?;
    Ok(survey)
}

/// Runs `read` on `path` with the GIL released, giving it the progress callback of a bar of the
/// bytes read (with `progress`); fails first if there is no such file.
fn with_read_bar<T: Send>(
    py: Python<'_>,
    path: &Path,
    progress: bool,
    read: impl FnOnce(&mut dyn FnMut(u64)) -> uwbimu_io::IoResult<T> + Send,
) -> PyResult<T> {
    if !path.exists() {
        return Err(missing_file(path).into());
    }
    let size = std::fs::metadata(path).map_or(0, |m| m.len());
    let mut bar = progress.then(|| Bar::new("reading", size));
    Ok(py.detach(|| read(&mut |n| bar.iter_mut().for_each(|b| b.update(n))))?)
}

/// Warns (a `UserWarning`) when the recording ended before its footer.
fn warn_if_truncated(py: Python<'_>, path: &Path, stats: &ReadStats) -> PyResult<()> {
    if let Some(w) = stats.end.warning(&path.display().to_string()) {
        super::errors::warn_all(py, &[w])?;
    }
    Ok(())
}

fn stats_dict<'py>(py: Python<'py>, s: &ReadStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let topics = PyList::empty(py);
    for t in &s.topics {
        let td = PyDict::new(py);
        td.set_item("topic", &t.topic)?;
        td.set_item("schema", &t.schema)?;
        td.set_item("encoding", &t.encoding)?;
        td.set_item("count", t.count)?;
        td.set_item("role", t.role.name())?;
        topics.append(td)?;
    }
    d.set_item("topics", topics)?;
    d.set_item("duration_s", s.duration_s())?;
    d.set_item("late_dropped", s.late_dropped)?;
    d.set_item("reordered", s.reordered)?;
    d.set_item("imu_duplicates", s.imu_duplicates)?;
    d.set_item("unknown_anchor", s.unknown_anchor)?;
    d.set_item("tdoa_unknown_anchor", s.tdoa_unknown_anchor)?;
    d.set_item("tdoa_unknown_ids", s.tdoa_unknown_ids.iter().collect::<Vec<_>>())?;
    d.set_item("tdoa_bad_value", s.tdoa_bad_value)?;
    d.set_item("unknown_tag", s.unknown_tag)?;
    d.set_item("unknown_tag_ids", s.unknown_tag_ids.iter().collect::<Vec<_>>())?;
    let sensors = PyDict::new(py);
    for (kind, c) in &s.sensors {
        let counts = PyDict::new(py);
        counts.set_item("used", c.used)?;
        counts.set_item("invalid", c.invalid)?;
        sensors.set_item(kind.info().name, counts)?;
    }
    d.set_item("sensors", sensors)?;
    d.set_item("anchor_source", s.anchor_source)?;
    d.set_item("log_time_stamps", s.log_time_stamps)?;
    d.set_item("messages", s.messages)?;
    d.set_item("complete", s.end == McapEnd::Complete)?;
    let invalid = PyDict::new(py);
    for (id, c) in &s.per_anchor {
        invalid.set_item(id, c.invalid)?;
    }
    d.set_item("invalid_per_anchor", invalid)?;
    Ok(d)
}

/// Reads an MCAP file through a mapping (JSON text of the `[mapping]` table) and/or a replay TOML
/// file. Returns a dict: `imu`, `ranges` (with `tag`), `tdoa`, `anchors`, `ground_truth` and, for
/// each other sensor the mapping reads (`altitude`, `odometry`), its table (dicts of columns),
/// `anchor_ids` (list of str) and `stats` (dict).
#[pyfunction]
#[pyo3(signature = (path, *, mapping=None, config_file=None))]
fn read_mcap<'py>(
    py: Python<'py>,
    path: PathBuf,
    mapping: Option<&str>,
    config_file: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let cfg = settings(config_file.as_deref(), mapping)?;
    let rec = read(py, &path, &cfg.mapping, false)?;
    let out = PyDict::new(py);
    let col = |f: &dyn Fn(usize) -> f64, n: usize| (0..n).map(f).collect::<Vec<f64>>();
    let (imu, ranges, tdoa, gt) = (&rec.imu, &rec.ranges, &rec.tdoa, &rec.ground_truth);
    out.set_item(
        "imu",
        columns(
            py,
            vec![
                ("t", col(&|i| imu[i].t_s, imu.len())),
                ("ax", col(&|i| imu[i].accel.x, imu.len())),
                ("ay", col(&|i| imu[i].accel.y, imu.len())),
                ("az", col(&|i| imu[i].accel.z, imu.len())),
                ("gx", col(&|i| imu[i].gyro.x, imu.len())),
                ("gy", col(&|i| imu[i].gyro.y, imu.len())),
                ("gz", col(&|i| imu[i].gyro.z, imu.len())),
            ],
        )?,
    )?;
    out.set_item(
        "ranges",
        columns(
            py,
            vec![
                ("t", col(&|i| ranges[i].t_s, ranges.len())),
                ("anchor", col(&|i| ranges[i].anchor as f64, ranges.len())),
                ("range", col(&|i| ranges[i].range_m, ranges.len())),
                ("variance", rec.range_variances.clone()),
                ("tag", col(&|i| ranges[i].tag as f64, ranges.len())),
            ],
        )?,
    )?;
    for kind in SensorKind::ALL.iter().filter(|k| rec.observations.iter().any(|o| o.kind() == **k)) {
        let (width, values) = kind.table(&rec.observations);
        let names = kind.info().layouts.iter().find(|l| l.len() == width).copied().unwrap_or_default();
        let table = names.iter().enumerate().map(|(c, name)| (*name, values.iter().skip(c).step_by(width).copied().collect()));
        out.set_item(kind.info().name, columns(py, table.collect())?)?;
    }
    out.set_item(
        "tdoa",
        columns(
            py,
            vec![
                ("t", col(&|k| tdoa[k].t_s, tdoa.len())),
                ("i", col(&|k| tdoa[k].anchor_i as f64, tdoa.len())),
                ("j", col(&|k| tdoa[k].anchor_j as f64, tdoa.len())),
                ("d_ij", col(&|k| tdoa[k].tdoa_m, tdoa.len())),
            ],
        )?,
    )?;
    let a = &rec.anchors;
    out.set_item(
        "anchors",
        columns(py, vec![("x", col(&|i| a[i].x, a.len())), ("y", col(&|i| a[i].y, a.len())), ("z", col(&|i| a[i].z, a.len()))])?,
    )?;
    out.set_item("anchor_ids", rec.anchor_ids.clone())?;
    out.set_item(
        "ground_truth",
        columns(
            py,
            vec![
                ("t", col(&|i| gt[i].0, gt.len())),
                ("x", col(&|i| gt[i].1.x, gt.len())),
                ("y", col(&|i| gt[i].1.y, gt.len())),
                ("z", col(&|i| gt[i].1.z, gt.len())),
            ],
        )?,
    )?;
    out.set_item("stats", stats_dict(py, &rec.stats)?)?;
    Ok(out)
}

/// Reads an MCAP file and replays it through `method` (None: the config file's, else `best`)
/// from `initial` (None: the config file's `[initial]`, else self-initialisation); the same core
/// as the `uwbimu-replay` binary. `config` replaces the config file's `[config]`; `overrides`
/// (a config dict) sets its keys over the result. `ground_truth` is a truth CSV (the CLI's `--ground-truth`);
/// `progress` draws bars on stderr. Returns `(columns, info)`; info holds the keys of the CLI's
/// `--json` summary plus `stats`, `health` and `warnings`.
#[pyfunction]
#[pyo3(signature = (path, method=None, *, mapping=None, config_file=None, config=None, overrides=None, initial=None, smooth=None, ground_truth=None, progress=false))]
#[allow(clippy::too_many_arguments)] // the Python keyword arguments
fn replay<'py>(
    py: Python<'py>,
    path: PathBuf,
    method: Option<&str>,
    mapping: Option<&str>,
    config_file: Option<PathBuf>,
    config: Option<&Bound<'py, PyAny>>,
    overrides: Option<&Bound<'py, PyAny>>,
    initial: Option<&Bound<'py, PyAny>>,
    smooth: Option<bool>,
    ground_truth: Option<PathBuf>,
    progress: bool,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
    let mut cfg = settings(config_file.as_deref(), mapping)?;
    if config.is_some_and(|c| !c.is_none()) {
        cfg.config = read_config(config)?;
    }
    if let Some(keys) = overrides.filter(|o| !o.is_none()) {
        super::filters::apply_config_dict(&mut cfg.config, keys)?;
    }
    if let Some(i) = read_optional_initial(initial)? {
        cfg.initial = Some(i);
    }
    if let Some(file) = ground_truth {
        if !file.exists() {
            return Err(missing_file(&file).into());
        }
        cfg.mapping.ground_truth.file = Some(file);
    }
    let method = cfg.method_or(method)?;
    let smooth = method.smooth(smooth);
    if method == Method::UwbLs {
        return replay_whole(py, &path, &cfg, method, smooth, progress);
    }
    let survey = survey(py, &path, &cfg.mapping, progress)?;
    let names = step_column_names(false);
    let mut values: Vec<Vec<f64>> = vec![Vec::with_capacity(survey.n_imu); names.len()];
    let dir = std::env::temp_dir();
    let result = run_interruptible(py, progress, survey.n_imu as u64, |p| {
        let input = StreamedInput {
            path: &path,
            mapping: &cfg.mapping,
            survey: &survey,
            config: &cfg.config,
            initial: cfg.initial.as_ref(),
            smooth,
            progress: Some(p),
            spill_dir: &dir,
        };
        let mut row = Vec::with_capacity(names.len());
        replay_streamed(method, &input, &mut |s| {
            step_row(s, false, &mut row);
            values.iter_mut().zip(&row).for_each(|(column, v)| column.push(*v));
            Ok(())
        })
    })??;
    let info = info_dict(py, &result.summary(method, &survey), &survey.stats)?;
    info.set_item("health", super::filters::health_dict(py, &result.health)?)?;
    info.set_item("warnings", result.warnings.clone())?;
    super::errors::warn_all(py, &result.warnings)?;
    Ok((columns(py, names.into_iter().zip(values).collect())?, info))
}

/// The info dict of a replay: the summary's keys, and `stats` (what reading found).
fn info_dict<'py>(py: Python<'py>, summary: &ReplaySummary, stats: &ReadStats) -> PyResult<Bound<'py, PyDict>> {
    let text =
        serde_json::to_string(summary).map_err(|e| IoError::Format { what: "replay summary".into(), reason: e.to_string() })?;
    let info = py.import("json")?.call_method1("loads", (text,))?.cast_into::<PyDict>().map_err(PyErr::from)?;
    info.set_item("stats", stats_dict(py, stats)?)?;
    Ok(info)
}

/// [`replay`] of a method that needs no IMU (`uwb_ls`): reads the whole recording.
fn replay_whole<'py>(
    py: Python<'py>,
    path: &Path,
    cfg: &ReplayConfig,
    method: Method,
    smooth: bool,
    progress: bool,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
    let rec = read(py, path, &cfg.mapping, progress)?;
    let result = run_interruptible(py, progress, rec.imu.len() as u64, |p| {
        replay_recording(&rec, method, &cfg.config, cfg.initial.as_ref(), smooth, Some(p))
    })??;
    let info = info_dict(py, &result.summary(&rec)?, &rec.stats)?;
    Ok((columns(py, output_columns(&result.output, false))?, info))
}

/// Reads a ground-truth CSV (header `t,x,y,z` or `t_s,x_m,y_m,z_m`, or none) into columns
/// `t, x, y, z` (s, m), sorted by time.
#[pyfunction]
fn read_truth<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    if !path.exists() {
        return Err(missing_file(&path).into());
    }
    let truth = py.detach(|| read_truth_csv(&path))?;
    let col = |f: fn(&(f64, uwbimu_vocabulary::math::Vec3)) -> f64| truth.iter().map(f).collect::<Vec<f64>>();
    columns(py, vec![("t", col(|g| g.0)), ("x", col(|g| g.1.x)), ("y", col(|g| g.1.y)), ("z", col(|g| g.1.z))])
}

/// Writes a recording as MCAP: IMU as CDR `sensor_msgs/msg/Imu` on `/imu`, ranges as JSON
/// `uwbimu.UwbRange` on `/uwb` (anchor ids `A0`, `A1`, ...; a tag beyond 0 in `tag`), the other
/// sensors' arrays `sensors` (keywords of the registry) on their topics
/// ([`uwbimu_io::mapping::topics::SensorIo::written`]), anchors in the `uwbimu.anchors` metadata
/// record; zstd chunks.
#[pyfunction]
#[pyo3(signature = (path, imu, ranges, anchors, *, range_std=None, **sensors))]
fn write_mcap(
    py: Python<'_>,
    path: PathBuf,
    imu: &Bound<'_, PyAny>,
    ranges: &Bound<'_, PyAny>,
    anchors: &Bound<'_, PyAny>,
    range_std: Option<f64>,
    sensors: Option<&Bound<'_, PyDict>>,
) -> PyResult<()> {
    let inputs = read_inputs(imu, ranges, anchors)?;
    let observations = read_observations(sensors, inputs.anchors.len(), inputs.anchor_ids.as_ref())?;
    let label = path.display().to_string();
    py.detach(|| {
        let file = std::fs::File::create(&path).map_err(|e| IoError::io(&label, e))?;
        let sink = std::io::BufWriter::new(file);
        let streams =
            RecordingStreams { imu: &inputs.imu, ranges: &inputs.ranges, observations: &observations, anchors: &inputs.anchors };
        write_recording_mcap(sink, &label, &streams, range_std, true)
    })?;
    Ok(())
}

/// Registers the functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_mcap, m)?)?;
    m.add_function(wrap_pyfunction!(replay, m)?)?;
    m.add_function(wrap_pyfunction!(read_truth, m)?)?;
    // The accepted column names of a ground-truth table: one list of spellings per column.
    m.add("TRUTH_COLUMNS", TRUTH_COLUMNS.iter().map(|names| names.to_vec()).collect::<Vec<_>>())?;
    m.add_function(wrap_pyfunction!(write_mcap, m)?)?;
    Ok(())
}
