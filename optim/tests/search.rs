//! The search loop with a cheap synthetic evaluator: reproducibility (same seed → same
//! log, whatever the thread count), resume without repeated evaluations, the run
//! directory's guards, and the output files.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use tdpcr::Tdpcr;
use tdpcr_optim::config::OptimConfig;
use tdpcr_optim::evaluate::Evaluator;
use tdpcr_optim::objectives::{Infeasibility, MeanMin, Measures, Outcome};
use tdpcr_optim::report::{ReportContext, write_outputs};
use tdpcr_optim::runlog::{LOG_FILE, Record, read_log};
use tdpcr_optim::search::{Overrides, Setup, Silent, TerminationReason, run_search};
use tdpcr_optim::{OptimError, SearchResult};

const CONFIG: &str = include_str!("../default.ron");

/// Smooth made-up measures of the parameters, with an infeasible region (small
/// platforms "collide at home"); counts its calls.
#[derive(Default)]
struct Synthetic {
    calls: AtomicUsize,
}

impl Evaluator for Synthetic {
    fn evaluate(&self, d: &Tdpcr) -> Outcome {
        self.calls.fetch_add(1, Ordering::Relaxed);
        if d.platform.side_length < 0.09 {
            return Outcome::Infeasible {
                reason: Infeasibility::InvalidHome {
                    message: "disks collide at home".into(),
                },
            };
        }
        let l = d.leg.length / 0.145;
        let volume = 1.2e-3 * l * l * (-(d.alpha - 0.8).powi(2)).exp();
        let rcond = 0.3
            * (-(d.beta - 0.6).powi(2)).exp()
            * (-((d.platform.side_length - 0.14) / 0.05).powi(2)).exp();
        let margin =
            1.0 / (1.0 + 1e5 * (d.leg.tendons[0].offset - 0.004).powi(2) + d.coupling_offset);
        Outcome::Feasible(Measures {
            volume_non_singular: volume,
            volume_reachable: volume * 1.1,
            reachable_cells: 100,
            non_singular_cells: 90,
            rcond_j_p: MeanMin {
                mean: rcond,
                min: rcond / 10.0,
            },
            singularity_margin: margin,
            min_tension: d.pretension,
            ..Default::default()
        })
    }
}

fn setup(evaluations: usize, seed: u64) -> Setup {
    let config_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("default.ron");
    let config = OptimConfig::from_ron_str(CONFIG, &config_path).unwrap();
    let base = Tdpcr::from_ron_file(config.base_design_path(&config_path)).unwrap();
    let overrides = Overrides {
        budget_evals: Some(evaluations),
        seed: Some(seed),
    };
    Setup::new(config, base, &config_path, &overrides).unwrap()
}

fn fresh_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("optim-search")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The log without the timing field, sorted by id: what must be reproducible.
fn canonical(dir: &Path) -> Vec<Record> {
    read_log(&dir.join(LOG_FILE))
        .unwrap()
        .into_iter()
        .map(|r| Record {
            eval_time_s: 0.0,
            ..r
        })
        .collect()
}

fn run(
    dir: &Path,
    evaluations: usize,
    seed: u64,
    resume: bool,
    eval: &Synthetic,
) -> Result<SearchResult, OptimError> {
    run_search(&setup(evaluations, seed), eval, dir, resume, &Silent)
}

