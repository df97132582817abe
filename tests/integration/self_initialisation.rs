//! Self-initialisation in one pass: a [`SelfInitializer`] fed event by event keeps what it solved
//! and scanned between its attempts, and must decide exactly what one evaluation of the same
//! prefix decides ([`initialize_with_tdoa`] on the data up to the deciding sample). The oracle is
//! that one-shot evaluation, over runs it was not written for: TDoA only at 1 kHz, a still start
//! that never settles its heading, a moving start, two tags, jittered and staggered ranges.

#![allow(clippy::unwrap_used)]

use uwbimu_rs::app::sim::{self, simulate, zoo, OverrideValue, SimData};
use uwbimu_rs::estimation::gate::Gate;
use uwbimu_rs::estimation::init::{initialize_with_tdoa, SelfInit, SelfInitializer};
use uwbimu_rs::estimation::pipeline::{Event, Streams};
use uwbimu_rs::vocabulary::config::FilterConfig;
use uwbimu_rs::vocabulary::records::{ImuSample, RangeMeasurement, TdoaMeasurement};
use uwbimu_rs::vocabulary::sensors::{Observation, SensorKind};

/// The kept (gate-passed) data of a run, in the order the initializer took it.
#[derive(Default)]
struct Taken {
    imu: Vec<ImuSample>,
    ranges: Vec<RangeMeasurement>,
    tdoa: Vec<TdoaMeasurement>,
}

/// Feeds the run's events through the gate into a [`SelfInitializer`] as a self-initialising
/// stream does: the decision (None if the data ended first, then `finish`) and the data taken.
fn streamed(data: &SimData, tdoa_only: bool, config: &FilterConfig) -> (SelfInit, bool, Taken) {
    let observations = data.observations_for(|k| k == SensorKind::Tdoa);
    let ranges = if tdoa_only { &[][..] } else { &data.ranges[..] };
    let streams = Streams { imu: &data.imu, ranges, observations: &observations, ..Streams::default() };
    let gate = Gate::new(&data.anchors, &config.gate);
    let mut initializer = SelfInitializer::new(&data.anchors, config).unwrap();
    let mut taken = Taken::default();
    for event in streams.events() {
        if gate.check(&event).is_some() {
            continue;
        }
        match event {
            Event::Imu(s) => {
                taken.imu.push(s);
                if let Some(init) = initializer.imu(&s).unwrap() {
                    return (init, true, taken);
                }
            }
            Event::Range(r) => {
                taken.ranges.push(r);
                initializer.range(&r).unwrap();
            }
            Event::Observation(Observation::Tdoa(m)) => {
                taken.tdoa.push(m);
                initializer.tdoa(&m).unwrap();
            }
            Event::Observation(_) => {}
        }
    }
    (initializer.finish().unwrap(), false, taken)
}

/// A zoo scenario, its overrides, and whether it is run on TDoA alone.
type Case<'a> = (&'a str, &'a [(&'a str, OverrideValue)], bool);

#[test]
fn a_streamed_decision_is_the_one_shot_initialisation_of_its_prefix() {
    let number = OverrideValue::Number;
    let runs: [Case<'_>; 8] = [
        ("tdoa_drone", &[], true),
        ("still_tdoa_lost", &[], true),
        ("handheld_walk", &[("jitter_s", number(0.01)), ("uwb_rate_hz", number(7.0))], false),
        ("agv_loop", &[], false),
        ("agv_loop", &[("tag_separation_m", number(0.5))], false),
        ("stop_and_go", &[("stagger_s", number(0.02))], false),
        ("forklift", &[("tdoa", OverrideValue::Flag(true))], true),
        ("imu_z_down", &[], false),
    ];
    let (mut decided, mut total) = (0, 0);
    for (name, overrides, tdoa_only) in runs {
        for seed in [3, 4] {
            let mut s = zoo(name, seed).unwrap();
            s.sim.apply_overrides(overrides).unwrap();
            s.config.ranging.tdoa_std = sim::matched_config(&s.sim).ranging.tdoa_std;
            s.config.mounting.lever_arm = sim::lever_arms_seen(&s.sim, &s.config.mounting.imu_rotation);
            let data = simulate(&s.sim).unwrap();
            for config in [s.config.clone(), FilterConfig { mounting: s.config.mounting, ..FilterConfig::default() }] {
                let (init, was_decided, taken) = streamed(&data, tdoa_only, &config);
                let one_shot = initialize_with_tdoa(&taken.imu, &taken.ranges, &taken.tdoa, &data.anchors, &config).unwrap();
                assert_eq!(init, one_shot, "{name} seed {seed}: streamed ≠ one-shot on its prefix");
                (decided, total) = (decided + usize::from(was_decided), total + 1);
            }
        }
    }
    // Most runs decide before their end (a still TDoA flight cannot: its heading waits for the
    // timeout), so the comparison is of decisions, not only of whole logs.
    println!("{decided} of {total} runs decided before their end");
    assert!(decided >= total / 2, "{decided} of {total} runs decided before their end");
}

#[test]
fn tdoa_before_the_first_imu_sample_join_the_windows_as_in_one_evaluation() {
    // The stream holds the TDoA that come before the first IMU sample until it knows the start
    // (those older than half a second before it are left out); one evaluation takes them after
    // the IMU. Oracle: the one-shot evaluation of the same data, with the IMU starting 0.8 s
    // after the TDoA, on the still start and on the TDoA drone.
    for name in ["still_tdoa_lost", "tdoa_drone"] {
        let s = zoo(name, 5).unwrap();
        let mut data = simulate(&s.sim).unwrap();
        let first_tdoa_s = data.observations_for(|k| k == SensorKind::Tdoa)[0].t_s();
        data.imu.retain(|imu| imu.t_s >= first_tdoa_s + 0.8);
        let (init, _, taken) = streamed(&data, true, &s.config);
        assert!(taken.tdoa.first().is_some_and(|m| m.t_s < taken.imu[0].t_s - 0.5), "{name}: TDoA before the cut-off");
        let one_shot = initialize_with_tdoa(&taken.imu, &taken.ranges, &taken.tdoa, &data.anchors, &s.config).unwrap();
        assert_eq!(init, one_shot, "{name}");
    }
}
