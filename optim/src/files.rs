//! Output files: written to a temporary sibling and renamed, so an interrupted run never
//! leaves a half-written file (the evaluation log is the one append-only exception).

use std::path::Path;

use crate::error::OptimError;

/// Writes `contents` to `path` atomically (temporary file in the same directory, then
/// rename).
///
/// # Errors
/// [`OptimError::Io`].
pub fn write_atomically(path: &Path, contents: &[u8]) -> Result<(), OptimError> {
    let name = path
        .file_name()
        .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    let tmp = path.with_file_name(format!(".{name}.tmp{}", std::process::id()));
    std::fs::write(&tmp, contents)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|source| {
            let _ = std::fs::remove_file(&tmp);
            OptimError::io(path, source)
        })
}
