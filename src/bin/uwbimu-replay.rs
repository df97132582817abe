//! `uwbimu-replay`: replays an MCAP recording through one of the filters ([`uwbimu_rs::cli`]).

fn main() -> std::process::ExitCode {
    std::process::ExitCode::from(uwbimu_rs::cli::main_with_args(std::env::args_os()))
}
