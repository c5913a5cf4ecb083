//! The search loop: the reference evaluation, then CMA-ES generations whose candidates are
//! evaluated in parallel, every evaluation logged as it finishes, until a budget or
//! convergence ends it (argmin's split: the problem is an [`Evaluator`] on a
//! [`ParameterSpace`], the method is [`CmaEs`], progress goes to an [`Observer`], and
//! the end is a [`TerminationReason`]).
//!
//! **Reproducibility.** CMA-ES draws every random number on this thread from the seed,
//! the candidates are evaluated independently, and the results are told in candidate
//! order: the same config, seed and budget give the same candidates and outcomes whatever
//! the number of threads. **Resume** replays the search from the seed, taking the outcome
//! of every candidate already in the log instead of evaluating it again, so an interrupted
//! run that is resumed ends exactly as an uninterrupted one.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use rayon::prelude::*;
use tdpcr::Tdpcr;
use tdpcr::error::Violations;

use crate::cmaes::{CmaEs, CmaesSettings, Convergence};
use crate::config::OptimConfig;
use crate::error::OptimError;
use crate::evaluate::{Evaluator, evaluate_design, evaluate_point};
use crate::objectives::Composite;
use crate::pareto::{dominates, pareto_front};
use crate::runlog::{Record, ResultsLog, RunInfo};
use crate::space::ParameterSpace;

/// Stop when every coordinate's standard deviation is below this (box units): far below
/// the resolution of a coarse workspace evaluation.
pub const CONVERGENCE_TOLERANCE: f64 = 1e-4;

/// Command-line overrides of the config.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Overrides {
    /// Replaces `budget.evaluations`.
    pub budget_evals: Option<usize>,
    /// Replaces `seed`.
    pub seed: Option<u64>,
}

impl Overrides {
    /// Writes the given overrides into `config`.
    pub fn apply(&self, config: &mut OptimConfig) {
        if let Some(n) = self.budget_evals {
            config.budget.evaluations = Some(n);
        }
        if let Some(s) = self.seed {
            config.seed = s;
        }
    }
}

/// A validated search: the effective config and its parameter space around the base
/// design.
#[derive(Debug, Clone)]
pub struct Setup {
    /// The config with the overrides applied.
    pub config: OptimConfig,
    /// Where the config was read from.
    pub config_path: PathBuf,
    /// The varying parameters on the base design.
    pub space: ParameterSpace,
}

impl Setup {
    /// Loads the config, applies `overrides`, loads the base design (relative to the
    /// config file) and checks the rules that involve both.
    ///
    /// # Errors
    /// [`OptimError::Config`] listing every problem.
    pub fn load(config_path: &Path, overrides: &Overrides) -> Result<Self, OptimError> {
        let mut config = OptimConfig::parse_ron_file(config_path)?;
        overrides.apply(&mut config);
        config.validate(&config_path.display().to_string())?;
        let base = Tdpcr::from_ron_file(config.base_design_path(config_path))?;
        Self::new(config, base, config_path, &Overrides::default())
    }

    /// A setup from a parsed config and base design.
    ///
    /// # Errors
    /// [`OptimError::Config`] listing every problem of the config with the overrides.
    pub fn new(
        mut config: OptimConfig,
        base: Tdpcr,
        config_path: &Path,
        overrides: &Overrides,
    ) -> Result<Self, OptimError> {
        overrides.apply(&mut config);
        let mut v = Violations::default();
        config.check(Some(&base), &mut v);
        v.into_result(&config_path.display().to_string())?;
        let space = ParameterSpace::new(base, config.parameters.clone());
        Ok(Self {
            config,
            config_path: config_path.to_path_buf(),
            space,
        })
    }

    /// The run identity stored in the output directory.
    pub fn run_info(&self) -> RunInfo {
        RunInfo {
            config: self.config.clone(),
            base_design: self.space.base().clone(),
        }
    }

    /// Parameter values of `x` by name.
    pub fn parameter_map(&self, values: &[f64]) -> BTreeMap<String, f64> {
        self.space
            .bounds()
            .iter()
            .zip(values)
            .map(|(b, &v)| (b.parameter.name().to_string(), v))
            .collect()
    }
}

/// Why the search ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TerminationReason {
    /// The evaluation budget is used up.
    EvaluationBudget {
        /// Candidate evaluations.
        evaluations: usize,
    },
    /// The wall-time budget is used up.
    WallTime {
        /// The budget \[s\].
        seconds: f64,
    },
    /// CMA-ES converged (or degenerated).
    Converged(Convergence),
}

impl std::fmt::Display for TerminationReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::EvaluationBudget { evaluations } => {
                write!(f, "evaluation budget reached ({evaluations} candidates)")
            }
            Self::WallTime { seconds } => write!(f, "wall-time budget reached ({seconds} s)"),
            Self::Converged(c) => write!(f, "{c}"),
        }
    }
}

/// Progress after one evaluation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvaluationStatus {
    /// Candidates done so far (evaluated or taken from the log).
    pub done: usize,
    /// The evaluation budget.
    pub budget: Option<usize>,
    /// Time since the start of this invocation \[s\].
    pub elapsed_s: f64,
    /// Taken from the log of a resumed run (not evaluated again).
    pub from_log: bool,
}

