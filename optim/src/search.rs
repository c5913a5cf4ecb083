//! The search loop: the reference evaluation, then CMA-ES generations whose candidates are
//! evaluated in parallel, every evaluation logged as it finishes, until a budget or
//! convergence ends it (argmin's split: the problem is an [`Evaluator`] on a
//! [`ParameterSpace`], the method is [`CmaEs`], progress goes to an [`Observer`], and
//! the end is a [`TerminationReason`]).
//!
//! The steps are those of [`Search`], a driver that any executor can run: [`Search::ask`]
//! hands out the candidates to evaluate (the reference first), anyone evaluates them
//! with [`evaluate_candidate`] (a pure function of the setup and the candidate),
//! [`Search::record`] logs one result, [`Search::tell`] ends the generation, and
//! [`Search::finish`] returns the [`SearchResult`]. [`run_search`] is these steps with
//! the evaluations on rayon's threads; the Python package runs the same steps with the
//! evaluations on a Dask cluster.
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
use serde::{Deserialize, Serialize};
use tdpcr::Tdpcr;
use tdpcr::error::Violations;

use crate::cmaes::{CmaEs, CmaesSettings, Convergence};
use crate::config::OptimConfig;
use crate::error::OptimError;
use crate::evaluate::{Evaluator, evaluate_design, evaluate_point};
use crate::objectives::Composite;
use crate::objectives::Outcome;
use crate::pareto::{dominates, pareto_front};
use crate::runlog::{Record, ResultsLog, RunInfo, RunLock};
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

    /// The setup of a run identity (as sent to another process); `source` names it in
    /// errors.
    ///
    /// # Errors
    /// [`OptimError::Config`] listing every problem.
    pub fn from_run_info(info: RunInfo, source: &Path) -> Result<Self, OptimError> {
        Self::new(info.config, info.base_design, source, &Overrides::default())
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

/// One candidate to evaluate: the reference (id 0, the base design itself) or a point of
/// a CMA-ES generation. Serializable, to send it to another process.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Candidate {
    /// 0 for the reference; candidates from 1, in the order asked.
    pub id: usize,
    /// CMA-ES generation (from 0); `None` for the reference.
    pub generation: Option<usize>,
    /// The point in the unit box (the reference's may lie outside \[0, 1\]).
    pub x: Vec<f64>,
}

/// The result of one candidate's evaluation, as [`evaluate_candidate`] returns it.
/// Serializable, to send it back from another process.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Evaluation {
    /// The candidate's id.
    pub id: usize,
    /// What the evaluation found.
    pub outcome: Outcome,
    /// Wall time of the evaluation \[s\].
    pub eval_time_s: f64,
}

/// Evaluates `candidate` of the search `setup` with `evaluator`: the base design itself
/// for the reference, else the design of the candidate's box point. A pure function of
/// its arguments (except the wall time), callable on any thread or machine.
pub fn evaluate_candidate(
    setup: &Setup,
    evaluator: &dyn Evaluator,
    candidate: &Candidate,
) -> Evaluation {
    let (outcome, eval_time_s) = if candidate.id == 0 {
        let t = Instant::now();
        let outcome = evaluate_design(evaluator, setup.space.base());
        (outcome, t.elapsed().as_secs_f64())
    } else {
        evaluate_point(&setup.space, evaluator, &candidate.x)
    };
    Evaluation {
        id: candidate.id,
        outcome,
        eval_time_s,
    }
}

/// The generation between [`Search::ask`] and [`Search::tell`].
#[derive(Debug)]
struct Pending {
    /// Generation index (from 0).
    generation: usize,
    /// Id of the generation's first candidate.
    first_id: usize,
    /// The points CMA-ES asked for (λ of them).
    xs: Vec<Vec<f64>>,
    /// One slot per candidate within the budget; `Some` once done.
    slots: Vec<Option<Record>>,
}

impl Pending {
    fn candidate(&self, i: usize) -> Candidate {
        Candidate {
            id: self.first_id + i,
            generation: Some(self.generation),
            x: self.xs[i].clone(),
        }
    }

    /// The candidates whose slot is empty.
    fn todo(&self) -> Vec<Candidate> {
        (0..self.slots.len())
            .filter(|&i| self.slots[i].is_none())
            .map(|i| self.candidate(i))
            .collect()
    }
}

/// A search as a sequence of steps (ask, evaluate anywhere, record, tell, finish), with
/// its log and resume. See the module documentation.
pub struct Search<'a> {
    setup: Setup,
    observer: &'a dyn Observer,
    start: Instant,
    deadline: Option<Instant>,
    log: ResultsLog,
    /// Records of a resumed run's log by id.
    logged: BTreeMap<usize, Record>,
    /// The reference's record and the composite it normalizes, once evaluated.
    reference: Option<(Record, Composite)>,
    es: CmaEs,
    pending: Option<Pending>,
    /// Candidates done so far (evaluated or taken from the log), by id.
    candidates: Vec<Record>,
    /// Candidates done, counted by [`Search::record`] from any thread.
    done: AtomicUsize,
    evaluated: usize,
    from_log: usize,
    best: Option<(f64, usize)>,
    termination: Option<TerminationReason>,
}

