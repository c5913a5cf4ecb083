//! The run directory's record of a search: `evaluations.jsonl` (one JSON object per
//! evaluation, appended and flushed as each evaluation finishes) and `run.ron` (the
//! effective config and the base design, to check that `--resume` continues the same
//! search).
//!
//! Lines are appended in the order evaluations finish, which varies with the thread
//! schedule; each carries its `id` (0 = the reference, candidates from 1 in the order
//! CMA-ES asks for them), and everything in a record except `eval_time_s` depends only on
//! the config and the seed.

use std::collections::BTreeMap;
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use serde::{Deserialize, Serialize};
use tdpcr::Tdpcr;

use crate::config::OptimConfig;
use crate::error::OptimError;
use crate::objectives::Outcome;

/// File name of the evaluation log in the run directory.
pub const LOG_FILE: &str = "evaluations.jsonl";
/// File name of the run identity (effective config and base design).
pub const RUN_FILE: &str = "run.ron";

/// One evaluation, as logged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Record {
    /// 0 for the reference (base) design; candidates from 1, in the order asked.
    pub id: usize,
    /// CMA-ES generation (from 0); `None` for the reference.
    pub generation: Option<usize>,
    /// The point in the unit box (the reference's may lie outside \[0, 1\]).
    pub x: Vec<f64>,
    /// Parameter values by name (units: rad, m, N, see the config).
    pub parameters: BTreeMap<String, f64>,
    /// What the evaluation found.
    pub outcome: Outcome,
    /// The weighted composite (None when infeasible); recomputed on resume.
    pub composite: Option<f64>,
    /// Wall time of this evaluation \[s\] (other evaluations ran at the same time).
    pub eval_time_s: f64,
}

/// The identity of a run, stored as `run.ron`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunInfo {
    /// The config with the command-line overrides applied.
    pub config: OptimConfig,
    /// The base design as loaded.
    pub base_design: Tdpcr,
}

impl RunInfo {
    /// The text of `run.ron` (also how a run travels to another process).
    pub fn to_ron(&self) -> String {
        run_info_text(self)
    }

    /// Parses the text of [`RunInfo::to_ron`]; `source` names it in errors.
    ///
    /// # Errors
    /// [`OptimError::CorruptLog`] naming `source` and the line.
    pub fn from_ron(text: &str, source: &Path) -> Result<Self, OptimError> {
        ron::de::from_str(text).map_err(|e| OptimError::CorruptLog {
            path: source.to_path_buf(),
            line: e.span.start.line,
            message: e.code.to_string(),
        })
    }

    /// The differences that forbid resuming `stored` with `self`: every config field
    /// except the budget (which may grow) and the base design's path (its content is
    /// compared instead). Returns (field, stored, now) triples.
    pub fn differences(&self, stored: &RunInfo) -> Vec<(String, String, String)> {
        let (a, b) = (&stored.config, &self.config);
        let mut out = Vec::new();
        let mut cmp = |field: &str, x: String, y: String| {
            if x != y {
                out.push((field.to_string(), x, y));
            }
        };
        cmp(
            "parameters",
            format!("{:?}", a.parameters),
            format!("{:?}", b.parameters),
        );
        cmp(
            "evaluation",
            format!("{:?}", a.evaluation),
            format!("{:?}", b.evaluation),
        );
        cmp(
            "objectives",
            format!("{:?}", a.objectives),
            format!("{:?}", b.objectives),
        );
        cmp("seed", a.seed.to_string(), b.seed.to_string());
        cmp(
            "population",
            a.population_size().to_string(),
            b.population_size().to_string(),
        );
        cmp(
            "initial_step",
            a.initial_step.to_string(),
            b.initial_step.to_string(),
        );
        if stored.base_design != self.base_design {
            cmp(
                "base_design (content)",
                stored.base_design.to_ron_string(),
                self.base_design.to_ron_string(),
            );
        }
        out
    }
}

/// The append-only evaluation log.
#[derive(Debug)]
pub struct ResultsLog {
    path: PathBuf,
    /// Shared with the [`RunLock`]s handed out: the lock lasts while any of them lives.
    file: Arc<Mutex<File>>,
}

