//! Output files are written atomically by the library's
//! [`tdpcr::workspace::files::write_atomically`] (temporary sibling, then rename), so an
//! interrupted run never leaves a half-written file (the evaluation log is the one
//! append-only exception).

use std::path::Path;

use tdpcr::error::Error;

use crate::error::OptimError;

/// Writes `contents` to `path` atomically.
///
/// # Errors
/// [`OptimError::Io`].
pub fn write_atomically(path: &Path, contents: &[u8]) -> Result<(), OptimError> {
    tdpcr::workspace::files::write_atomically(path, contents).map_err(|e| match e {
        Error::Output { path, source } => OptimError::Io { path, source },
        other => OptimError::io(path, std::io::Error::other(other.to_string())),
    })
}
