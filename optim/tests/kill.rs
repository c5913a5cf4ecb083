//! Kill at any moment loses nothing (issue 14, deliverable 5): `tdpcr-optim` killed with
//! SIGKILL at several points of a tiny search, then `--resume`d, ends with the same log as
//! an uninterrupted run with the same seed and budget.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{fresh_dir, optim, tiny_config};
use tdpcr_optim::runlog::{LOG_FILE, Record, read_log};

const BUDGET: &str = "8";
const SEED: &str = "9";

/// The log's records by id, without their wall times (the only field that is not a
/// function of config and seed).
fn log_without_times(dir: &Path) -> Vec<Record> {
    let mut records = read_log(&dir.join(LOG_FILE)).unwrap();
    for r in &mut records {
        r.eval_time_s = 0.0;
    }
    records
}

/// Starts the search into `out` (resumed if `resume`) and kills it with SIGKILL after
/// `delay`, or lets it finish if it ends first.
fn run_killed_after(config: &Path, out: &Path, resume: bool, delay: Duration) {
    let mut args = vec![
        config.to_str().unwrap(),
        "--budget-evals",
        BUDGET,
        "--seed",
        SEED,
        "--out",
        out.to_str().unwrap(),
    ];
    if resume {
        args.push("--resume");
    }
    let mut child = Command::new(env!("CARGO_BIN_EXE_tdpcr-optim"))
        .args(&args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("binary starts");
    let start = Instant::now();
    while start.elapsed() < delay && child.try_wait().unwrap().is_none() {
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = child.kill(); // SIGKILL on Unix; harmless if it has ended
    child.wait().unwrap();
}

#[test]
fn a_search_killed_at_any_point_resumes_to_the_uninterrupted_log() {
    let d = fresh_dir("optim-kill", "reference");
    let config = tiny_config(&d);
    let reference_out = d.join("run");
    let start = Instant::now();
    let o = optim(&[
        config.to_str().unwrap(),
        "--budget-evals",
        BUDGET,
        "--seed",
        SEED,
        "--out",
        reference_out.to_str().unwrap(),
    ]);
    let full = start.elapsed();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let reference = log_without_times(&reference_out);
    let reference_pareto = std::fs::read_to_string(reference_out.join("pareto.csv")).unwrap();

    // Kill points spread over the whole run, from start-up to the final writes; a second
    // kill during the resume itself at the larger fractions.
    for (i, fraction) in [0.02, 0.1, 0.25, 0.5, 0.75, 0.9, 0.97]
        .into_iter()
        .enumerate()
    {
        let out = fresh_dir("optim-kill", &format!("killed-{i}")).join("run");
        run_killed_after(&config, &out, false, full.mul_f64(fraction));
        if fraction >= 0.5 {
            run_killed_after(&config, &out, true, full.mul_f64(0.3));
        }
        let o = optim(&[
            config.to_str().unwrap(),
            "--budget-evals",
            BUDGET,
            "--seed",
            SEED,
            "--resume",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(
            o.status.success(),
            "resume after a kill at {fraction} of the run: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert_eq!(
            log_without_times(&out),
            reference,
            "kill at {fraction} of the run"
        );
        assert_eq!(
            std::fs::read_to_string(out.join("pareto.csv")).unwrap(),
            reference_pareto,
            "kill at {fraction} of the run"
        );
    }
}