/// The lock of a run directory's log, held while this (or a clone) lives: the search's
/// result keeps it until its outputs are written, so that no other search (new or
/// resumed) starts on the directory between the last record and the report.
#[derive(Clone)]
pub struct RunLock {
    _file: Arc<Mutex<File>>,
}

impl std::fmt::Debug for RunLock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("RunLock")
    }
}

impl ResultsLog {
    /// Starts a new run in `dir` (created if missing): writes `run.ron` and an empty log.
    ///
    /// # Errors
    /// [`OptimError::RunExists`] if `dir` already holds a log with records;
    /// [`OptimError::Io`].
    pub fn create(dir: &Path, info: &RunInfo) -> Result<Self, OptimError> {
        check_dir(dir)?;
        std::fs::create_dir_all(dir).map_err(|source| OptimError::io(dir, source))?;
        let path = dir.join(LOG_FILE);
        let file = open_locked(&path)?;
        let len = file
            .metadata()
            .map_err(|source| OptimError::io(&path, source))?
            .len();
        if len > 0 {
            return Err(OptimError::RunExists { path });
        }
        tdpcr::output::write_atomically(&dir.join(RUN_FILE), run_info_text(info).as_bytes())?;
        Ok(Self {
            path,
            file: Arc::new(Mutex::new(file)),
        })
    }

    /// Reopens the run in `dir` for `--resume`: checks that `info` matches the stored
    /// `run.ron`, reads every record, drops a torn last line (an interrupted write), and
    /// rewrites `run.ron` (the budget may have grown; an evaluation budget below the
    /// log's records is a [`OptimError::ResumeMismatch`]).
    ///
    /// # Errors
    /// [`OptimError::NoRun`], [`OptimError::ResumeMismatch`], [`OptimError::CorruptLog`]
    /// (a bad line other than the last), [`OptimError::Io`].
    pub fn resume(
        dir: &Path,
        info: &RunInfo,
    ) -> Result<(Self, BTreeMap<usize, Record>), OptimError> {
        check_dir(dir)?;
        let run_path = dir.join(RUN_FILE);
        let path = dir.join(LOG_FILE);
        let text = match std::fs::read_to_string(&run_path) {
            Ok(t) => t,
            Err(_) => return Err(OptimError::NoRun { path: run_path }),
        };
        let stored = RunInfo::from_ron(&text, &run_path)?;
        let diffs = info.differences(&stored);
        if !diffs.is_empty() {
            return Err(OptimError::ResumeMismatch {
                dir: dir.to_path_buf(),
                differences: diffs
                    .into_iter()
                    .map(|(f, a, b)| format!("\n  - {f}: stored {a}, now {b}"))
                    .collect(),
            });
        }
        // Locked before it is read: another search on this directory keeps it. Read
        // through the locked handle (where locks are mandatory, others cannot read it).
        let mut file = open_locked(&path)?;
        // As bytes: a write torn inside a multi-byte character leaves a last line that is
        // not UTF-8 (dropped below as any torn line; the whole file as text would not read).
        let mut content = Vec::new();
        file.read_to_end(&mut content)
            .map_err(|source| OptimError::io(&path, source))?;
        let mut records = BTreeMap::new();
        let mut good_len = 0;
        let lines: Vec<&[u8]> = content.split_inclusive(|&b| b == b'\n').collect();
        for (i, line) in lines.iter().enumerate() {
            let last = i + 1 == lines.len();
            let parsed = std::str::from_utf8(line)
                .map_err(|e| e.to_string())
                .and_then(|text| {
                    serde_json::from_str::<Record>(text.trim_end()).map_err(|e| e.to_string())
                });
            match (parsed, line.ends_with(b"\n")) {
                (Ok(r), true) => {
                    records.insert(r.id, r);
                    good_len += line.len();
                }
                (Err(message), _) if !last => {
                    return Err(OptimError::CorruptLog {
                        path,
                        line: i + 1,
                        message,
                    });
                }
                // The last line torn by an interrupted write: dropped, evaluated again.
                _ => break,
            }
        }
        // A smaller budget ended the replay early and rewrote the outputs from fewer
        // candidates than the log holds (the best ones lost from the report). The budget
        // counts the candidates after the reference (id 0).
        let candidates = records.range(1..).count();
        if let Some(budget) = info.config.budget.evaluations
            && budget < candidates
        {
            return Err(OptimError::ResumeMismatch {
                dir: dir.to_path_buf(),
                differences: format!(
                    "\n  - budget.evaluations: the log holds {n} candidates, now {budget}: a \
                     resumed run goes on from its log (pass --budget-evals {n} or more, or \
                     choose another --out (out))",
                    n = candidates
                ),
            });
        }
        file.set_len(good_len as u64)
            .and_then(|()| file.seek(SeekFrom::End(0)))
            .map_err(|source| OptimError::io(&path, source))?;
        tdpcr::output::write_atomically(&run_path, run_info_text(info).as_bytes())?;
        Ok((
            Self {
                path,
                file: Arc::new(Mutex::new(file)),
            },
            records,
        ))
    }