/// Progress after one generation.
#[derive(Debug, Clone, PartialEq)]
pub struct GenerationReport {
    /// Generation index (from 0).
    pub generation: usize,
    /// Candidates done so far.
    pub done: usize,
    /// Feasible candidates in this generation.
    pub feasible: usize,
    /// Best composite so far and its candidate id.
    pub best: Option<(f64, usize)>,
    /// CMA-ES step size σ after the update (box units).
    pub sigma: f64,
    /// Time since the start of this invocation \[s\].
    pub elapsed_s: f64,
}

/// Receives progress (argmin's observers). `evaluated` is called from worker threads.
pub trait Observer: Sync {
    /// After the reference's evaluation.
    fn reference(&self, _record: &Record) {}
    /// After each candidate (evaluated or taken from the log).
    fn evaluated(&self, _record: &Record, _status: &EvaluationStatus) {}
    /// After each complete generation.
    fn generation(&self, _report: &GenerationReport) {}
}

/// An observer that ignores everything.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Observer for Silent {}

/// The result of a search.
#[derive(Debug, Clone)]
pub struct SearchResult {
    /// The reference (base) design's record (id 0).
    pub reference: Record,
    /// Every candidate of this search, sorted by id.
    pub candidates: Vec<Record>,
    /// The composite objective (normalized by the reference).
    pub composite: Composite,
    /// Why it ended.
    pub termination: TerminationReason,
    /// Candidates evaluated in this invocation.
    pub evaluated: usize,
    /// Candidates taken from the log (resume).
    pub from_log: usize,
    /// Complete CMA-ES generations.
    pub generations: usize,
    /// Wall time of this invocation \[s\].
    pub wall_time_s: f64,
}

impl SearchResult {
    /// The feasible candidate with the largest composite (lowest id on ties).
    pub fn best_composite(&self) -> Option<&Record> {
        self.candidates
            .iter()
            .filter_map(|r| r.composite.map(|c| (c, r)))
            .fold(None, |best: Option<(f64, &Record)>, (c, r)| match best {
                Some((b, _)) if b >= c => best,
                _ => Some((c, r)),
            })
            .map(|(_, r)| r)
    }

    /// The Pareto front of the feasible candidates on the three objectives, by id.
    pub fn pareto_front(&self) -> Vec<&Record> {
        let feasible: Vec<&Record> = self
            .candidates
            .iter()
            .filter(|r| r.outcome.measures().is_some())
            .collect();
        let points: Vec<[f64; 3]> = feasible
            .iter()
            .filter_map(|r| r.outcome.measures().map(|m| m.pareto()))
            .collect();
        pareto_front(&points)
            .into_iter()
            .map(|i| feasible[i])
            .collect()
    }

    /// The front member with the largest value of Pareto objective `k` (0 volume, 1
    /// isotropy, 2 margin), lowest id on ties.
    pub fn pareto_extreme(&self, k: usize) -> Option<&Record> {
        let front = self.pareto_front();
        front
            .iter()
            .copied()
            .filter_map(|r| r.outcome.measures().map(|m| (m.pareto()[k], r)))
            .fold(None, |best: Option<(f64, &Record)>, (v, r)| match best {
                Some((b, _)) if b >= v => best,
                _ => Some((v, r)),
            })
            .map(|(_, r)| r)
    }

    /// The candidates that Pareto-dominate the reference on the three objectives.
    pub fn dominating_reference(&self) -> Vec<&Record> {
        let Some(reference) = self.reference.outcome.measures() else {
            return self.pareto_front();
        };
        let r = reference.pareto();
        self.candidates
            .iter()
            .filter(|c| {
                c.outcome
                    .measures()
                    .is_some_and(|m| dominates(&m.pareto(), &r))
            })
            .collect()
    }
}

