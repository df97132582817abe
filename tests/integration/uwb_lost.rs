//! No invented motion without UWB (issue 20): a still drone whose TDoA stop after a second
//! (`still_tdoa_lost`) and a robot whose ranges stop after its first second of driving
//! (`moving_uwb_lost`), every inertial method, self-initialised and from the true start. Figures:
//! docs/design-notes.md#uwb-lost (`cargo run --release --example uwb_lost`).

use uwbimu_rs::app::methods::{run_method, BatchInput, BatchOutput, Method};
use uwbimu_rs::app::sim::{self, Scenario, SimData};
use uwbimu_rs::estimation::init::SelfInit;
use uwbimu_rs::estimation::pipeline::Trace;
use uwbimu_rs::vocabulary::config::InitialState;
use uwbimu_rs::vocabulary::sensors::observations;

/// The inertial methods (15-state, smoothable).
fn inertial() -> impl Iterator<Item = Method> {
    Method::ALL.iter().copied().filter(|m| m.smoothable())
}

/// Runs `method` forward on `data`: TDoA for the methods that take them when the run has any,
/// else the ranges (the loosely coupled methods take no TDoA).
fn run(method: Method, s: &Scenario, data: &SimData, initial: Option<&InitialState>) -> (Trace, Option<Box<SelfInit>>) {
    let tdoa = method.takes_tdoa() && !data.tdoa.is_empty();
    let input = BatchInput {
        imu: &data.imu,
        ranges: if tdoa { &[] } else { &data.ranges },
        anchors: &data.anchors,
        initial,
        config: &s.config,
        smooth: false,
        observations: if tdoa { &observations(&data.tdoa) } else { &[] },
        progress: None,
        marginals_every_s: None,
    };
    match run_method(method, &input) {
        Ok(BatchOutput::Inertial { trace, init, .. }) => (trace, init),
        other => panic!("{method:?}: {other:?}"),
    }
}

/// The heading of a body → navigation rotation, rad.
fn yaw(q: &uwbimu_rs::vocabulary::math::Quat) -> f64 {
    q.euler_angles().2
}

/// One run of `still_tdoa_lost`: final horizontal error (m), yaw swing while the TDoA are there
/// (rad) and the share of rows marked still.
fn still_run(method: Method, s: &Scenario, data: &SimData, initial: Option<&InitialState>) -> StillRun {
    let t0 = data.imu[0].t_s;
    let uwb_end = data.tdoa.last().expect("TDoA").t_s;
    let (trace, init) = run(method, s, data, initial);
    if let Some(init) = &init {
        assert!(init.still, "{method:?}: the start is still");
    }
    let last = trace.steps.len() - 1;
    let err = (trace.steps[last].state.position - data.truth[last].position).xy().norm();
    let yaw_err: Vec<f64> = trace
        .steps
        .iter()
        .zip(&data.truth)
        .filter(|(st, _)| st.t_s >= t0 + 0.5 && st.t_s <= uwb_end)
        .map(|(st, tr)| {
            let e = yaw(&st.state.orientation) - yaw(&tr.orientation);
            e.sin().atan2(e.cos())
        })
        .collect();
    let swing = yaw_err.iter().copied().fold(f64::NEG_INFINITY, f64::max) - yaw_err.iter().copied().fold(f64::INFINITY, f64::min);
    let still = trace.steps.iter().filter(|st| st.still).count() as f64 / trace.steps.len() as f64;
    (err, swing, still)
}

/// Final horizontal error (m), yaw swing (rad), share of rows marked still.
type StillRun = (f64, f64, f64);

/// The runs of `still_tdoa_lost`, seeds 0–2: (seed, method, self-initialised, result).
fn still_runs() -> Vec<(u64, Method, bool, StillRun)> {
    let mut out = Vec::new();
    for seed in 0..3 {
        let s = sim::zoo("still_tdoa_lost", seed).expect("zoo");
        let data = sim::simulate(&s.sim).expect("simulate");
        let t0 = data.imu[0].t_s;
        assert!(data.tdoa.last().expect("TDoA").t_s < t0 + 1.01, "TDoA lost after 1 s");
        assert!(data.ranges.last().expect("ranges").t_s < t0 + 1.01, "ranges lost after 1 s");
        let truth = s.true_initial(&data).expect("initial");
        for method in inertial() {
            out.push((seed, method, true, still_run(method, &s, &data, None)));
            out.push((seed, method, false, still_run(method, &s, &data, Some(&truth))));
        }
    }
    out
}

#[test]
fn a_still_drone_keeps_its_heading_and_stays_put_where_the_detector_holds_it() {
    // Measured (seeds 0–2, matched settings), docs/design-notes.md#uwb-lost:
    // - yaw swing while the TDoA are there ≤ 0.8° for every method and start (before: 30–97°
    //   self-initialised);
    // - self-initialised, every method but `eskf` ends ≤ 0.035 m off and marks ≥ 0.98 of the rows
    //   still (`eskf`: 7.6 m on seed 2, where its speed passed the detector's gate);
    // - `best`, `criekf` (still detector on) and `ackf` end ≤ 0.016 m off from either start.
    for (seed, method, self_init, (err, swing, still)) in still_runs() {
        let run = format!(
            "seed {seed} {method:?} self-initialised {self_init}: {err:.3} m, {:.1}°, still {still:.2}",
            swing.to_degrees()
        );
        println!("{run}");
        assert!(swing.to_degrees() < 3.0, "{run}");
        if matches!(method, Method::Best | Method::Criekf | Method::Ackf) {
            assert!(err < 0.1 && still > 0.8, "{run}");
        } else if self_init && method != Method::Eskf {
            assert!(err < 0.15 && still > 0.8, "{run}");
        }
    }
}

#[test]
fn every_method_stays_within_the_issue_bars_on_a_still_drone() {
    // The issue's bars: ≤ 3 m after 10 s IMU-only for every inertial method (0.5 m with the
    // still detector on), the still column on for most rows. Measured (seeds 0–2, matched
    // settings, both starts): every method ends within 0.03 m, the still column on for ≥ 0.94 of
    // the rows; the bounds keep the issue's bars.
    let mut failures = Vec::new();
    for (seed, method, self_init, (err, _, still)) in still_runs() {
        let bound = if matches!(method, Method::Best | Method::Criekf) { 0.5 } else { 3.0 };
        if !(err < bound && still > 0.5) {
            failures.push(format!("seed {seed} {method:?} self-initialised {self_init}: {err:.2} m, still {still:.2}"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn a_robot_without_ranges_stays_finite() {
    // 11.5 s without ranges on a 10 m drive with a stop: no inertial method can know where it
    // is; every one must return finite estimates. Measured (seeds 0–2) worst final horizontal
    // error: 103 m self-initialised (the heading is not found in 1 s of motion: σ = π), 33 m from
    // the true start; the bound is 1.5× that.
    for seed in 0..3 {
        let s = sim::zoo("moving_uwb_lost", seed).expect("zoo");
        let data = sim::simulate(&s.sim).expect("simulate");
        let truth = s.true_initial(&data).expect("initial");
        for method in inertial() {
            for (initial, bound) in [(None, 150.0), (Some(&truth), 50.0)] {
                let (trace, _) = run(method, &s, &data, initial);
                assert!(trace.steps.iter().all(|st| st.state.position.iter().all(|x| x.is_finite())), "{method:?}");
                let last = trace.steps.len() - 1;
                let err = (trace.steps[last].state.position - data.truth[last].position).xy().norm();
                assert!(err < bound, "seed {seed} {method:?} {initial:?}: final error {err:.1} m");
            }
        }
    }
}
