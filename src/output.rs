//! Output files written atomically: a temporary file in the same directory, then a rename
//! (atomic on POSIX file systems), so an interrupted run leaves the complete file or none.

use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// A file that could not be written, and why. Every error type of the crate and of its
/// optimizer converts from it (`?` at every call site).
#[derive(Debug, thiserror::Error)]
#[error("cannot write {path}: {source}")]
pub struct WriteError {
    /// The file.
    pub path: PathBuf,
    /// The I/O error of creating, writing, syncing or renaming.
    #[source]
    pub source: io::Error,
}

/// Writes `bytes` to `path` through `.<name>.<pid>.tmp` in the same directory, synced to
/// disk, then renamed over `path`; the temporary file is removed on any failure. The one
/// atomic writer of tdpcr's outputs (with [`write_atomically_with`]).
///
/// # Errors
/// [`WriteError`] with the path and the I/O error.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    write_atomically_with(path, |file| file.write_all(bytes))
}

/// As [`write_atomically`], the content written by `fill` into the temporary file (in
/// pieces, e.g. while the next piece is being formatted).
///
/// # Errors
/// [`WriteError`] with the path and the I/O error (of `fill` too).
pub fn write_atomically_with(
    path: &Path,
    fill: impl FnOnce(&mut fs::File) -> io::Result<()>,
) -> Result<(), WriteError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp: PathBuf = path.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| {
        let mut f = fs::File::create(&tmp)?;
        fill(&mut f)?;
        f.sync_all()?;
        fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result.map_err(|source| WriteError {
        path: path.to_path_buf(),
        source,
    })
}

/// Moved to [`crate::cli_support`] (feature `cli`); re-exported here for old callers.
#[cfg(feature = "cli")]
pub use crate::cli_support::end_quietly_on_broken_pipe;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_the_file_and_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("tdpcr-atomic-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.txt");
        write_atomically(&path, b"first").unwrap();
        write_atomically(&path, b"second").unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "second");
        let names: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
        // Into a directory that does not exist: an error, nothing left behind.
        assert!(write_atomically(&dir.join("missing").join("b.txt"), b"x").is_err());
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1);
        fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_file_written_in_pieces_is_whole_or_absent() {
        let dir = std::env::temp_dir().join(format!("tdpcr-pieces-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("c.txt");
        write_atomically_with(&path, |f| {
            ["one ", "two ", "three"]
                .iter()
                .try_for_each(|piece| f.write_all(piece.as_bytes()))
        })
        .unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "one two three");
        // A piece that fails: the old file stays, no temporary is left, the error names
        // the file.
        let err = write_atomically_with(&path, |f| {
            f.write_all(b"half")?;
            Err(io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("c.txt") && err.to_string().contains("disk full"));
        assert_eq!(fs::read_to_string(&path).unwrap(), "one two three");
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1);
        fs::remove_dir_all(&dir).ok();
    }
}
