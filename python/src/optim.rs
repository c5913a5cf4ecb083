//! The design search of `tdpcr-optim` for a distributed driver (`tdpcr.optim`):
//! `DesignSearch` holds the search's steps (ask, tell, finish: CMA-ES, the log, resume
//! and the output files, all in Rust), `SearchProblem` evaluates one candidate with the
//! GIL released. Candidates, results and the problem travel as strings (JSON, RON), so
//! any executor can ship them to other processes.

use std::path::{Path, PathBuf};

use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use tdpcr_optim::OptimError;
use tdpcr_optim::report::{ReportContext, load_average, write_outputs};
use tdpcr_optim::runlog::{RunInfo, RunLock};
use tdpcr_optim::search::{
    Candidate, Evaluation, Overrides, Search, SearchResult, Setup, Silent, evaluate_candidate,
};
use tdpcr_optim::workspace_eval::{WorkspaceEvaluator, slice_sets};

/// An optimizer error as `ValueError` (bad input), `OSError` (I/O) or `RuntimeError`.
fn optim_error(e: OptimError) -> PyErr {
    let message = e.to_string();
    match e {
        OptimError::Io { .. } => PyOSError::new_err(message),
        e if e.is_input_error() => PyValueError::new_err(message),
        OptimError::UnexpectedRecord { .. } | OptimError::CorruptLog { .. } => {
            PyValueError::new_err(message)
        }
        _ => PyRuntimeError::new_err(message),
    }
}

fn json_error(what: &str, e: serde_json::Error) -> PyErr {
    PyValueError::new_err(format!("{what}: {e}"))
}

/// One search of `tdpcr-optim` in the run directory `out`, driven step by step:
/// `ask()` the candidates (JSON strings), evaluate them anywhere with
/// `SearchProblem(search.problem).evaluate(candidate)`, `tell(results)`, until `ask()`
/// returns nothing; then `finish()` writes the outputs. The log is written by `tell`
/// only, in candidate order.
#[pyclass(module = "tdpcr")]
pub struct DesignSearch {
    search: Option<Search<'static>>,
    /// The ended search's result once `finish` has taken it (kept, so that a `finish`
    /// whose outputs could not be written can be called again).
    result: Option<(Setup, SearchResult)>,
    /// The run directory's lock from the search's end until its outputs are written.
    directory: Option<RunLock>,
    out: PathBuf,
    problem: String,
}

impl DesignSearch {
    fn search(&mut self) -> PyResult<&mut Search<'static>> {
        self.search
            .as_mut()
            .ok_or_else(|| PyRuntimeError::new_err("the search is finished (or closed)"))
    }
}

#[pymethods]
impl DesignSearch {
    /// Opens the search of `config` (a RON file, as `tdpcr-optim`'s) in `out`; `seed` and
    /// `budget_evals` override the config's; `resume` continues the run in `out`.
    #[new]
    #[pyo3(signature = (config, out, *, seed=None, budget_evals=None, resume=false))]
    fn new(
        config: PathBuf,
        out: PathBuf,
        seed: Option<u64>,
        budget_evals: Option<usize>,
        resume: bool,
    ) -> PyResult<Self> {
        let overrides = Overrides { budget_evals, seed };
        let setup = Setup::load(&config, &overrides).map_err(optim_error)?;
        let problem = setup.run_info().to_ron();
        let search = Search::open(setup, &out, resume, &Silent).map_err(optim_error)?;
        Ok(Self {
            search: Some(search),
            result: None,
            directory: None,
            out,
            problem,
        })
    }

    /// The problem (effective config and base design, RON text) for `SearchProblem`.
    #[getter]
    fn problem(&self) -> &str {
        &self.problem
    }

    /// Candidates per generation (λ).
    #[getter]
    fn population(&mut self) -> PyResult<usize> {
        Ok(self.search()?.setup().config.population_size())
    }

    /// The candidates to evaluate next (JSON strings: `id`, `generation`, `x`): the
    /// reference first, then one generation's (those not in the log). Empty: the search
    /// has ended.
    fn ask(&mut self) -> PyResult<Vec<String>> {
        let candidates = self.search()?.ask().map_err(optim_error)?;
        Ok(candidates
            .iter()
            .map(|c| serde_json::to_string(c).expect("candidates always serialize"))
            .collect())
    }

    /// Logs the results (JSON strings of `SearchProblem.evaluate`, any order) in candidate
    /// order and tells them to the optimizer.
    fn tell(&mut self, results: Vec<String>) -> PyResult<()> {
        let evaluations = results
            .iter()
            .map(|r| serde_json::from_str::<Evaluation>(r).map_err(|e| json_error("result", e)))
            .collect::<PyResult<Vec<_>>>()?;
        self.search()?
            .tell_evaluations(evaluations)
            .map_err(optim_error)
    }

    /// Releases the run directory without writing outputs (also after a `finish` that
    /// could not write them): the log stays (a later
    /// `DesignSearch(..., resume=True)` continues it) and this object's search ends (its
    /// methods then raise). Also on leaving a `with` block.
    fn close(&mut self) {
        self.search = None;
        // The ended search's result too: a `finish` after `close` wrote the outputs into
        // a directory another search may hold by then.
        self.result = None;
        self.directory = None;
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&mut self, _args: &Bound<'_, pyo3::types::PyTuple>) -> bool {
        self.close();
        false
    }