impl<'a> Search<'a> {
    /// Starts (or, with `resume`, continues) the search of `setup`, logging to `dir`.
    ///
    /// # Errors
    /// [`OptimError::RunExists`] / [`OptimError::NoRun`] / [`OptimError::ResumeMismatch`] /
    /// [`OptimError::CorruptLog`] for a directory that does not fit the request,
    /// [`OptimError::Io`] if the log cannot be written.
    pub fn open(
        setup: Setup,
        dir: &Path,
        resume: bool,
        observer: &'a dyn Observer,
    ) -> Result<Self, OptimError> {
        let start = Instant::now();
        let (log, logged) = if resume {
            ResultsLog::resume(dir, &setup.run_info())?
        } else {
            (ResultsLog::create(dir, &setup.run_info())?, BTreeMap::new())
        };
        let config = &setup.config;
        let x0: Vec<f64> = setup
            .space
            .normalize(&setup.space.values_of(setup.space.base()))
            .iter()
            .map(|v| v.clamp(0.0, 1.0))
            .collect();
        let es = CmaEs::new(
            &CmaesSettings::new(x0, config.initial_step, config.population_size())?,
            config.seed,
        );
        let deadline = config
            .budget
            .wall_time_s
            .map(|s| start + Duration::from_secs_f64(s));
        let mut search = Self {
            observer,
            start,
            deadline,
            log,
            logged,
            reference: None,
            es,
            pending: None,
            candidates: Vec::new(),
            done: AtomicUsize::new(0),
            evaluated: 0,
            from_log: 0,
            best: None,
            termination: None,
            setup,
        };
        if let Some(r) = search.logged.get(&0).cloned() {
            search.set_reference(r);
        }
        Ok(search)
    }

    /// The search's setup.
    pub fn setup(&self) -> &Setup {
        &self.setup
    }

    /// Why the search ended, once [`Search::ask`] has found that it has.
    pub fn termination(&self) -> Option<TerminationReason> {
        self.termination
    }

    fn past_deadline(&self) -> bool {
        self.deadline.is_some_and(|d| Instant::now() >= d)
    }

    fn set_reference(&mut self, reference: Record) {
        let config = &self.setup.config;
        let composite = Composite::new(
            &config.objectives,
            config.aggregation,
            reference.outcome.measures(),
        );
        let reference = Record {
            composite: composite.of(&reference.outcome),
            ..reference
        };
        self.observer.reference(&reference);
        self.reference = Some((reference, composite));
    }

    /// The candidates to evaluate next: the reference alone first, then the candidates of
    /// one generation that are not in the log of a resumed run (generations entirely in
    /// the log are replayed here). Empty when the search has ended. Asking again before
    /// [`Search::tell`] returns the generation's candidates still missing.
    ///
    /// # Errors
    /// [`OptimError::ReplayMismatch`] if a logged candidate is not the one asked for.
    pub fn ask(&mut self) -> Result<Vec<Candidate>, OptimError> {
        let Some((_, composite)) = &self.reference else {
            let space = &self.setup.space;
            return Ok(vec![Candidate {
                id: 0,
                generation: None,
                x: space.normalize(&space.values_of(space.base())),
            }]);
        };
        let composite = composite.clone();
        loop {
            if self.termination.is_some() {
                return Ok(Vec::new());
            }
            if let Some(p) = &self.pending {
                return Ok(p.todo());
            }
            let budget = self.setup.config.budget.evaluations;
            let remaining = budget.map_or(usize::MAX, |b| b.saturating_sub(self.candidates.len()));
            if remaining == 0 {
                self.termination = Some(TerminationReason::EvaluationBudget {
                    evaluations: self.candidates.len(),
                });
                continue;
            }
            if let Some(c) = self.es.convergence(CONVERGENCE_TOLERANCE) {
                self.termination = Some(TerminationReason::Converged(c));
                continue;
            }
            if self.past_deadline() {
                self.termination = Some(self.wall_time());
                continue;
            }
            let lambda = self.setup.config.population_size();
            let mut pending = Pending {
                generation: self.es.generation(),
                first_id: self.candidates.len() + 1,
                xs: self.es.ask(),
                slots: vec![None; lambda.min(remaining)],
            };
            self.done.store(self.candidates.len(), Ordering::Relaxed);
            for i in 0..pending.slots.len() {
                let id = pending.first_id + i;
                let Some(r) = self.logged.get(&id) else {
                    continue;
                };
                if r.x != pending.xs[i] {
                    return Err(OptimError::ReplayMismatch {
                        id,
                        logged: r.x.clone(),
                        asked: pending.xs[i].clone(),
                    });
                }
                let record = Record {
                    composite: composite.of(&r.outcome),
                    ..r.clone()
                };
                self.observer.evaluated(&record, &self.status(true));
                self.from_log += 1;
                pending.slots[i] = Some(record);
            }
            let todo = pending.todo();
            self.pending = Some(pending);
            if !todo.is_empty() {
                return Ok(todo);
            }
            self.tell(Vec::new())?;
        }
    }