fn on_threads<T: Send>(n: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn same_seed_and_budget_give_the_same_log_whatever_the_thread_count() {
    let (a, b, c) = (
        fresh_dir("repro-a"),
        fresh_dir("repro-b"),
        fresh_dir("repro-c"),
    );
    let ra = on_threads(1, || run(&a, 47, 5, false, &Synthetic::default()).unwrap());
    let rb = on_threads(3, || run(&b, 47, 5, false, &Synthetic::default()).unwrap());
    assert_eq!(
        ra.termination,
        TerminationReason::EvaluationBudget { evaluations: 47 }
    );
    assert_eq!(canonical(&a), canonical(&b));
    assert_eq!(canonical(&a).len(), 48, "the reference and 47 candidates");
    assert_eq!(
        ra.best_composite().unwrap().id,
        rb.best_composite().unwrap().id
    );
    let rc = run(&c, 47, 6, false, &Synthetic::default()).unwrap();
    assert_ne!(
        canonical(&a)[1..],
        canonical(&c)[1..],
        "another seed, another run"
    );
    assert!(
        rc.candidates
            .iter()
            .all(|r| r.x.iter().all(|v| (0.0..=1.0).contains(v)))
    );
}

#[test]
fn an_interrupted_run_resumed_ends_as_an_uninterrupted_one_without_repeating_evaluations() {
    let (whole, parts) = (fresh_dir("whole"), fresh_dir("parts"));
    let full = run(&whole, 45, 3, false, &Synthetic::default()).unwrap();

    // Stop mid-generation (population 10), then tear the last line as a kill would.
    let first = Synthetic::default();
    run(&parts, 23, 3, false, &first).unwrap();
    assert_eq!(first.calls.load(Ordering::Relaxed), 24, "reference + 23");
    let log = parts.join(LOG_FILE);
    let text = std::fs::read_to_string(&log).unwrap();
    let torn = &text[..text.len() - 25];
    std::fs::write(&log, torn).unwrap();

    let second = Synthetic::default();
    let resumed = run(&parts, 45, 3, true, &second).unwrap();
    assert_eq!(
        second.calls.load(Ordering::Relaxed),
        45 - 22,
        "only the torn one and the rest"
    );
    assert_eq!(resumed.from_log, 22);
    assert_eq!(canonical(&whole), canonical(&parts));
    assert_eq!(
        full.best_composite().unwrap().id,
        resumed.best_composite().unwrap().id
    );

    // Resuming a finished run evaluates nothing.
    let third = Synthetic::default();
    run(&parts, 45, 3, true, &third).unwrap();
    assert_eq!(third.calls.load(Ordering::Relaxed), 0);
}

#[test]
fn the_run_directory_guards_against_mixing_runs() {
    let dir = fresh_dir("guards");
    let e = Synthetic::default();
    let err = run(&dir, 5, 1, true, &e).unwrap_err();
    assert!(matches!(err, OptimError::NoRun { .. }), "{err}");
    run(&dir, 5, 1, false, &e).unwrap();
    let err = run(&dir, 5, 1, false, &e).unwrap_err();
    assert!(matches!(err, OptimError::RunExists { .. }), "{err}");
    let err = run(&dir, 5, 2, true, &e).unwrap_err().to_string();
    assert!(
        err.contains("the settings differ") && err.contains("seed: stored 1, now 2"),
        "{err}"
    );
    // A larger budget is a continuation, not a difference.
    run(&dir, 12, 1, true, &e).unwrap();
    // A smaller one than the log holds is refused (the outputs were rewritten from the
    // first candidates only), and changes nothing.
    let log = std::fs::read(dir.join(LOG_FILE)).unwrap();
    let err = run(&dir, 5, 1, true, &e).unwrap_err();
    assert!(err.is_input_error());
    assert!(
        err.to_string()
            .contains("budget.evaluations: the log holds 12 candidates, now 5"),
        "{err}"
    );
    assert_eq!(std::fs::read(dir.join(LOG_FILE)).unwrap(), log);
    run(&dir, 12, 1, true, &e).unwrap();
}

#[test]
fn the_outputs_load_and_report_the_comparison() {
    let dir = fresh_dir("outputs");
    let s = setup(120, 11);
    let result = run_search(&s, &Synthetic::default(), &dir, false, &Silent).unwrap();
    assert!(
        !result.dominating_reference().is_empty(),
        "the synthetic optimum beats the reference"
    );
    let infeasible = result
        .candidates
        .iter()
        .filter(|r| r.composite.is_none())
        .count();
    assert!(infeasible > 0, "the box holds infeasible designs");
    let files = write_outputs(&dir, &s, &result, &[], &ReportContext::default()).unwrap();
    for name in [
        "best_composite.ron",
        "pareto_max_volume.ron",
        "pareto_max_isotropy.ron",
        "pareto_max_margin.ron",
    ] {
        let path = dir.join(name);
        assert!(files.contains(&path));
        let design = Tdpcr::from_ron_file(&path).unwrap();
        design.validate("reloaded").unwrap();
    }
    // The 3D view of the reference and the best design, linked from the report.
    let page = std::fs::read_to_string(dir.join("designs.html")).unwrap();
    assert!(files.contains(&dir.join("designs.html")));
    assert!(page.contains("\"reference\"") && page.contains("best composite (candidate "));
    assert!(
        !page.contains("no home configuration"),
        "both designs solved at home"
    );
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(md.contains("[designs.html](designs.html)"));
    let best = Tdpcr::from_ron_file(dir.join("best_composite.ron")).unwrap();
    let rec = result.best_composite().unwrap();
    assert!((best.leg.length - rec.parameters["leg_length"]).abs() < 1e-15);

    let csv = std::fs::read_to_string(dir.join("pareto.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines
            .next()
            .unwrap()
            .split(',')
            .take(15)
            .collect::<Vec<_>>()
            .join(","),
        "id,role,best_composite,generation,alpha,beta,leg_length,tendon_offset,platform_side,coupling_offset,pretension,psi,workspace_volume,mean_rcond_j_p,singularity_margin"
    );
    assert!(lines.next().unwrap().starts_with("0,reference,0,,"));
    assert_eq!(lines.count(), result.pareto_front().len());
    assert!(!csv.contains("NaN") && !csv.contains("inf"));

    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(
        md.contains("candidate(s) Pareto-dominate the reference"),
        "{md}"
    );
    assert!(
        md.contains("| **non-singular workspace volume [cm³]** |"),
        "{md}"
    );
    assert!(
        md.contains("| α alpha (bounds 14.90° – 69.90°) | 30.00° |"),
        "{md}"
    );
    for svg in ["pareto.svg", "progress.svg"] {
        let text = std::fs::read_to_string(dir.join(svg)).unwrap();
        assert!(text.starts_with("<svg") && text.contains("circle"), "{svg}");
    }
}

/// A second search on a directory in use (its log locked by the first, here in the same
/// process) is refused, new or resumed, and leaves the first's log alone; once the
/// first has ended the directory can be resumed. An empty directory path is refused (it
/// put the log in the working directory).
#[test]
fn a_directory_in_use_by_another_search_is_refused() {
    use tdpcr_optim::search::Search;
    let dir = fresh_dir("in-use");
    let first = Search::open(setup(6, 1), &dir, false, &Silent).unwrap();
    for resume in [false, true] {
        match Search::open(setup(6, 1), &dir, resume, &Silent) {
            Err(e @ OptimError::RunInUse { .. }) => {
                assert!(e.is_input_error());
                assert!(e.to_string().contains("in use by another search"), "{e}");
            }
            Err(e) => panic!("resume {resume}: expected RunInUse, got {e}"),
            Ok(_) => panic!("resume {resume}: a second search opened {}", dir.display()),
        }
    }
    drop(first);
    assert!(Search::open(setup(6, 1), &dir, true, &Silent).is_ok());
    match Search::open(setup(6, 1), Path::new(""), false, &Silent) {
        Err(OptimError::NoOutDir) => {}
        Err(e) => panic!("expected NoOutDir, got {e}"),
        Ok(_) => panic!("an empty directory path was accepted"),
    }
    // A file where the directory goes is bad input (it failed as an I/O error, exit 1).
    let file = fresh_dir("a-file").with_extension("txt");
    std::fs::create_dir_all(file.parent().unwrap()).unwrap();
    std::fs::write(&file, "not a directory").unwrap();
    match Search::open(setup(6, 1), &file, false, &Silent) {
        Err(e @ OptimError::NotADirectory { .. }) => {
            assert!(e.is_input_error());
            assert!(e.to_string().contains("not a directory"), "{e}");
        }
        Err(e) => panic!("expected NotADirectory, got {e}"),
        Ok(_) => panic!("a file was taken for the run directory"),
    }
}

/// A search that ends holding its directory (`tdpcr-optim` writes its outputs so) keeps
/// other searches out until the lock is dropped (one started between the last record
/// and the report wrote beside the outputs); the plain result holds nothing.
#[test]
fn the_directory_stays_locked_until_the_outputs_are_written() {
    use tdpcr_optim::run_search_holding_directory;
    use tdpcr_optim::search::Search;
    let dir = fresh_dir("held");
    let opens = || Search::open(setup(6, 1), &dir, true, &Silent).map(drop);
    let (result, lock) =
        run_search_holding_directory(&setup(6, 1), &Synthetic::default(), &dir, false, &Silent)
            .unwrap();
    match opens() {
        Err(OptimError::RunInUse { .. }) => {}
        other => panic!("expected RunInUse while the lock lives, got {other:?}"),
    }
    drop(lock);
    opens().unwrap();
    // The result alone (as `run_search` returns it) does not hold the directory.
    let again = run(&dir, 6, 1, true, &Synthetic::default()).unwrap();
    assert_eq!(again.candidates.len(), result.candidates.len());
    opens().unwrap();
}

/// A last line torn inside a multi-byte character (records carry solver messages such as
/// "RᵀR − I") is dropped on resume like any torn line; the whole log as text did not read.
#[test]
fn a_last_line_torn_inside_a_multibyte_character_is_dropped_on_resume() {
    use std::io::Write;
    let dir = fresh_dir("torn-utf8");
    run(&dir, 6, 3, false, &Synthetic::default()).unwrap();
    let before = canonical(&dir);
    let mut log = std::fs::OpenOptions::new()
        .append(true)
        .open(dir.join(LOG_FILE))
        .unwrap();
    let torn = "{\"id\": 99, \"note\": \"RᵀR −".as_bytes();
    log.write_all(&torn[..torn.len() - 1]).unwrap();
    drop(log);
    let resumed = run(&dir, 6, 3, true, &Synthetic::default());
    assert!(resumed.is_ok(), "{:?}", resumed.err());
    assert_eq!(canonical(&dir), before);
}