/// Runs (or, with `resume`, continues) the search of `setup` with `evaluator`, logging to
/// `dir`.
///
/// # Errors
/// [`OptimError::RunExists`] / [`OptimError::NoRun`] / [`OptimError::ResumeMismatch`] /
/// [`OptimError::ReplayMismatch`] / [`OptimError::CorruptLog`] for a directory that does
/// not fit the request, [`OptimError::Io`] if the log cannot be written.
pub fn run_search(
    setup: &Setup,
    evaluator: &dyn Evaluator,
    dir: &Path,
    resume: bool,
    observer: &dyn Observer,
) -> Result<SearchResult, OptimError> {
    let start = Instant::now();
    let config = &setup.config;
    let space = &setup.space;
    let (log, logged) = if resume {
        ResultsLog::resume(dir, &setup.run_info())?
    } else {
        (ResultsLog::create(dir, &setup.run_info())?, BTreeMap::new())
    };

    let base_values = space.values_of(space.base());
    let base_x = space.normalize(&base_values);
    let reference = match logged.get(&0) {
        Some(r) => r.clone(),
        None => {
            let t = Instant::now();
            let outcome = evaluate_design(evaluator, space.base());
            let record = Record {
                id: 0,
                generation: None,
                x: base_x.clone(),
                parameters: setup.parameter_map(&base_values),
                outcome,
                composite: None,
                eval_time_s: t.elapsed().as_secs_f64(),
            };
            log.append(&record)?;
            record
        }
    };
    let composite = Composite::new(
        &config.objectives,
        config.aggregation,
        reference.outcome.measures(),
    );
    let reference = Record {
        composite: composite.of(&reference.outcome),
        ..reference
    };
    observer.reference(&reference);

    let lambda = config.population_size();
    let x0: Vec<f64> = base_x.iter().map(|v| v.clamp(0.0, 1.0)).collect();
    let mut es = CmaEs::new(
        &CmaesSettings::new(x0, config.initial_step, lambda)?,
        config.seed,
    );
    let budget = config.budget.evaluations;
    let deadline = config
        .budget
        .wall_time_s
        .map(|s| start + Duration::from_secs_f64(s));
    let past_deadline = || deadline.is_some_and(|d| Instant::now() >= d);
    let mut candidates: Vec<Record> = Vec::new();
    let (mut evaluated, mut from_log) = (0usize, 0usize);
    let mut best: Option<(f64, usize)> = None;
    let termination = loop {
        let remaining = budget.map_or(usize::MAX, |b| b.saturating_sub(candidates.len()));
        if remaining == 0 {
            break TerminationReason::EvaluationBudget {
                evaluations: candidates.len(),
            };
        }
        if let Some(c) = es.convergence(CONVERGENCE_TOLERANCE) {
            break TerminationReason::Converged(c);
        }
        let wall = || TerminationReason::WallTime {
            seconds: config.budget.wall_time_s.unwrap_or(0.0),
        };
        if past_deadline() {
            break wall();
        }
        let generation = es.generation();
        let xs = es.ask();
        let first_id = candidates.len() + 1;
        let count = lambda.min(remaining);
        let done = AtomicUsize::new(candidates.len());
        let status = |from_log| EvaluationStatus {
            done: done.fetch_add(1, Ordering::Relaxed) + 1,
            budget,
            elapsed_s: start.elapsed().as_secs_f64(),
            from_log,
        };
        let mut slots: Vec<Option<Record>> = vec![None; count];
        let mut todo = Vec::new();
        for (i, slot) in slots.iter_mut().enumerate() {
            let id = first_id + i;
            match logged.get(&id) {
                Some(r) if r.x != xs[i] => {
                    return Err(OptimError::ReplayMismatch {
                        id,
                        logged: r.x.clone(),
                        asked: xs[i].clone(),
                    });
                }
                Some(r) => {
                    let record = Record {
                        composite: composite.of(&r.outcome),
                        ..r.clone()
                    };
                    observer.evaluated(&record, &status(true));
                    from_log += 1;
                    *slot = Some(record);
                }
                None => todo.push(i),
            }
        }
        let results: Vec<(usize, Option<Result<Record, OptimError>>)> = todo
            .par_iter()
            .map(|&i| {
                if past_deadline() {
                    return (i, None);
                }
                let (outcome, eval_time_s) = evaluate_point(space, evaluator, &xs[i]);
                let record = Record {
                    id: first_id + i,
                    generation: Some(generation),
                    x: xs[i].clone(),
                    parameters: setup.parameter_map(&space.values(&xs[i])),
                    composite: composite.of(&outcome),
                    outcome,
                    eval_time_s,
                };
                let logged = log.append(&record);
                if logged.is_ok() {
                    observer.evaluated(&record, &status(false));
                }
                (i, Some(logged.map(|()| record)))
            })
            .collect();
        for (i, r) in results {
            if let Some(r) = r {
                slots[i] = Some(r?);
                evaluated += 1;
            }
        }
        let complete = count == lambda && slots.iter().all(Option::is_some);
        let fitness: Vec<f64> = slots
            .iter()
            .flatten()
            .map(|r| composite.fitness(&r.outcome))
            .collect();
        for r in slots.iter().flatten() {
            if let Some(c) = r.composite {
                if best.is_none_or(|(b, _)| c > b) {
                    best = Some((c, r.id));
                }
            }
        }
        let feasible = slots
            .iter()
            .flatten()
            .filter(|r| r.composite.is_some())
            .count();
        candidates.extend(slots.into_iter().flatten());
        if !complete {
            // A partial generation: the budget or the deadline cut it.
            break if past_deadline() && candidates.len() < budget.unwrap_or(usize::MAX) {
                wall()
            } else {
                TerminationReason::EvaluationBudget {
                    evaluations: candidates.len(),
                }
            };
        }
        es.tell(&fitness)?;
        observer.generation(&GenerationReport {
            generation,
            done: candidates.len(),
            feasible,
            best,
            sigma: es.sigma(),
            elapsed_s: start.elapsed().as_secs_f64(),
        });
    };
    Ok(SearchResult {
        reference,
        candidates,
        composite,
        termination,
        evaluated,
        from_log,
        generations: es.generation(),
        wall_time_s: start.elapsed().as_secs_f64(),
    })
}
