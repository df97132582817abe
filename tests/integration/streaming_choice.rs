//! The streaming `best` choosing its model while it runs (`uwbimu_app::streaming_choice`, the
//! live node's model choice): on a simulated run with TDoA, heights, wheel speeds and two tags
//! whose anchors' ranges have steady biases, the choice changes the model; the steps after the change
//! equal, bit for bit, those of a stream of the chosen model fed every event from the start (the
//! replay of the same input), and the choice equals the batch selection on the same window as
//! arrays.

#![allow(clippy::unwrap_used)]

use std::time::Duration;

use uwbimu_rs::app::methods::{BatchInput, Method};
use uwbimu_rs::app::select::choose;
use uwbimu_rs::app::sim::{lever_arms_seen, matched_config, simulate, zoo, OverrideValue};
use uwbimu_rs::app::streaming_choice::{ChoiceSettings, ChoosingStream, OpenStream};
use uwbimu_rs::estimation::filters::{Best, NamedFilter};
use uwbimu_rs::estimation::pipeline::{Builder, Event, StepRecord, Stream, StreamOptions};
use uwbimu_rs::vocabulary::config::FilterConfig;
use uwbimu_rs::vocabulary::math::Vec3;
use uwbimu_rs::vocabulary::sensors::Observation;

/// Steady range biases per anchor, m: the model the configuration gives (white noise) is not the
/// one the data have.
const BIASES_M: [f64; 8] = [0.4, -0.3, 0.5, 0.0, -0.4, 0.3, 0.0, 0.2];

/// A self-initialising `Best` stream with the reorder window of the replay, recording its steps.
fn opener(anchors: Vec<Vec3>) -> OpenStream<Best> {
    Box::new(move |config: &FilterConfig| {
        let (a, c) = (anchors.clone(), config.clone());
        let build: Builder<Best> = Box::new(move |initial| Best::build(a.clone(), initial, c.clone()));
        let mut stream = Stream::self_initializing(anchors.clone(), config.clone(), build, StreamOptions::default())?;
        stream.record_steps();
        Ok(stream)
    })
}

#[test]
fn a_model_change_equals_the_replay_of_every_sensor_and_tag_with_the_chosen_model() {
    let mut scenario = zoo("agv_loop", 0).unwrap();
    let overrides = [
        ("tag_separation_m", OverrideValue::Number(0.6)),
        ("tdoa", OverrideValue::Flag(true)),
        // Noisy TDoA: ranges with steady biases beside precise TDoA of the same anchors hardly
        // move the track, and the choice rightly keeps the configured model.
        ("tdoa_std_m", OverrideValue::Number(1.0)),
        ("altimeter", OverrideValue::Flag(true)),
        ("odometer", OverrideValue::Flag(true)),
    ];
    scenario.sim.apply_overrides(&overrides).unwrap();
    let matched = matched_config(&scenario.sim);
    let mut config = scenario.config.clone();
    config.ranging.tdoa_std = matched.ranging.tdoa_std;
    (config.sensors.altitude, config.sensors.odometry) = (matched.sensors.altitude, matched.sensors.odometry);
    config.mounting.lever_arm = lever_arms_seen(&scenario.sim, &config.mounting.imu_rotation);
    let mut data = simulate(&scenario.sim).unwrap();
    for r in &mut data.ranges {
        r.range_m += BIASES_M[r.anchor];
    }
    let t0 = data.imu[0].t_s;
    let end_s = t0 + 30.0;
    let observations = data.observations_for(|_| true);
    let mut events: Vec<Event> = data.imu.iter().map(|&s| Event::Imu(s)).collect();
    events.extend(data.ranges.iter().map(|&r| Event::Range(r)));
    events.extend(observations.iter().map(|&o| Event::Observation(o)));
    events.retain(|e| e.t_s() <= end_s);
    events.sort_by(|a, b| a.t_s().total_cmp(&b.t_s()).then(a.rank().cmp(&b.rank())));
    assert!(data.ranges.iter().any(|r| r.tag == 1));
    for kind in ["tdoa", "altitude", "odometry"] {
        assert!(observations.iter().any(|o| o.kind().info().name == kind), "no {kind}");
    }

    let after_s = 15.0;
    let settings = ChoiceSettings { method: Method::Best, after_s, anchors: data.anchors.clone(), initial: None };
    let mut live = ChoosingStream::new(config.clone(), opener(data.anchors.clone()), Some(settings)).unwrap();
    let (mut steps, mut switched_at, mut started_at) = (Vec::<StepRecord>::new(), None, None);
    for (k, event) in events.iter().enumerate() {
        live.push("test", *event).unwrap();
        live.stream_mut().move_steps(&mut steps);
        if started_at.is_none() && live.choice_window().is_some() {
            started_at = Some(k);
        }
        // The choice applied 5 s after it started: what came meanwhile is replayed too.
        if switched_at.is_none() && matches!(event, Event::Imu(s) if s.t_s >= t0 + 20.0) {
            assert!(live.waiter().expect("the choice started").wait(Duration::from_secs(600)));
            assert!(live.switch_if_chosen(&mut |_, _| {}), "{:?}", live.choice().map(|c| &c.choice.reason));
            switched_at = Some(event.t_s());
            assert!(!live.choosing() && live.waiter().is_none());
        }
    }
    live.flush().unwrap();
    live.stream_mut().move_steps(&mut steps);
    let (switched_at, started_at) = (switched_at.unwrap(), started_at.unwrap());
    let made = live.choice().unwrap().clone();
    assert!(made.switched);
    let label = &made.choice.chosen().unwrap().label;
    assert!(label.starts_with("steady bias"), "{label}: {}", made.choice.reason);

    // The replay of the same input with the chosen model.
    let mut replay = opener(data.anchors.clone())(&made.choice.config).unwrap();
    let mut want = Vec::new();
    for event in &events {
        replay.push("replay", *event).unwrap();
    }
    replay.flush().unwrap();
    replay.move_steps(&mut want);
    let after: Vec<&StepRecord> = steps.iter().filter(|s| s.t_s > switched_at).collect();
    let want: Vec<&StepRecord> = want.iter().filter(|s| s.t_s > switched_at).collect();
    assert!(after.len() > 500, "{} steps after the change", after.len());
    assert_eq!(after.len(), want.len());
    for (got, want) in after.iter().zip(&want) {
        assert_eq!(got, want, "at t = {}", got.t_s);
    }
    // Nothing was handed on twice.
    assert!(steps.windows(2).all(|w| w[0].t_s < w[1].t_s));

    // The choice is the batch selection's on the window as arrays: what came up to the IMU sample
    // that started it (at equal times the IMU comes first).
    let start_s = events[started_at].t_s();
    assert!(matches!(events[started_at], Event::Imu(_)) && start_s - t0 >= after_s);
    let imu: Vec<_> = data.imu.iter().copied().filter(|s| s.t_s <= start_s).collect();
    let ranges: Vec<_> = data.ranges.iter().copied().filter(|r| r.t_s < start_s).collect();
    let others: Vec<Observation> = observations.iter().copied().filter(|o| o.t_s() < start_s).collect();
    let batch = BatchInput { observations: &others, ..BatchInput::forward(&imu, &ranges, &data.anchors, &config) };
    assert_eq!(made.choice, choose(Method::Best, &batch).unwrap());
    assert_eq!((made.window.imu, made.window.ranges, made.window.observations), (imu.len(), ranges.len(), others.len()));
}
