//! Errors of a search. A design that cannot be scored is not an error (it is an
//! [`crate::objectives::Infeasibility`]); the end of a search is a
//! [`crate::search::TerminationReason`], not an error.

use std::path::{Path, PathBuf};

use tdpcr::DesignError;

use crate::cmaes::CmaesError;

/// Anything that stops a search before it can run or finish.
#[derive(Debug, thiserror::Error)]
pub enum OptimError {
    /// The config or the base design cannot be read, parsed or accepted.
    #[error(transparent)]
    Config(#[from] DesignError),
    /// A file or directory could not be read or written.
    #[error("cannot access {path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// Underlying I/O error.
        source: std::io::Error,
    },
    /// A new run would overwrite an existing one.
    #[error(
        "{path} already holds evaluations: pass --resume to continue that run (Python: resume=True), or choose another --out (out)"
    )]
    RunExists {
        /// The existing log.
        path: PathBuf,
    },
    /// Another search (in this or another process) is running in the same directory.
    #[error(
        "{path} is in use by another search (another process, or a DesignSearch not finished or closed): wait for it to end, or choose another --out (out)"
    )]
    RunInUse {
        /// The locked log.
        path: PathBuf,
    },
    /// The run directory is an empty path.
    #[error("the output directory is an empty path: name a directory (--out; Python: out)")]
    NoOutDir,
    /// The run directory's path names something that is not a directory (a file).
    #[error("--out (out) = {path}: not a directory: name a directory (created if missing)")]
    NotADirectory {
        /// The path given.
        path: PathBuf,
    },
    /// `--resume` without a run to continue.
    #[error("--resume (resume=True): no run to continue ({path} is missing)")]
    NoRun {
        /// The missing run identity file.
        path: PathBuf,
    },
    /// `--resume` with settings that differ from the stored run.
    #[error("--resume (resume=True): the settings differ from the run in {dir}:{differences}")]
    ResumeMismatch {
        /// The run directory.
        dir: PathBuf,
        /// One line per differing field: stored and current value.
        differences: String,
    },
    /// A line of the log (or the run file) does not parse.
    #[error("{path}:{line}: corrupt record: {message}")]
    CorruptLog {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// The parser's message.
        message: String,
    },
    /// A logged candidate is not the one the replayed search asks for.
    #[error(
        "--resume (resume=True): logged candidate {id} has x = {logged:?} but the replayed search asks for x = {asked:?} (the log was written by another version or edited)"
    )]
    ReplayMismatch {
        /// Candidate id.
        id: usize,
        /// Box point in the log.
        logged: Vec<f64>,
        /// Box point the search asks for now.
        asked: Vec<f64>,
    },
    /// A driver of [`crate::search::Search`] told a result that does not fit the step.
    #[error("{} told out of turn: expected {expected}", told(*.id))]
    UnexpectedRecord {
        /// The candidate id told (`None`: no result at all).
        id: Option<usize>,
        /// What the step expected.
        expected: String,
    },
    /// The optimizer was misused (a bug).
    #[error(transparent)]
    Cmaes(#[from] CmaesError),
}

/// What [`OptimError::UnexpectedRecord`] was told, in words.
fn told(id: Option<usize>) -> String {
    match id {
        Some(id) => format!("the result of candidate {id}"),
        None => "no result".to_string(),
    }
}

impl From<tdpcr::output::WriteError> for OptimError {
    fn from(e: tdpcr::output::WriteError) -> Self {
        Self::Io {
            path: e.path,
            source: e.source,
        }
    }
}

impl OptimError {
    /// [`OptimError::Io`] for `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// Whether the user's input is at fault (exit code 2) rather than the run (exit 1).
    pub fn is_input_error(&self) -> bool {
        matches!(
            self,
            Self::Config(_)
                | Self::RunExists { .. }
                | Self::RunInUse { .. }
                | Self::NoOutDir
                | Self::NotADirectory { .. }
                | Self::NoRun { .. }
                | Self::ResumeMismatch { .. }
                | Self::ReplayMismatch { .. }
                | Self::CorruptLog { .. }
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_file_and_the_values() {
        let cases = [
            (
                OptimError::RunExists {
                    path: "out/evaluations.jsonl".into(),
                },
                "out/evaluations.jsonl already holds evaluations: pass --resume to continue that run (Python: resume=True), or choose another --out (out)",
            ),
            (
                OptimError::NoRun {
                    path: "out/run.ron".into(),
                },
                "--resume (resume=True): no run to continue (out/run.ron is missing)",
            ),
            (
                OptimError::CorruptLog {
                    path: "e.jsonl".into(),
                    line: 3,
                    message: "EOF".into(),
                },
                "e.jsonl:3: corrupt record: EOF",
            ),
            (
                OptimError::ReplayMismatch {
                    id: 4,
                    logged: vec![0.5],
                    asked: vec![0.25],
                },
                "--resume (resume=True): logged candidate 4 has x = [0.5] but the replayed search asks for x = [0.25] (the log was written by another version or edited)",
            ),
        ];
        for (e, text) in cases {
            assert_eq!(e.to_string(), text);
        }
    }
}