    fn wall_time(&self) -> TerminationReason {
        TerminationReason::WallTime {
            seconds: self.setup.config.budget.wall_time_s.unwrap_or(0.0),
        }
    }

    fn status(&self, from_log: bool) -> EvaluationStatus {
        EvaluationStatus {
            done: self.done.fetch_add(1, Ordering::Relaxed) + 1,
            budget: self.setup.config.budget.evaluations,
            elapsed_s: self.start.elapsed().as_secs_f64(),
            from_log,
        }
    }

    /// Logs the evaluation of `candidate` (one line, flushed) and returns its record, to
    /// be told. Callable from several threads at once, in any order.
    ///
    /// # Errors
    /// [`OptimError::Io`] if the log cannot be written.
    pub fn record(
        &self,
        candidate: &Candidate,
        evaluation: Evaluation,
    ) -> Result<Record, OptimError> {
        let space = &self.setup.space;
        let values = if candidate.id == 0 {
            space.values_of(space.base())
        } else {
            space.values(&candidate.x)
        };
        let record = Record {
            id: candidate.id,
            generation: candidate.generation,
            x: candidate.x.clone(),
            parameters: self.setup.parameter_map(&values),
            composite: self
                .reference
                .as_ref()
                .and_then(|(_, c)| c.of(&evaluation.outcome)),
            outcome: evaluation.outcome,
            eval_time_s: evaluation.eval_time_s,
        };
        self.log.append(&record)?;
        if candidate.id != 0 {
            self.observer.evaluated(&record, &self.status(false));
        }
        Ok(record)
    }

    /// Takes the records of the candidates asked for (any order; those not evaluated
    /// because the wall time ran out left out): the reference's, or the generation's,
    /// which is then told to CMA-ES. The records of a generation may come in several
    /// calls: until all are in (or the wall time has run out, which ends the search with
    /// the generation cut short) it stays open and [`Search::ask`] returns the
    /// candidates still missing.
    ///
    /// # Errors
    /// [`OptimError::UnexpectedRecord`] for a record of a candidate that was not asked for
    /// (or given twice); [`OptimError::Cmaes`] on a misuse of the optimizer (a bug).
    pub fn tell(&mut self, records: Vec<Record>) -> Result<(), OptimError> {
        if self.reference.is_none() {
            let mut records = records.into_iter();
            match (records.next(), records.next()) {
                (Some(r), None) if r.id == 0 => self.set_reference(r),
                (r, _) => return Err(unexpected(r.map(|r| r.id), "the reference (id 0) alone")),
            }
            return Ok(());
        }
        let Some(mut pending) = self.pending.take() else {
            return Err(unexpected(
                records.first().map(|r| r.id),
                "no record: no generation is pending",
            ));
        };
        for r in records {
            let i = r.id.wrapping_sub(pending.first_id);
            match pending.slots.get_mut(i) {
                Some(slot @ None) => *slot = Some(r),
                _ => {
                    let expected = format!(
                        "the missing candidates of generation {} (ids {}..={})",
                        pending.generation,
                        pending.first_id,
                        pending.first_id + pending.slots.len() - 1
                    );
                    self.pending = Some(pending);
                    return Err(unexpected(Some(r.id), &expected));
                }
            }
            self.evaluated += 1;
        }
        if pending.slots.iter().any(Option::is_none) && !self.past_deadline() {
            // Results may come in pieces (a Python caller telling them as they arrive):
            // the generation stays open, and `ask` returns the candidates still missing.
            self.pending = Some(pending);
            return Ok(());
        }
        let composite = &self.reference.as_ref().expect("reference told").1;
        let complete =
            pending.slots.len() == pending.xs.len() && pending.slots.iter().all(Option::is_some);
        let fitness: Vec<f64> = pending
            .slots
            .iter()
            .flatten()
            .map(|r| composite.fitness(&r.outcome))
            .collect();
        for r in pending.slots.iter().flatten() {
            if let Some(c) = r.composite
                && self.best.is_none_or(|(b, _)| c > b)
            {
                self.best = Some((c, r.id));
            }
        }
        let feasible = pending
            .slots
            .iter()
            .flatten()
            .filter(|r| r.composite.is_some())
            .count();
        self.candidates.extend(pending.slots.into_iter().flatten());
        let budget = self.setup.config.budget.evaluations;
        if !complete {
            // A partial generation: the budget or the deadline cut it.
            self.termination = Some(
                if self.past_deadline() && self.candidates.len() < budget.unwrap_or(usize::MAX) {
                    self.wall_time()
                } else {
                    TerminationReason::EvaluationBudget {
                        evaluations: self.candidates.len(),
                    }
                },
            );
            return Ok(());
        }
        self.es.tell(&fitness)?;
        self.observer.generation(&GenerationReport {
            generation: pending.generation,
            done: self.candidates.len(),
            feasible,
            best: self.best,
            sigma: self.es.sigma(),
            elapsed_s: self.start.elapsed().as_secs_f64(),
        });
        Ok(())
    }

