//! The integration tests, one module per subject, built as one test binary (forty binaries linked
//! the whole library forty times: docs/testing.md, "Where CI's time goes"); `cargo test --test
//! integration <module>::` runs one subject. The allocation counts stay a binary of their own
//! (`tests/allocations.rs`): they install a global allocator, which would count every test here.

mod ackf;
mod anchor_survey_mcap;
mod arckf;
mod calibrate;
mod common;
mod config_keys;
mod consistency;
mod constraints;
mod covariance_rate;
mod crlb;
mod docs_tables;
mod ekf;
mod fuzz_io;
mod generality;
mod impossible_data;
mod isas_walk1;
mod jacobians;
mod long_run_health;
mod loose;
mod map_smoothing;
mod offsets;
mod planar_tilt;
mod pose_fix;
mod range_bias;
mod ranging;
mod replay_cli;
mod robust;
mod robust_smoothing;
mod select;
mod self_initialisation;
mod self_start_consistency;
mod sensors;
mod sensors_mcap;
mod sim;
mod smoother;
mod streamed_replay;
mod streaming_choice;
mod tags;
mod tdoa;
mod tdoa_mcap;
mod uwb_lost;
mod wang_2018;

/// Every file of this directory is a module of this binary: a test file left out of the list
/// above would build and run nowhere.
#[test]
fn every_test_file_is_a_module_here() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/integration");
    let source = std::fs::read_to_string(dir.join("main.rs")).expect("read main.rs");
    for entry in std::fs::read_dir(&dir).expect("read tests/integration") {
        let name = entry.expect("a directory entry").file_name().to_string_lossy().into_owned();
        if let Some(module) = name.strip_suffix(".rs").filter(|m| *m != "main") {
            assert!(source.contains(&format!("\nmod {module};\n")), "tests/integration/{name} is not declared in main.rs");
        }
    }
}
