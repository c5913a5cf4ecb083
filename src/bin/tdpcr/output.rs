//! A subcommand's result on stdout: one pretty-printed JSON object, or the subcommand's
//! own text lines.

use serde::Serialize;

use tdpcr::error::Error;

use crate::args::Format;

/// Prints `value` as one pretty-printed JSON object.
pub fn print_json<T: Serialize>(value: &T) {
    println!(
        "{}",
        serde_json::to_string_pretty(value).expect("plain data serializes")
    );
}

/// Prints `value` in `format`: JSON ([`print_json`]) or the lines written by `text`.
pub fn print<T: Serialize>(format: Format, value: &T, text: impl FnOnce(&T)) {
    match format {
        Format::Json => print_json(value),
        Format::Text => text(value),
    }
}

/// A failed solve in JSON (`fk`, `ik`, `tdcr`): the message and, where the error has
/// them, the iterations, the residual norm and the typed stop reason.
#[derive(Serialize)]
struct FailureOutput {
    converged: bool,
    error: String,
    iterations: Option<usize>,
    residual_norm: Option<f64>,
    /// Why Newton stopped, as a stable snake_case name (`tdpcr::StopReason`).
    stop_reason: Option<tdpcr::StopReason>,
    /// When the solve diverged: the inputs beyond their natural scale, largest factor
    /// first (empty if none is); absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    diverged_inputs: Option<Vec<tdpcr::error::OutOfRange>>,
}

/// Prints a solve's failure as one JSON object on stdout in JSON `format` (the error
/// itself still goes to stderr and sets the exit code); nothing for other errors or
/// formats.
pub fn print_solve_failure(format: Format, e: &Error) {
    let (Format::Json, Error::Solve(se)) = (format, e) else {
        return;
    };
    let (iterations, residual_norm, stop_reason) = match se {
        tdpcr::SolveError::NotConverged {
            iterations,
            residual_norm,
            reason,
            ..
        } => (Some(*iterations), Some(*residual_norm), Some(*reason)),
        _ => (None, None, None),
    };
    let diverged_inputs = match se {
        tdpcr::SolveError::Diverged { inputs, .. } => Some(inputs.clone()),
        _ => None,
    };
    print_json(&FailureOutput {
        converged: false,
        error: e.to_string(),
        iterations,
        residual_norm,
        stop_reason,
        diverged_inputs,
    });
}