    /// [`Search::record`] then [`Search::tell`] of evaluations done elsewhere, logged in
    /// candidate order (whatever order they come in).
    ///
    /// # Errors
    /// As [`Search::record`] and [`Search::tell`]; nothing is logged if an evaluation is
    /// not of a candidate asked for.
    pub fn tell_evaluations(&mut self, mut evaluations: Vec<Evaluation>) -> Result<(), OptimError> {
        let asked = self.ask()?;
        evaluations.sort_by_key(|e| e.id);
        let mut pairs = Vec::with_capacity(evaluations.len());
        for (k, e) in evaluations.iter().enumerate() {
            let repeated = k > 0 && evaluations[k - 1].id == e.id;
            match asked.iter().find(|c| c.id == e.id) {
                Some(c) if !repeated => pairs.push((c.clone(), e.clone())),
                _ => return Err(unexpected(Some(e.id), "a candidate asked for, once")),
            }
        }
        let records = pairs
            .into_iter()
            .map(|(c, e)| self.record(&c, e))
            .collect::<Result<Vec<_>, _>>()?;
        self.tell(records)
    }

    /// The result, once [`Search::ask`] has returned no candidate.
    ///
    /// # Errors
    /// [`OptimError::UnexpectedRecord`] if the search has not ended.
    pub fn finish(self) -> Result<SearchResult, OptimError> {
        self.finish_holding_directory().map(|(result, _)| result)
    }

    /// [`Search::finish`], the run directory's log kept locked while the returned
    /// [`RunLock`] lives: for writing the outputs before another search (new or resumed)
    /// may start on the directory (one started in between wrote beside them).
    ///
    /// # Errors
    /// As [`Search::finish`].
    pub fn finish_holding_directory(self) -> Result<(SearchResult, RunLock), OptimError> {
        let lock = self.log.run_lock();
        let (Some(termination), Some((reference, composite))) = (self.termination, self.reference)
        else {
            return Err(unexpected(
                None,
                "ask until it returns no candidate before finishing",
            ));
        };
        let result = SearchResult {
            reference,
            candidates: self.candidates,
            composite,
            termination,
            evaluated: self.evaluated,
            from_log: self.from_log,
            generations: self.es.generation(),
            wall_time_s: self.start.elapsed().as_secs_f64(),
        };
        Ok((result, lock))
    }
}

fn unexpected(id: Option<usize>, expected: &str) -> OptimError {
    OptimError::UnexpectedRecord {
        id,
        expected: expected.to_string(),
    }
}

/// Runs (or, with `resume`, continues) the search of `setup` with `evaluator`, logging to
/// `dir`: the steps of [`Search`] with each generation's candidates evaluated on rayon's
/// threads, each logged as it finishes.
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
    run_search_holding_directory(setup, evaluator, dir, resume, observer).map(|(r, _)| r)
}

/// [`run_search`], the run directory kept locked while the returned [`RunLock`] lives
/// (as [`Search::finish_holding_directory`]): `tdpcr-optim` writes its outputs under it.
///
/// # Errors
/// As [`run_search`].
pub fn run_search_holding_directory(
    setup: &Setup,
    evaluator: &dyn Evaluator,
    dir: &Path,
    resume: bool,
    observer: &dyn Observer,
) -> Result<(SearchResult, RunLock), OptimError> {
    let mut search = Search::open(setup.clone(), dir, resume, observer)?;
    loop {
        let todo = search.ask()?;
        if todo.is_empty() {
            break;
        }
        let records: Vec<Option<Result<Record, OptimError>>> = todo
            .par_iter()
            .map(|c| {
                // The reference is always evaluated; a candidate not past the deadline.
                if c.id != 0 && search.past_deadline() {
                    return None;
                }
                Some(search.record(c, evaluate_candidate(setup, evaluator, c)))
            })
            .collect();
        let records = records
            .into_iter()
            .flatten()
            .collect::<Result<Vec<_>, _>>()?;
        search.tell(records)?;
    }
    search.finish_holding_directory()
}
