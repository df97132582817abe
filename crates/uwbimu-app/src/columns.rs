//! Named columns of a batch output (the `run_filter` DataFrame layout), shared by the Python
//! bindings and the CSV writer of `uwbimu-replay`.

use uwbimu_estimation::multilateration::Fix;
use uwbimu_estimation::pipeline::{StepRecord, Trace};

use crate::run::BatchOutput;

/// Columns as (name, values).
pub type Columns = Vec<(&'static str, Vec<f64>)>;

const COV_ENTRIES: [(&str, usize, usize); 6] =
    [("cov_xx", 0, 0), ("cov_xy", 0, 1), ("cov_xz", 0, 2), ("cov_yy", 1, 1), ("cov_yz", 1, 2), ("cov_zz", 2, 2)];

/// Declares the step columns before the covariance entries once: their names
/// (`STEP_NAMES`) and their values in a record (`step_values`, one inlined function rather than
/// a call per column).
macro_rules! step_fields {
    ($($name:literal => |$r:ident| $value:expr),+ $(,)?) => {
        /// The names of the step columns before the covariance entries.
        const STEP_NAMES: &[&str] = &[$($name),+];

        /// The values of the step columns of `record` before the covariance entries.
        fn step_values(record: &StepRecord) -> [f64; STEP_NAMES.len()] {
            [$({
                let $r = record;
                $value
            }),+]
        }
    };
}

step_fields! {
    "t" => |r| r.t_s,
    "x" => |r| r.state.position.x,
    "y" => |r| r.state.position.y,
    "z" => |r| r.state.position.z,
    "vx" => |r| r.state.velocity.x,
    "vy" => |r| r.state.velocity.y,
    "vz" => |r| r.state.velocity.z,
    "qw" => |r| r.state.orientation.w,
    "qx" => |r| r.state.orientation.i,
    "qy" => |r| r.state.orientation.j,
    "qz" => |r| r.state.orientation.k,
    "std_x" => |r| r.position_cov[(0, 0)].sqrt(),
    "std_y" => |r| r.position_cov[(1, 1)].sqrt(),
    "std_z" => |r| r.position_cov[(2, 2)].sqrt(),
    "still" => |r| f64::from(u8::from(r.still)),
    "status" => |r| f64::from(r.status),
}

/// The names of the step columns ([`step_columns`]), in order: `t, x, y, z, vx, vy, vz, qw,
/// qx, qy, qz, std_x, std_y, std_z, still, status`, then `cov_xx, cov_xy, cov_xz, cov_yy,
/// cov_yz, cov_zz` when `covariance`.
pub fn step_column_names(covariance: bool) -> Vec<&'static str> {
    let mut names: Vec<&'static str> = STEP_NAMES.to_vec();
    if covariance {
        names.extend(COV_ENTRIES.iter().map(|c| c.0));
    }
    names
}

/// Replaces the contents of `out` with the step columns' values of `record`, in the order of
/// [`step_column_names`]`(covariance)`.
pub fn step_row(record: &StepRecord, covariance: bool, out: &mut Vec<f64>) {
    out.clear();
    out.extend(step_values(record));
    if covariance {
        out.extend(COV_ENTRIES.iter().map(|&(_, i, j)| record.position_cov[(i, j)]));
    }
}

/// One row per step ([`step_row`]) under the names of [`step_column_names`]: `t`, position,
/// velocity, orientation (`qw, qx, qy, qz`), position standard deviations, `still`, `status`
/// (the bits of [`StepRecord::status`]), then the position covariance entries when `covariance`.
pub fn step_columns(s: &[StepRecord], covariance: bool) -> Columns {
    let mut cols: Columns = step_column_names(covariance).into_iter().map(|name| (name, vec![0.0; s.len()])).collect();
    let (fields, entries) = cols.split_at_mut(STEP_NAMES.len());
    // Written by index into columns of their final length: one store per value.
    let mut fields: Vec<&mut [f64]> = fields.iter_mut().map(|(_, values)| values.as_mut_slice()).collect();
    for (row, record) in s.iter().enumerate() {
        for (values, value) in fields.iter_mut().zip(step_values(record)) {
            values[row] = value;
        }
    }
    for ((_, values), &(_, i, j)) in entries.iter_mut().zip(&COV_ENTRIES) {
        values.iter_mut().zip(s).for_each(|(value, record)| *value = record.position_cov[(i, j)]);
    }
    cols
}

