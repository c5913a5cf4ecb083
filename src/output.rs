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
/// atomic writer of tdpcr's outputs (with [`write_atomically_with`]). A symbolic link
/// is followed (the file it names is replaced, the link stays); anything else that is
/// not a regular file (a directory, a device such as `/dev/null`, a pipe) is refused
/// before anything is written: the rename would replace it.
///
/// # Errors
/// [`WriteError`] with the path and the I/O error (`InvalidInput` for a target that is
/// not a regular file, `NotFound` for a dangling link).
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
    let error = |source| WriteError {
        path: path.to_path_buf(),
        source,
    };
    let target = regular_file_target(path).map_err(error)?;
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp: PathBuf = target.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| {
        let mut f = fs::File::create(&tmp)?;
        fill(&mut f)?;
        f.sync_all()?;
        fs::rename(&tmp, &target)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result.map_err(error)
}

/// Whether [`write_atomically`] could replace `path`: an error (as the write's) if it,
/// or the file a symbolic link names, exists and is not a regular file. For checks
/// before a long computation whose results go there.
///
/// # Errors
/// [`WriteError`] with the path and the reason.
pub fn check_target(path: &Path) -> Result<(), WriteError> {
    regular_file_target(path)
        .map(|_| ())
        .map_err(|source| WriteError {
            path: path.to_path_buf(),
            source,
        })
}

/// The file an atomic write of `path` replaces: `path` itself, or the file a symbolic
/// link names; an error if that exists and is not a regular file.
fn regular_file_target(path: &Path) -> io::Result<PathBuf> {
    let is_link = fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
    let target = if is_link {
        fs::canonicalize(path).map_err(|e| {
            io::Error::new(e.kind(), format!("a symbolic link to a missing path ({e})"))
        })?
    } else {
        path.to_path_buf()
    };
    match fs::metadata(&target) {
        Ok(m) if !m.is_file() => Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{} is a {}, expected a regular file or a new file's path",
                target.display(),
                kind_of(&m.file_type())
            ),
        )),
        _ => Ok(target),
    }
}

/// What a file type is, in words.
fn kind_of(t: &fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() || t.is_block_device() {
            return "device";
        }
        if t.is_fifo() {
            return "named pipe";
        }
        if t.is_socket() {
            return "socket";
        }
    }
    if t.is_dir() {
        "directory"
    } else {
        "special file"
    }
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

    /// A link is followed, and a target that is not a regular file is refused before
    /// anything is written (the rename replaced `--view /dev/null` by a regular file).
    #[test]
    fn links_are_followed_and_special_files_refused() {
        let dir = std::env::temp_dir().join(format!("tdpcr-special-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let sub = dir.join("sub");
        fs::create_dir_all(&sub).unwrap();
        let err = write_atomically(&sub, b"x").unwrap_err().to_string();
        assert!(
            err.contains("is a directory, expected a regular file"),
            "{err}"
        );
        assert!(sub.is_dir());
        #[cfg(unix)]
        {
            // A socket file stands for the devices and pipes (a test must not risk
            // /dev/null).
            let socket = dir.join("socket");
            let _listener = std::os::unix::net::UnixListener::bind(&socket).unwrap();
            let err = write_atomically(&socket, b"x").unwrap_err().to_string();
            assert!(err.contains("socket is a socket, expected"), "{err}");
            fs::remove_file(&socket).unwrap();
            let target = dir.join("target.html");
            fs::write(&target, "old").unwrap();
            let link = dir.join("link.html");
            std::os::unix::fs::symlink(&target, &link).unwrap();
            write_atomically(&link, b"new").unwrap();
            assert!(
                fs::symlink_metadata(&link)
                    .unwrap()
                    .file_type()
                    .is_symlink()
            );
            assert_eq!(fs::read_to_string(&target).unwrap(), "new");
            let dangling = dir.join("dangling.html");
            std::os::unix::fs::symlink(dir.join("missing").join("x"), &dangling).unwrap();
            let err = write_atomically(&dangling, b"x").unwrap_err().to_string();
            assert!(err.contains("symbolic link to a missing path"), "{err}");
        }
        // Nothing but what the test made (no temporary left anywhere).
        let mut names: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        let expected: &[&str] = if cfg!(unix) {
            &["dangling.html", "link.html", "sub", "target.html"]
        } else {
            &["sub"]
        };
        assert_eq!(names, expected);
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
