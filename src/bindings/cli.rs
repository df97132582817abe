//! Binding of the `uwbimu-replay` program: `replay_main`, behind the console script that
//! `pip install` puts on PATH (`uwbimu_rs._cli:main`).

use pyo3::prelude::*;

/// Runs `uwbimu-replay` with `argv` (`sys.argv`: the program, then its arguments) with the GIL
/// released and returns its exit status (0 success, 2 error).
#[pyfunction]
fn replay_main(py: Python<'_>, argv: Vec<String>) -> u8 {
    py.detach(|| crate::cli::main_with_args(argv))
}

/// Registers the function.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(replay_main, m)?)?;
    Ok(())
}
