//! Named columns of a batch output (the `run_filter` DataFrame layout), shared by the Python
//! bindings and the CSV writer of `uwbimu-replay`.

use uwbimu_estimation::multilateration::Fix;
use uwbimu_estimation::pipeline::{StepRecord, Trace};

use crate::methods::BatchOutput;

/// Columns as (name, values).
pub type Columns = Vec<(&'static str, Vec<f64>)>;

const COV_ENTRIES: [(&str, usize, usize); 6] =
    [("cov_xx", 0, 0), ("cov_xy", 0, 1), ("cov_xz", 0, 2), ("cov_yy", 1, 1), ("cov_yz", 1, 2), ("cov_zz", 2, 2)];

/// One row per step: `t, x, y, z, vx, vy, vz, qw, qx, qy, qz, std_x, std_y, std_z, still,
/// status` (`status`: the bits of [`StepRecord::status`]), then the position covariance entries
/// when `covariance`.
pub fn step_columns(s: &[StepRecord], covariance: bool) -> Columns {
    let col = |f: &dyn Fn(&StepRecord) -> f64| s.iter().map(f).collect::<Vec<f64>>();
    let mut cols = vec![
        ("t", col(&|r| r.t_s)),
        ("x", col(&|r| r.state.position.x)),
        ("y", col(&|r| r.state.position.y)),
        ("z", col(&|r| r.state.position.z)),
        ("vx", col(&|r| r.state.velocity.x)),
        ("vy", col(&|r| r.state.velocity.y)),
        ("vz", col(&|r| r.state.velocity.z)),
        ("qw", col(&|r| r.state.orientation.w)),
        ("qx", col(&|r| r.state.orientation.i)),
        ("qy", col(&|r| r.state.orientation.j)),
        ("qz", col(&|r| r.state.orientation.k)),
        ("std_x", col(&|r| r.position_cov[(0, 0)].sqrt())),
        ("std_y", col(&|r| r.position_cov[(1, 1)].sqrt())),
        ("std_z", col(&|r| r.position_cov[(2, 2)].sqrt())),
        ("still", col(&|r| f64::from(u8::from(r.still)))),
        ("status", col(&|r| f64::from(r.status))),
    ];
    if covariance {
        for (name, i, j) in COV_ENTRIES {
            cols.push((name, col(&|r| r.position_cov[(i, j)])));
        }
    }
    cols
}

/// One row per range or TDoA update: `t, epoch_t, anchor, anchor_j, range, innovation, nis,
/// accepted, weight, inflation, down_weighted, iterations, prior_fading, reacquired, bias, bias_std`
/// (`epoch_t`: when its epoch was applied; `anchor_j`: a TDoA's anchor j, −1 for a range;
/// `range`: a TDoA's `d_ij`; `reacquired`: applied as its UWB-only fix; `bias`, `bias_std`: the
/// anchor's estimated range bias after the update with `range_bias.states`, else NaN).
pub fn update_columns(trace: &Trace) -> Columns {
    let u = &trace.updates;
    vec![
        ("t", u.iter().map(|r| r.t_s).collect()),
        ("epoch_t", u.iter().map(|r| r.epoch_t_s).collect()),
        ("anchor", u.iter().map(|r| r.anchor as f64).collect()),
        ("anchor_j", u.iter().map(|r| r.anchor_j.map_or(-1.0, |j| j as f64)).collect()),
        ("range", u.iter().map(|r| r.range_m).collect()),
        ("innovation", u.iter().map(|r| r.report.innovation).collect()),
        ("nis", u.iter().map(|r| r.report.nis).collect()),
        ("accepted", u.iter().map(|r| f64::from(u8::from(r.report.accepted))).collect()),
        ("weight", u.iter().map(|r| r.report.weight).collect()),
        ("inflation", u.iter().map(|r| r.report.inflation).collect()),
        ("down_weighted", u.iter().map(|r| f64::from(u8::from(r.report.down_weighted))).collect()),
        ("iterations", u.iter().map(|r| f64::from(r.report.iterations)).collect()),
        ("prior_fading", u.iter().map(|r| r.report.prior_fading).collect()),
        ("reacquired", u.iter().map(|r| f64::from(u8::from(r.report.reacquired))).collect()),
        ("bias", u.iter().map(|r| r.report.range_bias.map_or(f64::NAN, |b| b.0)).collect()),
        ("bias_std", u.iter().map(|r| r.report.range_bias.map_or(f64::NAN, |b| b.1)).collect()),
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