    /// Why the search ended (None while it runs).
    #[getter]
    fn termination(&mut self) -> PyResult<Option<String>> {
        Ok(self.search()?.termination().map(|t| t.to_string()))
    }

    /// Writes the outputs of the ended search (designs, `pareto.csv`, figures,
    /// `report.md`; slice figures swept here) and returns a summary dict. `command` and
    /// `workers` go into the report. Called before the search has ended it raises
    /// `ValueError` and changes nothing; where the outputs cannot be written
    /// (`OSError`) it can be called again.
    #[pyo3(signature = (command, workers))]
    fn finish<'py>(
        &mut self,
        py: Python<'py>,
        command: String,
        workers: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        let load_start = load_average();
        if self.result.is_some() && self.directory.is_none() {
            // Written once: the directory is released, another search may hold it now.
            return Err(PyRuntimeError::new_err(
                "finish() has written the outputs already (and released the directory)",
            ));
        }
        if self.result.is_none() {
            let search = self
                .search
                .as_ref()
                .ok_or_else(|| PyRuntimeError::new_err("the search is closed"))?;
            // Checked before the search is taken: an early call leaves it usable.
            if search.termination().is_none() {
                return Err(PyValueError::new_err(
                    "finish() before the search has ended: call ask() until it returns no \
                     candidate (telling each generation's results) first",
                ));
            }
            let search = self.search.take().expect("checked above");
            let setup = search.setup().clone();
            let (result, directory) = search.finish_holding_directory().map_err(optim_error)?;
            self.result = Some((setup, result));
            self.directory = Some(directory);
        }
        let (setup, result) = self.result.as_ref().expect("set above");
        let out = self.out.clone();
        let files = py
            .detach(|| {
                let (slices, slices_note) = slice_sets(setup, result, &|line| eprintln!("{line}"));
                let ctx = ReportContext {
                    command,
                    threads: workers,
                    load_average: [load_start, load_average()],
                    slices_note,
                };
                write_outputs(&out, setup, result, &slices, &ctx)
            })
            .map_err(optim_error)?;
        // Written: other searches may open the directory.
        self.directory = None;
        let summary = PyDict::new(py);
        summary.set_item("termination", result.termination.to_string())?;
        summary.set_item("candidates", result.candidates.len())?;
        summary.set_item("evaluated", result.evaluated)?;
        summary.set_item("from_log", result.from_log)?;
        summary.set_item("generations", result.generations)?;
        summary.set_item("pareto", result.pareto_front().len())?;
        summary.set_item("dominating_reference", result.dominating_reference().len())?;
        summary.set_item(
            "best_composite",
            result
                .best_composite()
                .map(|r| (r.composite.unwrap_or(0.0), r.id)),
        )?;
        summary.set_item("files", files)?;
        Ok(summary)
    }
}

/// The evaluation of a search's candidates: built from `DesignSearch.problem` on any
/// process; `evaluate` is a pure function of the problem and the candidate.
#[pyclass(module = "tdpcr", frozen)]
pub struct SearchProblem {
    setup: Setup,
    evaluator: WorkspaceEvaluator,
}

#[pymethods]
impl SearchProblem {
    /// Parses and checks the problem text of `DesignSearch.problem`.
    #[new]
    fn new(problem: &str) -> PyResult<Self> {
        let source = Path::new("<problem>");
        let setup = RunInfo::from_ron(problem, source)
            .and_then(|info| Setup::from_run_info(info, source))
            .map_err(optim_error)?;
        let evaluator = WorkspaceEvaluator::new(&setup.config.evaluation);
        Ok(Self { setup, evaluator })
    }

    /// The result (JSON: `id`, `outcome`, `eval_time_s`) of one candidate (JSON of
    /// `DesignSearch.ask`), computed with the GIL released.
    fn evaluate(&self, py: Python<'_>, candidate: &str) -> PyResult<String> {
        let candidate: Candidate =
            serde_json::from_str(candidate).map_err(|e| json_error("candidate", e))?;
        let dimension = self.setup.space.dimension();
        if candidate.x.len() != dimension {
            return Err(PyValueError::new_err(format!(
                "candidate x has {} coordinates: expected {dimension} (one per parameter)",
                candidate.x.len()
            )));
        }
        // The search's box is [0, 1] in every coordinate: a point outside it is no
        // candidate of `DesignSearch.ask` (it was evaluated as the point clamped into the
        // box, silently); the reference (id 0) is the base design whatever its x.
        let outside = candidate
            .x
            .iter()
            .enumerate()
            .find(|(_, x)| !(0.0..=1.0).contains(*x));
        if let (Some((i, x)), true) = (outside, candidate.id != 0) {
            return Err(PyValueError::new_err(format!(
                "candidate x[{i}] = {x}: expected a number in [0, 1] (the search box; as \
                 DesignSearch.ask gives it)"
            )));
        }
        let evaluation = py.detach(|| evaluate_candidate(&self.setup, &self.evaluator, &candidate));
        Ok(serde_json::to_string(&evaluation).expect("evaluations always serialize"))
    }
}
