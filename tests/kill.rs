//! Kill at any moment loses nothing (issue 14, deliverable 5): `tdpcr workspace` killed
//! with SIGKILL at several points leaves under each final name (points.csv,
//! summary.json, the slice figures) either nothing or the complete file of an
//! uninterrupted run. The optimizer's counterpart is `optim/tests/kill.rs`.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A coarse sweep of the reference design, five planes (1.2 s in the test profile on the
/// 2-core AMD machine; the whole z range 2.5 s).
fn workspace_args(out: &Path) -> Vec<String> {
    [
        "workspace",
        &common::design_path("lilge2022.ron").display().to_string(),
        "--step",
        "0.02",
        "--angle-step",
        "0.3",
        "--z-range",
        "-0.04,0.04",
        "--out",
        &out.display().to_string(),
    ]
    .map(str::to_string)
    .to_vec()
}

fn fresh_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("workspace-kill")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the sweep into `out`, killed with SIGKILL after `delay` unless it ends first.
fn run_killed_after(out: &Path, delay: Duration) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tdpcr"))
        .args(workspace_args(out))
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

/// summary.json without the fields that measure the run (wall time, rate, threads).
fn summary_without_timing(text: &str) -> serde_json::Value {
    let mut v: serde_json::Value = serde_json::from_str(text).expect("complete JSON");
    let map = v.as_object_mut().expect("an object");
    for key in ["wall_time_s", "solves_per_second", "threads"] {
        map.remove(key);
    }
    v
}

/// The files under final names (temporaries are `.<name>.<pid>.tmp`).
fn final_files(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = match std::fs::read_dir(dir) {
        Ok(entries) => entries
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| !n.starts_with('.'))
            .collect(),
        Err(_) => Vec::new(),
    };
    names.sort();
    names
}

#[test]
fn a_sweep_killed_at_any_point_leaves_only_complete_files() {
    let reference_dir = fresh_dir("reference");
    let start = Instant::now();
    let o = Command::new(env!("CARGO_BIN_EXE_tdpcr"))
        .args(workspace_args(&reference_dir))
        .output()
        .unwrap();
    let full = start.elapsed();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let reference = final_files(&reference_dir);
    assert!(
        reference.contains(&"points.csv".to_string()),
        "{reference:?}"
    );
    assert!(reference.contains(&"summary.json".to_string()));

    let mut kills_with_files = 0;
    for (i, fraction) in [0.05, 0.2, 0.4, 0.6, 0.8, 0.9, 0.95, 0.98, 1.0]
        .into_iter()
        .enumerate()
    {
        let dir = fresh_dir(&format!("killed-{i}"));
        run_killed_after(&dir, full.mul_f64(fraction));
        let names = final_files(&dir);
        if !names.is_empty() {
            kills_with_files += 1;
        }
        for name in names {
            assert!(
                reference.contains(&name),
                "kill at {fraction}: unexpected {name}"
            );
            let got = std::fs::read_to_string(dir.join(&name)).unwrap();
            let want = std::fs::read_to_string(reference_dir.join(&name)).unwrap();
            if name == "summary.json" {
                assert_eq!(
                    summary_without_timing(&got),
                    summary_without_timing(&want),
                    "kill at {fraction}: {name}"
                );
            } else {
                assert!(got == want, "kill at {fraction}: {name} differs");
            }
        }
    }
    eprintln!("uninterrupted sweep {full:?}; {kills_with_files} of 9 kills left some final files");
}
