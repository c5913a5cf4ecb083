//! `tdpcr-optim`: searches TDPCR designs (a thin layer over the `tdpcr_optim` library:
//! arguments, progress on stderr, exit codes). Exit codes: 0 success, 1 the run failed
//! (I/O), 2 bad input (config, base design, or a run directory that does not fit).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;

use tdpcr_optim::OptimError;
use tdpcr_optim::objectives::Outcome;
use tdpcr_optim::report::{ReportContext, load_average, write_outputs};
use tdpcr_optim::runlog::{LOG_FILE, Record};
use tdpcr_optim::search::{
    EvaluationStatus, GenerationReport, Observer, Overrides, Setup, run_search_holding_directory,
};
use tdpcr_optim::workspace_eval::{WorkspaceEvaluator, slice_sets};

/// Design optimization of tendon-driven parallel continuum robots: CMA-ES over the
/// design parameters of CONFIG for workspace volume, isotropy and singularity margin,
/// each design evaluated on a coarse workspace sweep. Every evaluation is appended to
/// DIR/evaluations.jsonl as it finishes; the best designs, pareto.csv and report.md are
/// written to DIR at the end. Threads: RAYON_NUM_THREADS (default: all cores).
#[derive(Parser)]
#[command(version, about)]
struct Cli {
    /// Search configuration (RON), e.g. optim/default.ron.
    config: PathBuf,
    /// Candidate evaluations (overrides `budget.evaluations` of the config).
    #[arg(long, value_name = "N")]
    budget_evals: Option<usize>,
    /// Seed of the optimizer (overrides `seed` of the config).
    #[arg(long, value_name = "S")]
    seed: Option<u64>,
    /// Continue the interrupted (or finished) run in DIR: the search is replayed from
    /// its seed, logged candidates are not evaluated again. The settings must match the
    /// run's, except the budget.
    #[arg(long)]
    resume: bool,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
}

/// Progress lines on stderr.
struct Progress;

fn clock(seconds: f64) -> String {
    let s = seconds as u64;
    format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
}

fn summary(record: &Record) -> String {
    match &record.outcome {
        Outcome::Feasible(m) => format!(
            "volume {:7.1} cm³  rcond(J_p) {:.4}  margin {:.3}  composite {:.4}",
            m.volume_non_singular * 1e6,
            m.rcond_j_p.mean,
            m.singularity_margin,
            record.composite.unwrap_or(0.0)
        ),
        Outcome::Infeasible { reason } => {
            let text = reason.to_string().replace('\n', " ");
            let short: String = text.chars().take(110).collect();
            format!("infeasible: {short}")
        }
    }
}

impl Observer for Progress {
    fn reference(&self, record: &Record) {
        eprintln!(
            "reference ({:.1} s): {}",
            record.eval_time_s,
            summary(record)
        );
    }

    fn evaluated(&self, record: &Record, status: &EvaluationStatus) {
        if status.from_log {
            return;
        }
        let budget = status.budget.map_or("-".into(), |b| b.to_string());
        eprintln!(
            "[{}/{} {}] #{} {:.1} s  {}",
            status.done,
            budget,
            clock(status.elapsed_s),
            record.id,
            record.eval_time_s,
            summary(record)
        );
    }

    fn generation(&self, r: &GenerationReport) {
        let best = r
            .best
            .map_or("none feasible".into(), |(c, id)| format!("{c:.4} (#{id})"));
        eprintln!(
            "generation {} done ({} candidates, {} feasible in it): best composite {best}, sigma {:.3}, {}",
            r.generation,
            r.done,
            r.feasible,
            r.sigma,
            clock(r.elapsed_s)
        );
    }
}

fn run(cli: &Cli) -> Result<(), OptimError> {
    let overrides = Overrides {
        budget_evals: cli.budget_evals,
        seed: cli.seed,
    };
    let setup = Setup::load(&cli.config, &overrides)?;
    let evaluator = WorkspaceEvaluator::new(&setup.config.evaluation);
    let threads = rayon::current_num_threads();
    let load_start = load_average();
    eprintln!(
        "tdpcr-optim: {} parameters, population {}, budget {:?} evaluations / {:?} s, seed {}, {threads} threads; log {}",
        setup.space.dimension(),
        setup.config.population_size(),
        setup.config.budget.evaluations,
        setup.config.budget.wall_time_s,
        setup.config.seed,
        cli.out.join(LOG_FILE).display()
    );
    // The directory stays locked until the outputs are written (`_directory`).
    let (result, _directory) =
        run_search_holding_directory(&setup, &evaluator, &cli.out, cli.resume, &Progress)?;
    eprintln!("search ended: {}", result.termination);
    let (slice_sets, slices_note) = slice_sets(&setup, &result, &|line| eprintln!("{line}"));
    let ctx = ReportContext {
        command: std::env::args().collect::<Vec<_>>().join(" "),
        threads,
        load_average: [load_start, load_average()],
        slices_note,
    };
    let files = write_outputs(&cli.out, &setup, &result, &slice_sets, &ctx)?;
    let dominating = result.dominating_reference().len();
    println!(
        "{} candidates ({} evaluated now), {} Pareto-optimal, {} dominate the reference; best composite {}",
        result.candidates.len(),
        result.evaluated,
        result.pareto_front().len(),
        dominating,
        result.best_composite().map_or("none".into(), |r| format!(
            "{:.4} (#{})",
            r.composite.unwrap_or(0.0),
            r.id
        ))
    );
    for f in files
        .iter()
        .filter(|f| f.extension().is_some_and(|e| e != "svg"))
    {
        println!("{}", f.display());
    }
    Ok(())
}

fn main() -> ExitCode {
    tdpcr::cli_support::end_quietly_on_broken_pipe();
    let cli = Cli::parse();
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            if e.is_input_error() {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}
