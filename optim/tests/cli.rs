//! The `tdpcr-optim` binary end to end on the real workspace evaluation at a very coarse
//! resolution: outputs, resume, exit codes and error messages.

mod common;

use std::path::PathBuf;
use std::process::Output;

use common::{fresh_dir, optim, tiny_config};

use tdpcr::Tdpcr;
use tdpcr_optim::runlog::{LOG_FILE, read_log};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn dir(name: &str) -> PathBuf {
    fresh_dir("optim-cli", name)
}

#[test]
fn a_tiny_search_writes_loadable_designs_and_resumes_without_evaluating_again() {
    let d = dir("tiny");
    let config = tiny_config(&d);
    let out = d.join("run");
    let (c, o) = (config.to_str().unwrap(), out.to_str().unwrap());
    let first = optim(&[c, "--budget-evals", "5", "--seed", "9", "--out", o]);
    assert!(first.status.success(), "{}", stderr(&first));
    let records = read_log(&out.join(LOG_FILE)).unwrap();
    assert_eq!(records.len(), 6, "the reference and 5 candidates");
    assert!(
        records[0].outcome.measures().is_some(),
        "the reference is feasible"
    );
    for name in [
        "best_composite.ron",
        "pareto_max_volume.ron",
        "pareto_max_isotropy.ron",
    ] {
        let design = Tdpcr::from_ron_file(out.join(name)).unwrap();
        design.validate(name).unwrap();
    }
    for name in [
        "pareto.csv",
        "report.md",
        "pareto.svg",
        "progress.svg",
        "run.ron",
    ] {
        assert!(out.join(name).is_file(), "{name}");
    }
    assert!(out.join("slices/reference/reach_z+0.000.svg").is_file());
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("| **mean rcond(J_p)** |"), "{report}");
    assert!(!report.contains("NaN"));
    let stdout = String::from_utf8_lossy(&first.stdout);
    assert!(
        stdout.contains("5 candidates (5 evaluated now)"),
        "{stdout}"
    );

    // Resume with the same budget: nothing evaluated again, the same log.
    let again = optim(&[
        c,
        "--budget-evals",
        "5",
        "--seed",
        "9",
        "--resume",
        "--out",
        o,
    ]);
    assert!(again.status.success(), "{}", stderr(&again));
    assert!(String::from_utf8_lossy(&again.stdout).contains("5 candidates (0 evaluated now)"));
    assert_eq!(read_log(&out.join(LOG_FILE)).unwrap(), records);

    // A new run into the same directory is refused; so is a resume with another seed.
    let refused = optim(&[c, "--budget-evals", "5", "--seed", "9", "--out", o]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(stderr(&refused).contains("already holds evaluations: pass --resume"));
    let other = optim(&[
        c,
        "--budget-evals",
        "5",
        "--seed",
        "10",
        "--resume",
        "--out",
        o,
    ]);
    assert_eq!(other.status.code(), Some(2));
    assert!(
        stderr(&other).contains("seed: stored 9, now 10"),
        "{}",
        stderr(&other)
    );
}

#[test]
fn bad_configs_exit_2_with_the_file_position_or_every_broken_rule() {
    let d = dir("bad");
    let out = d.join("run");
    let malformed = d.join("malformed.ron");
    std::fs::write(&malformed, "OptimConfig(\n  seed: 1,\n  colour: 2,\n)").unwrap();
    let o = optim(&[malformed.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.starts_with(&format!("error: {}:3:", malformed.display())),
        "{e}"
    );

    let config = tiny_config(&d);
    let text = std::fs::read_to_string(&config)
        .unwrap()
        .replace("min: 0.4, max: 0.7", "min: 0.4, max: 1.7")
        .replace("seed: 4", "seed: 4, initial_step: 2.0");
    std::fs::write(&config, text).unwrap();
    let o = optim(&[
        config.to_str().unwrap(),
        "--budget-evals",
        "0",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    for line in [
        "parameters[0].max = 1.7: expected in (0, pi/2) rad (alpha)",
        "budget.evaluations = 0: expected >= 1",
        "initial_step = 2: expected in (0, 1] (fraction of each range)",
    ] {
        assert!(e.contains(line), "missing {line:?} in {e}");
    }
    assert!(!out.exists(), "nothing written for a bad config");
}