    /// Appends one record as one line and flushes it.
    ///
    /// # Errors
    /// [`OptimError::Io`].
    pub fn append(&self, record: &Record) -> Result<(), OptimError> {
        let mut line = serde_json::to_string(record).expect("records always serialize");
        line.push('\n');
        let mut file = self.file.lock().unwrap_or_else(|e| e.into_inner());
        file.write_all(line.as_bytes())
            .and_then(|()| file.flush())
            .map_err(|source| OptimError::io(&self.path, source))
    }

    /// The log's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A handle that keeps the log locked after this log is dropped.
    pub fn run_lock(&self) -> RunLock {
        RunLock {
            _file: Arc::clone(&self.file),
        }
    }
}

/// A run directory that names something that can be a directory: an empty path put the
/// log in the working directory.
fn check_dir(dir: &Path) -> Result<(), OptimError> {
    if dir.as_os_str().is_empty() {
        return Err(OptimError::NoOutDir);
    }
    // A file there failed later as an I/O error ("File exists", exit 1).
    if dir.exists() && !dir.is_dir() {
        return Err(OptimError::NotADirectory {
            path: dir.to_path_buf(),
        });
    }
    Ok(())
}

/// The log at `path` (created if missing, not truncated), locked for this search alone
/// for as long as the handle lives: a second search on the same directory started a new
/// log over the first's, and both appended to it.
///
/// # Errors
/// [`OptimError::RunInUse`] if another search (of this or another process) holds it;
/// [`OptimError::Io`]. Where the file system does not support locks, the log is used
/// unlocked.
fn open_locked(path: &Path) -> Result<File, OptimError> {
    let file = OpenOptions::new()
        .create(true)
        .read(true)
        .write(true)
        .truncate(false)
        .open(path)
        .map_err(|source| OptimError::io(path, source))?;
    match file.try_lock() {
        Ok(()) => Ok(file),
        Err(std::fs::TryLockError::WouldBlock) => Err(OptimError::RunInUse {
            path: path.to_path_buf(),
        }),
        // A file system without locks (some network and FUSE mounts): unlocked, as before.
        Err(std::fs::TryLockError::Error(source))
            if source.kind() == std::io::ErrorKind::Unsupported =>
        {
            Ok(file)
        }
        Err(std::fs::TryLockError::Error(source)) => Err(OptimError::io(path, source)),
    }
}

fn run_info_text(info: &RunInfo) -> String {
    let pretty = ron::ser::PrettyConfig::new().struct_names(true);
    let body = ron::ser::to_string_pretty(info, pretty).expect("run info always serializes");
    format!(
        "// tdpcr-optim run identity: --resume continues this run only with the same settings.\n{body}\n"
    )
}

/// Reads every complete record of a log file, sorted by id (for tests and tools).
///
/// # Errors
/// [`OptimError::Io`], [`OptimError::CorruptLog`].
pub fn read_log(path: &Path) -> Result<Vec<Record>, OptimError> {
    let content = std::fs::read_to_string(path).map_err(|source| OptimError::io(path, source))?;
    let mut records = Vec::new();
    for (i, line) in content.lines().enumerate() {
        let r: Record = serde_json::from_str(line).map_err(|e| OptimError::CorruptLog {
            path: path.to_path_buf(),
            line: i + 1,
            message: e.to_string(),
        })?;
        records.push(r);
    }
    records.sort_by_key(|r| r.id);
    Ok(records)
}
