//! The planar filters (`ekf2d`, `ukf2d`, `cekf2d`) on walks whose IMU is never level: the zoo's
//! `tilted_walk` (a tag held tilted like a phone and swinging) and, for a walk not built for the
//! fix, `handheld_walk` on other seeds; defaults, self-initialised, first 10 s left out (the
//! generality matrix's cells). Before the levelling by the propagated attitude (the start's roll
//! and pitch held fixed) `tilted_walk` gave 2.8–3.0× `uwb_ls` (ekf2d, ukf2d) and 4.3–4.7×
//! (cekf2d); docs/design-notes.md#planar-tilt, `cargo run --release --example planar_tilt`.

#![allow(clippy::unwrap_used)]

use uwbimu_rs::app::generality::{run_cell, Cell, Settings, Start};
use uwbimu_rs::app::methods::Method;

const PLANAR: [Method; 3] = [Method::Ekf2d, Method::Ukf2d, Method::Cekf2d];

fn ratio(scenario: &str, seed: u64, method: Method) -> f64 {
    let cell = Cell { scenario, seed, method, start: Start::SelfInit, settings: Settings::Defaults };
    let r = run_cell(&cell).unwrap();
    println!("{scenario} seed {seed} {}: {:.3} m, uwb_ls {:.3} m ({:.2}×)", method.name(), r.rmse_m, r.uwb_ls_rmse_m, r.ratio());
    assert!(r.finite, "{scenario} seed {seed} {}: not finite", method.name());
    r.ratio()
}

/// Every planar filter on `scenario` over `seeds`, self-initialised with the defaults, within
/// `bound` × `uwb_ls`.
fn assert_within(scenario: &str, seeds: std::ops::Range<u64>, bound: f64) {
    for seed in seeds {
        for method in PLANAR {
            let r = ratio(scenario, seed, method);
            assert!(r < bound, "{scenario} seed {seed} {}: {r:.2}× uwb_ls", method.name());
        }
    }
}

#[test]
fn planar_filters_hold_on_a_tilted_handheld_walk() {
    // Measured (seeds 0–2): ekf2d and ukf2d 0.47–0.51×, cekf2d 0.51–0.56× uwb_ls.
    assert_within("tilted_walk", 0..3, 0.65);
}

#[test]
fn planar_filters_hold_on_another_handheld_walk() {
    // Seeds not used to choose anything. Measured (seeds 3–5): 0.47–0.50× (ekf2d, ukf2d),
    // 0.53–0.54× (cekf2d).
    assert_within("handheld_walk", 3..6, 0.65);
}