/// One row per update, range or observation: `t, epoch_t, sensor, anchor, anchor_j, tag, axis,
/// value, innovation, nis, accepted, weight, inflation, down_weighted, iterations, prior_fading,
/// reacquired, bias, bias_std` (`epoch_t`: when its epoch was applied; `sensor`: the code of
/// `uwbimu_estimation::pipeline::Measured::sensor_code`, 0 for a range; `anchor`: a range's anchor
/// or a TDoA's i, −1 for none; `anchor_j`: a TDoA's anchor j, else −1; `tag`: a range's tag, else
/// −1; `axis`: an odometry reading's body axis, else −1; `value`: the range, `d_ij`, altitude or
/// speed (a magnetometer sample's field norm); `reacquired`: applied as its UWB-only fix; `bias`,
/// `bias_std`: the estimated additive bias after the update — a range's anchor total with
/// `range_bias.states`, an altitude's offset with `altitude.offset_std` — else NaN).
pub fn update_columns(trace: &Trace) -> Columns {
    let u = &trace.updates;
    let index = |i: Option<usize>| i.map_or(-1.0, |i| i as f64);
    vec![
        ("t", u.iter().map(|r| r.t_s).collect()),
        ("epoch_t", u.iter().map(|r| r.epoch_t_s).collect()),
        ("sensor", u.iter().map(|r| r.measured.sensor_code() as f64).collect()),
        ("anchor", u.iter().map(|r| index(r.measured.anchors()[0])).collect()),
        ("anchor_j", u.iter().map(|r| index(r.measured.anchors()[1])).collect()),
        ("tag", u.iter().map(|r| index(r.measured.tag())).collect()),
        ("axis", u.iter().map(|r| index(r.measured.axis())).collect()),
        ("value", u.iter().map(|r| r.measured.value()).collect()),
        ("innovation", u.iter().map(|r| r.report.innovation).collect()),
        ("nis", u.iter().map(|r| r.report.nis).collect()),
        ("accepted", u.iter().map(|r| f64::from(u8::from(r.report.accepted))).collect()),
        ("weight", u.iter().map(|r| r.report.weight).collect()),
        ("inflation", u.iter().map(|r| r.report.inflation).collect()),
        ("down_weighted", u.iter().map(|r| f64::from(u8::from(r.report.down_weighted))).collect()),
        ("iterations", u.iter().map(|r| f64::from(r.report.iterations)).collect()),
        ("prior_fading", u.iter().map(|r| r.report.prior_fading).collect()),
        ("reacquired", u.iter().map(|r| f64::from(u8::from(r.report.reacquired))).collect()),
        ("bias", u.iter().map(|r| r.report.bias.map_or(f64::NAN, |b| b.0)).collect()),
        ("bias_std", u.iter().map(|r| r.report.bias.map_or(f64::NAN, |b| b.1)).collect()),
    ]
}

/// One row per `uwb_ls` fix: `t, x, y, z, std_x, std_y, std_z, n_ranges, residual_rms`, then the
/// covariance entries when `covariance`.
pub fn fix_columns(fixes: &[(f64, Fix)], covariance: bool) -> Columns {
    let col = |f: &dyn Fn(&(f64, Fix)) -> f64| fixes.iter().map(f).collect::<Vec<f64>>();
    let mut cols = vec![
        ("t", col(&|(t, _)| *t)),
        ("x", col(&|(_, f)| f.position.x)),
        ("y", col(&|(_, f)| f.position.y)),
        ("z", col(&|(_, f)| f.position.z)),
        ("std_x", col(&|(_, f)| f.covariance[(0, 0)].sqrt())),
        ("std_y", col(&|(_, f)| f.covariance[(1, 1)].sqrt())),
        ("std_z", col(&|(_, f)| f.covariance[(2, 2)].sqrt())),
        ("n_ranges", col(&|(_, f)| f.ranges_used as f64)),
        ("residual_rms", col(&|(_, f)| f.residual_rms_m)),
    ];
    if covariance {
        for (name, i, j) in COV_ENTRIES {
            cols.push((name, col(&|(_, f)| f.covariance[(i, j)])));
        }
    }
    cols
}

/// The trajectory columns of any batch output (smoothed records when present).
pub fn output_columns(output: &BatchOutput, covariance: bool) -> Columns {
    match output {
        BatchOutput::Inertial { trace, smoothed, .. } => step_columns(smoothed.as_deref().unwrap_or(&trace.steps), covariance),
        BatchOutput::Multilateration(fixes) => fix_columns(fixes, covariance),
    }
}

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::math::{Mat3, Quat, Vec3};
    use uwbimu_vocabulary::state::NominalState;

    use super::*;

    fn record(k: usize) -> StepRecord {
        let s = k as f64;
        let a = Mat3::from_fn(|i, j| ((i * 3 + j + k) % 5) as f64 * 0.1);
        StepRecord {
            t_s: 0.01 * s,
            state: NominalState {
                position: Vec3::new(s, -2.0 * s, 0.5),
                velocity: Vec3::new(0.1, s.sin(), -s),
                orientation: Quat::from_euler_angles(0.1 * s, -0.2, 0.3),
                accel_bias: Vec3::zeros(),
                gyro_bias: Vec3::zeros(),
            },
            position_cov: a * a.transpose() + Mat3::identity(),
            still: k % 2 == 0,
            status: (k % 8) as u8,
        }
    }

    #[test]
    fn step_rows_are_the_step_columns_transposed() {
        let records: Vec<StepRecord> = (0..7).map(record).collect();
        for covariance in [false, true] {
            let cols = step_columns(&records, covariance);
            let names: Vec<&str> = cols.iter().map(|c| c.0).collect();
            assert_eq!(names, step_column_names(covariance));
            let mut row = Vec::new();
            for (r, rec) in records.iter().enumerate() {
                step_row(rec, covariance, &mut row);
                let column_values: Vec<f64> = cols.iter().map(|c| c.1[r]).collect();
                assert_eq!(row, column_values, "row {r}, covariance {covariance}");
            }
        }
        let names = step_column_names(true).join(",");
        let expected = "t,x,y,z,vx,vy,vz,qw,qx,qy,qz,std_x,std_y,std_z,still,status,cov_xx,cov_xy,cov_xz,cov_yy,cov_yz,cov_zz";
        assert_eq!(names, expected);
        let first = &step_columns(&records[..1], true);
        let rec = &records[0];
        assert_eq!(first[7].1[0], rec.state.orientation.w);
        assert_eq!(first[12].1[0], rec.position_cov[(1, 1)].sqrt());
        assert_eq!(first[17].1[0], rec.position_cov[(0, 1)]);
    }
}
