//! The package's exceptions and the mapping of [`tdpcr::Error`] onto them.

use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

use tdpcr::error::AnalysisError as LibAnalysisError;
use tdpcr::{DesignError as LibDesignError, Error, SolveError};

pyo3::create_exception!(
    tdpcr,
    DesignError,
    PyValueError,
    "A design that cannot be read, parsed or accepted; the message lists every bad field."
);
pyo3::create_exception!(
    tdpcr,
    ConvergenceError,
    PyRuntimeError,
    "A solve that failed; attributes `reason` (snake_case, as the CLI's `stop_reason`), \
     `residual_norm` (SI residual, None if unknown) and `iterations` (None if unknown)."
);
pyo3::create_exception!(
    tdpcr,
    AnalysisError,
    PyRuntimeError,
    "An analysis that cannot be carried out (an exactly singular matrix)."
);

/// A design error as `DesignError` (unreadable files too: the message names the path).
pub fn design_error(e: LibDesignError) -> PyErr {
    DesignError::new_err(e.to_string())
}

/// Any library error as the matching Python exception.
pub fn to_py_err(py: Python<'_>, e: Error) -> PyErr {
    let message = e.to_string();
    match e {
        Error::Design(d) => design_error(d),
        Error::Input(_) => PyValueError::new_err(message),
        Error::Solve(s) => convergence_error(py, &s, message),
        Error::Analysis(LibAnalysisError::Shape { .. } | LibAnalysisError::NonFinite { .. }) => {
            PyValueError::new_err(message)
        }
        Error::Analysis(LibAnalysisError::Singular { .. }) => AnalysisError::new_err(message),
        Error::Output { .. } => PyOSError::new_err(message),
        #[allow(unreachable_patterns)]
        _ => PyRuntimeError::new_err(message),
    }
}

/// `ConvergenceError` with `reason`, `residual_norm` and `iterations` set.
fn convergence_error(py: Python<'_>, e: &SolveError, message: String) -> PyErr {
    let reason = e.reason();
    let (residual_norm, iterations) = match e {
        SolveError::NotConverged {
            iterations,
            residual_norm,
            ..
        } => (Some(*residual_norm), Some(*iterations)),
        _ => (None, None),
    };
    let err = ConvergenceError::new_err(message);
    let value = err.value(py);
    let attributes = value
        .setattr("reason", reason)
        .and_then(|()| value.setattr("residual_norm", residual_norm))
        .and_then(|()| value.setattr("iterations", iterations));
    match attributes {
        Ok(()) => err,
        Err(e) => e,
    }
}
