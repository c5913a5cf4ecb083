//! A subcommand's result on stdout: one pretty-printed JSON object, or the subcommand's
//! own text lines.

use serde::Serialize;

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
