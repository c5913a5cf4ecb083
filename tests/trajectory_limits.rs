//! `tdpcr trajectory --limits free|strict --reference`: the IK steps of the 9-DoF design
//! resolved as `ik` resolves them, end to end.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::design_path;

/// Bending limit of each tendon pair \[m\] and translation limit \[m\] of
/// designs/lilge2022_redundant.ron (`actuation_limits`).
const BEND_LIMIT: f64 = 0.01;
const TRANSLATION_LIMIT: f64 = 0.1;

fn tdpcr(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tdpcr"))
        .args(args)
        .output()
        .expect("binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn redundant() -> String {
    design_path("lilge2022_redundant.ron").display().to_string()
}

/// A fresh directory for this test's files.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tdpcr-traj-limits-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes positions (identity orientation) as a trajectory CSV x,y,z,rx,ry,rz.
fn write_poses(path: &Path, positions: &[[f64; 3]]) {
    let mut csv = String::from("x,y,z,rx,ry,rz\n");
    for p in positions {
        csv.push_str(&format!("{},{},{},0,0,0\n", p[0], p[1], p[2]));
    }
    std::fs::write(path, csv).unwrap();
}

/// Largest |q_j| / limit_j (per leg [bend_x, bend_y, translation]).
fn limit_ratio(q: &[f64]) -> f64 {
    q.iter()
        .enumerate()
        .map(|(j, x)| {
            x.abs()
                / if j % 3 == 2 {
                    TRANSLATION_LIMIT
                } else {
                    BEND_LIMIT
                }
        })
        .fold(0.0, f64::max)
}

/// Every step of a JSON trajectory run: (position, q), after checking that it converged
/// to the residual tolerance.
fn converged_steps(o: &Output) -> Vec<([f64; 3], Vec<f64>)> {
    assert!(o.status.success(), "{}", stderr(o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    v["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            assert_eq!(s["converged"], serde_json::Value::Bool(true), "{s}");
            assert!(s["residual_norm"].as_f64().unwrap() <= 1e-10, "{s}");
            let f = |x: &serde_json::Value| x.as_f64().unwrap();
            let p = s["position"].as_array().unwrap();
            let q = s["q"].as_array().unwrap().iter().map(f).collect();
            ([f(&p[0]), f(&p[1]), f(&p[2])], q)
        })
        .collect()
}

fn run(design: &str, csv: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "trajectory",
        design,
        "--ik",
        csv.to_str().unwrap(),
        "--format",
        "json",
    ];
    args.extend_from_slice(extra);
    tdpcr(&args)
}

fn assert_reached(steps: &[([f64; 3], Vec<f64>)], targets: &[[f64; 3]]) {
    assert_eq!(steps.len(), targets.len());
    for ((p, _), t) in steps.iter().zip(targets) {
        for k in 0..3 {
            assert!((p[k] - t[k]).abs() <= 1e-12, "{p:?} vs {t:?}");
        }
    }
}

#[test]
fn strict_steps_near_home_stay_within_the_limits_and_reach_every_pose() {
    let dir = scratch("home");
    let csv = dir.join("poses.csv");
    // Ten poses 1 mm apart along x from home.
    let targets: Vec<[f64; 3]> = (0..10).map(|k| [0.001 * k as f64, 0.0, 0.0]).collect();
    write_poses(&csv, &targets);
    let strict = converged_steps(&run(&redundant(), &csv, &["--limits", "strict"]));
    assert_reached(&strict, &targets);
    for (_, q) in &strict {
        assert_eq!(q.len(), 9);
        assert!(limit_ratio(q) <= 1.0, "{q:?}");
    }
    // With a reference (home's least-norm actuation, within the limits) too.
    let free = converged_steps(&run(&redundant(), &csv, &["--limits", "free"]));
    assert_reached(&free, &targets);
    let reference: Vec<String> = free[0].1.iter().map(|x| x.to_string()).collect();
    let reference = reference.join(",");
    let pulled = converged_steps(&run(
        &redundant(),
        &csv,
        &["--limits", "strict", "--reference", &reference],
    ));
    assert_reached(&pulled, &targets);
    for (_, q) in &pulled {
        assert!(limit_ratio(q) <= 1.0, "{q:?}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Up 110 mm along z (10 mm steps), then 4 mm steps along y: the least-norm steps drive
/// leg 2's x-bending past its 10 mm limit from y = 40 mm on (found by experiment: at
/// y = 52 mm |q|/limit is 1.16), the QP steps reach the same poses with q on the limit.
#[test]
fn a_path_that_pushes_q_past_a_limit_leaves_it_free_and_stays_within_it_strict() {
    let dir = scratch("push");
    let csv = dir.join("poses.csv");
    let mut targets: Vec<[f64; 3]> = (0..12).map(|k| [0.0, 0.0, 0.01 * k as f64]).collect();
    targets.extend((1..=13).map(|k| [0.0, 0.004 * k as f64, 0.11]));
    write_poses(&csv, &targets);
    let free = converged_steps(&run(&redundant(), &csv, &[]));
    assert_reached(&free, &targets);
    let worst_free = free.iter().map(|(_, q)| limit_ratio(q)).fold(0.0, f64::max);
    assert!(worst_free > 1.1, "least-norm stayed within: {worst_free}");
    let strict = converged_steps(&run(&redundant(), &csv, &["--limits", "strict"]));
    assert_reached(&strict, &targets);
    let worst_strict = strict
        .iter()
        .map(|(_, q)| limit_ratio(q))
        .fold(0.0, f64::max);
    assert!(worst_strict <= 1.0 + 1e-12, "strict left: {worst_strict}");
    // On the limit where free is past it: the limit was active, not avoided by luck.
    assert!(worst_strict > 0.999, "{worst_strict}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn reference_and_limits_are_validated_as_in_ik() {
    let dir = scratch("validate");
    let csv = dir.join("poses.csv");
    write_poses(&csv, &[[0.0; 3], [0.001, 0.0, 0.0]]);
    let expect_input_error = |extra: &[&str], message: &str| {
        let o = run(&redundant(), &csv, extra);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(message), "{extra:?}: {}", stderr(&o));
        assert!(o.stdout.is_empty(), "{extra:?}: a result beside the error");
    };
    expect_input_error(
        &["--limits", "strict", "--reference", "0,0"],
        "--reference = 2 values: expected 9 values",
    );
    expect_input_error(
        &["--limits", "strict", "--reference", "0,0,0,0,NaN,0,0,0,0"],
        "--reference = a non-finite value: expected finite numbers",
    );
    expect_input_error(
        &["--limits", "strict", "--reference", "0,0,0,0,inf,0,0,0,0"],
        "--reference = a non-finite value",
    );
    expect_input_error(
        &["--reference", "0,0,0,0,0,0,0,0,0"],
        "only with --limits strict",
    );
    let o = run(&redundant(), &csv, &["--limits", "loose"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--limits"), "{}", stderr(&o));
    // FK has no redundancy: the flags are refused, not ignored.
    let q = dir.join("q.csv");
    std::fs::write(&q, "0,0,0,0,0,0,0,0,0\n").unwrap();
    let o = tdpcr(&[
        "trajectory",
        &redundant(),
        "--fk",
        q.to_str().unwrap(),
        "--limits",
        "strict",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--limits/--reference = given with --fk"),
        "{}",
        stderr(&o)
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The 6-DoF design has no redundancy: `ik` accepts `--limits strict` (and a reference)
/// and solves its square system; `trajectory` follows the same rule.
#[test]
fn the_6_dof_design_accepts_strict_as_ik_does_with_the_same_steps() {
    let dir = scratch("six");
    let csv = dir.join("poses.csv");
    let targets = [[0.0, 0.0, -0.0124], [0.001, 0.0, -0.0124]];
    write_poses(&csv, &targets);
    let six = design_path("lilge2022.ron").display().to_string();
    let free = converged_steps(&run(&six, &csv, &[]));
    let strict = converged_steps(&run(&six, &csv, &["--limits", "strict"]));
    assert_eq!(free, strict);
    let ik = tdpcr(&[
        "ik",
        &six,
        "--position",
        "0,0,-0.0124",
        "--limits",
        "strict",
        "--format",
        "json",
    ]);
    assert!(ik.status.success(), "{}", stderr(&ik));
    let v: serde_json::Value = serde_json::from_slice(&ik.stdout).unwrap();
    let q: Vec<f64> = v["q"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(q, strict[0].1);
    std::fs::remove_dir_all(&dir).ok();
}
