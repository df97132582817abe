//! Runs one hot-path call of one streaming filter `n` times, for instruction counts under
//! valgrind (`scripts/instruction_counts.sh` runs it at two `n` and takes the difference, which
//! leaves out the set-up):
//!
//! ```text
//! cargo run --release --example instruction_counts -- <filter> <call> <n>
//! ```
//!
//! `filter` is a streaming filter's type name (`Ekf`, `Riekf`, … ; `Ekf2d` etc. for the planar
//! filters), `call` one of `predict` (an IMU sample at 100 Hz), `range` (one range at the filter
//! time), `epoch` (four ranges, one 1 m long, at the filter time) or `restore` (what `range` and
//! `epoch` do before each call: copy the filter back to its state after set-up, so that every
//! update does the same work).

use uwbimu_rs::estimation::pipeline::Estimator;
use uwbimu_rs::estimation::planar::{PlanarFilter, PlanarKind};
use uwbimu_rs::estimation::update::UpdateReport;
use uwbimu_rs::vocabulary::config::{FilterConfig, InitialState};
use uwbimu_rs::vocabulary::math::Vec3;

fn anchors() -> Vec<Vec3> {
    vec![Vec3::new(0.0, 0.0, 2.0), Vec3::new(10.0, 0.0, 1.0), Vec3::new(10.0, 8.0, 2.2), Vec3::new(0.0, 8.0, 0.8)]
}

fn run<F: Estimator + Clone>(mut set_up: F, call: &str, n: usize) -> Result<(), Box<dyn std::error::Error>> {
    let (accel, gyro) = (Vec3::new(0.2, -0.1, 9.8), Vec3::new(0.01, -0.02, 0.3));
    set_up.predict(0.0, &accel, &gyro)?;
    let mut f = set_up.clone();
    let epoch = [(0, 5.1), (1, 6.3), (2, 8.2), (3, 6.4)];
    let mut reports = [UpdateReport::skipped(); 4];
    for k in 0..n {
        match call {
            "predict" => f.predict(0.01 * (k + 1) as f64, std::hint::black_box(&accel), &gyro)?,
            "restore" => f.clone_from(&set_up),
            "range" => {
                f.clone_from(&set_up);
                f.update_ranges(0.0, std::hint::black_box(&epoch[1..2]), &mut reports[..1])?;
            }
            "epoch" => {
                f.clone_from(&set_up);
                f.update_ranges(0.0, std::hint::black_box(&epoch), &mut reports)?;
            }
            other => return Err(format!("unknown call {other:?}: predict, range, epoch or restore").into()),
        }
    }
    std::hint::black_box(&f);
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [filter, call, n] = args.as_slice() else {
        return Err("usage: instruction_counts <filter> <call> <n>".into());
    };
    let n: usize = n.parse()?;
    let initial = InitialState { position: Vec3::new(4.0, 3.0, 0.3), ..InitialState::default() };
    let mut config = FilterConfig::default();
    config.mounting.lever_arm = Vec3::new(0.0, 0.0, 0.05);
    let mut found = false;
    macro_rules! dispatch {
        (inertial $ty:ident, [], $($doc:literal),+) => {
            if filter == stringify!($ty) {
                found = true;
                run(uwbimu_rs::estimation::filters::$ty::new(anchors(), &initial, config.clone())?, call, n)?;
            }
        };
        (planar $kind:ident, [], $($doc:literal),+) => {
            if *filter == format!("{}2d", stringify!($kind)) {
                found = true;
                run(PlanarFilter::new(PlanarKind::$kind, anchors(), &initial, &config)?, call, n)?;
            }
        };
        (multilateration, [], $($doc:literal),+) => {};
    }
    uwbimu_rs::app::for_each_streaming_filter!(dispatch);
    if !found {
        return Err(format!("unknown filter {filter:?} (a streaming filter's type name, e.g. Ekf, Riekf, Ekf2d)").into());
    }
    Ok(())
}
