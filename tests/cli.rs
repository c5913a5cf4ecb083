//! The `tdpcr` binary end to end: outputs, exit codes and error messages.

mod common;

use std::process::{Command, Output};

use common::design_path;

fn tdpcr(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tdpcr"))
        .args(args)
        .output()
        .expect("binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn robot() -> String {
    design_path("tdcr_one_segment.ron").display().to_string()
}

#[test]
fn tdcr_json_has_the_documented_keys() {
    let o = tdpcr(&[
        "tdcr",
        &robot(),
        "--displacements",
        "-0.005,0.005",
        "--format",
        "json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in [
        "tip_position",
        "tip_rotation",
        "tensions",
        "iterations",
        "residual_norm",
        "shape",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["tip_position"].as_array().unwrap().len(), 3);
    let rot = v["tip_rotation"].as_array().unwrap();
    assert_eq!(rot.len(), 3);
    assert_eq!(rot[0].as_array().unwrap().len(), 3);
    assert_eq!(v["shape"].as_array().unwrap().len(), 13);
    assert_eq!(v["tensions"][1].as_f64(), Some(0.0));
    assert!(v["residual_norm"].as_f64().unwrap() <= 1e-10);
    // The last disk is the tip.
    assert_eq!(v["shape"][12], v["tip_position"]);
}

#[test]
fn tension_mode_with_tip_load_runs_in_text_format() {
    let o = tdpcr(&[
        "tdcr",
        &robot(),
        "--tensions",
        "2,0.5",
        "--tip-force",
        "0,0.1,-0.2",
        "--tip-moment",
        "0,0,0.001",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("tip position [m]"), "{out}");
}

#[test]
fn bad_input_exits_2_naming_the_problem() {
    let o = tdpcr(&["tdcr", &robot(), "--tensions", "1,2,3"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("tensions = 3 values: expected 2 values, one per tendon"),
        "{}",
        stderr(&o)
    );
    let o = tdpcr(&["tdcr", &robot(), "--tensions", "1,-2"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("tensions[1] = -2: expected >= 0 N"),
        "{}",
        stderr(&o)
    );
    let o = tdpcr(&["tdcr", &robot(), "--tensions", "1,x"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("expected comma-separated numbers, got 'x'"),
        "{}",
        stderr(&o)
    );
    let o = tdpcr(&["tdcr", &robot()]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn displacement_control_without_tendons_is_an_input_error() {
    let dir = std::env::temp_dir().join(format!("tdpcr-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bare.ron");
    let text = std::fs::read_to_string(robot()).unwrap();
    let start = text.find("tendons: [").unwrap();
    let end = start + text[start..].find("],").unwrap() + 2;
    std::fs::write(
        &path,
        format!("{}tendons: [],{}", &text[..start], &text[end..]),
    )
    .unwrap();
    let o = tdpcr(&["tdcr", path.to_str().unwrap(), "--displacements", "0.0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("a robot with at least one tendon"),
        "{}",
        stderr(&o)
    );
    let o = tdpcr(&[
        "tdcr",
        path.to_str().unwrap(),
        "--tensions",
        "",
        "--tip-force",
        "0.001,0,0",
    ]);
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_failed_solve_exits_1_with_residual_and_iterations() {
    let o = tdpcr(&[
        "tdcr",
        &robot(),
        "--displacements",
        "-0.005,0.005",
        "--max-iterations",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("did not converge: residual norm") && e.contains("after 1 iteration:"),
        "{e}"
    );
    // In JSON the failure is an object on stdout, as for fk and ik.
    let o = tdpcr(&[
        "tdcr",
        &robot(),
        "--displacements",
        "-0.005,0.005",
        "--max-iterations",
        "1",
        "--format",
        "json",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["converged"], false);
    assert_eq!(v["stop_reason"], "iteration_limit");
    assert_eq!(v["iterations"], 1);
    // A leg the integration steps cannot follow: an error, not a frame off a rotation.
    let o = tdpcr(&["tdcr", &robot(), "--tensions", "40,0", "--format", "json"]);
    assert_eq!(o.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["converged"], false);
    let e = v["error"].as_str().unwrap();
    assert!(
        e.contains("off a rotation") && e.contains("raise leg.integration_steps"),
        "{e}"
    );
}

#[test]
fn malformed_and_invalid_files_exit_2_with_location() {
    let dir = std::env::temp_dir().join(format!("tdpcr-cli-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("broken.ron");
    std::fs::write(
        &path,
        "Tdcr(\n  gravity: (0.0, 0.0, -9.81),\n  leg: Leg(length: ,\n",
    )
    .unwrap();
    let o = tdpcr(&["tdcr", path.to_str().unwrap(), "--tensions", "1,1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("broken.ron:3:"), "{}", stderr(&o));
    let o = tdpcr(&[
        "validate",
        &design_path("lilge2022.ron").display().to_string(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("6-DoF"));
    // `validate` takes a file by what parses, not by how its first line is spelled: a
    // TDPCR file that `fk` loads is one with a space before its parenthesis or with no
    // struct name at all; a broken TDCR file gets the TDCR error.
    let text = std::fs::read_to_string(design()).unwrap();
    for (name, edited) in [
        ("spaced.ron", text.replacen("Tdpcr(", "Tdpcr (", 1)),
        ("anonymous.ron", text.replacen("Tdpcr(", "(", 1)),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, edited).unwrap();
        let o = tdpcr(&["validate", path.to_str().unwrap()]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        assert!(String::from_utf8_lossy(&o.stdout).contains("valid TDPCR"));
    }
    let o = tdpcr(&["validate", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("broken.ron:3:"), "{}", stderr(&o));
    std::fs::remove_dir_all(&dir).ok();
}

fn design() -> String {
    design_path("lilge2022.ron").display().to_string()
}

#[test]
fn fk_json_has_the_documented_keys_and_its_state_warm_starts() {
    let o = tdpcr(&[
        "fk",
        &design(),
        "--q",
        "0.002,0.01,0,0,0,0",
        "--format",
        "json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in [
        "position",
        "rotation",
        "q",
        "tensions",
        "iterations",
        "residual_norm",
        "converged",
        "solve_time_us",
        "state",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["converged"], serde_json::Value::Bool(true));
    assert_eq!(v["tensions"].as_array().unwrap().len(), 3);
    let jacobians = v["jacobian_evaluations"].as_u64().unwrap();
    assert!(jacobians >= 1 && jacobians <= v["residual_evaluations"].as_u64().unwrap());
    let dir = std::env::temp_dir().join(format!("tdpcr-cli-fk-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("state.json");
    std::fs::write(&path, &o.stdout).unwrap();
    let o2 = tdpcr(&[
        "fk",
        &design(),
        "--q",
        "0.002,0.01,0,0,0,0",
        "--init",
        path.to_str().unwrap(),
        "--format",
        "json",
    ]);
    let v2: serde_json::Value = serde_json::from_slice(&o2.stdout).unwrap();
    assert_eq!(v2["iterations"].as_u64(), Some(0));
    // IK of that pose from the FK state, with the finite-difference Jacobian.
    let p = v["position"].as_array().unwrap();
    let r = v["state"]["rotvec"].as_array().unwrap();
    let pos = format!("{},{},{}", p[0], p[1], p[2]);
    let rot = format!("{},{},{}", r[0], r[1], r[2]);
    let o3 = tdpcr(&[
        "ik",
        &design(),
        "--position",
        &pos,
        "--rotvec",
        &rot,
        "--init",
        path.to_str().unwrap(),
        "--jacobian",
        "fd",
        "--tolerance",
        "1e-9",
        "--format",
        "json",
    ]);
    assert!(o3.status.success(), "{}", stderr(&o3));
    let v3: serde_json::Value = serde_json::from_slice(&o3.stdout).unwrap();
    let q: Vec<f64> = v3["q"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert!(
        (q[0] - 0.002).abs() < 1e-7 && (q[1] - 0.01).abs() < 1e-7,
        "{q:?}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn fk_and_ik_report_bad_input_and_failures() {
    let o = tdpcr(&["fk", &design(), "--q", "0,0,0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("q = 3 values: expected 6 values"),
        "{}",
        stderr(&o)
    );
    let o = tdpcr(&["fk", &design(), "--q", "0,0,0,0,0,0", "--wrench", "1,2"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--wrench = 2 values"), "{}", stderr(&o));
    let o = tdpcr(&[
        "fk",
        &design(),
        "--q",
        "0,0,0,0,0,0",
        "--init",
        "/nonexistent.json",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let o = tdpcr(&[
        "ik",
        &design(),
        "--position",
        "0,0,0.6",
        "--max-iterations",
        "5",
        "--format",
        "json",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["converged"], serde_json::Value::Bool(false));
    // A stable name of why Newton stopped, beside the message.
    let reason = v["stop_reason"].as_str().unwrap();
    assert!(
        [
            "iteration_limit",
            "trust_region_collapsed",
            "continuation_stalled"
        ]
        .contains(&reason),
        "{reason}"
    );
    assert!(stderr(&o).contains("did not converge"), "{}", stderr(&o));
}

#[test]
fn trajectory_reports_steps_and_stats_and_jacobian_check_compares_blocks() {
    let dir = std::env::temp_dir().join(format!("tdpcr-cli-traj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("q.csv");
    let mut csv = String::from("q1,q2,q3,q4,q5,q6\n");
    for k in 0..5 {
        // Leg 1 bends towards its taut tendon's side: no taut/slack switch on the way.
        let x = 0.0005 * k as f64;
        csv.push_str(&format!("{},{},0,0,0,0\n", -x, 2.0 * x));
    }
    std::fs::write(&path, csv).unwrap();
    let o = tdpcr(&[
        "trajectory",
        &design(),
        "--fk",
        path.to_str().unwrap(),
        "--format",
        "json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["steps"].as_array().unwrap().len(), 5);
    for key in ["median_us", "mean_us", "max_us", "failed"] {
        assert!(v["stats"].get(key).is_some(), "missing stats.{key}");
    }
    assert_eq!(v["stats"]["failed"].as_u64(), Some(0));
    // Warm-started steps after the first need few iterations.
    assert!(v["steps"][4]["iterations"].as_u64().unwrap() <= 6);
    std::fs::write(&path, "0,0,0\n").unwrap();
    let o = tdpcr(&["trajectory", &design(), "--fk", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("q.csv:1:1 = 3 columns: expected 6 columns"),
        "{}",
        stderr(&o)
    );

    let o = tdpcr(&[
        "jacobian-check",
        &design(),
        "--samples",
        "2",
        "--format",
        "json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for block in ["b_x", "b_q", "b_w", "b_u"] {
        let e = v["max_rel_error"][block].as_f64().unwrap();
        assert!(e < 1e-6, "{block}: {e}");
    }
    for key in ["time_exact_us", "time_fd_forward_us", "time_fd_central_us"] {
        assert!(v[key].as_f64().unwrap() > 0.0, "{key}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `--two-sided-kinks` sweeps as before the one-sided kink columns: the same cells here,
/// with more Newton Jacobians (measured: 619 against 189).
#[test]
fn workspace_two_sided_kinks_gives_the_same_cells_for_more_jacobians() {
    let dir = std::env::temp_dir().join(format!("tdpcr-cli-kinks-{}", std::process::id()));
    let sweep = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut a = vec![
            "workspace".to_string(),
            design(),
            "--z-range=-0.003,0".into(),
            "--angle-step".into(),
            "0.4".into(),
            "--out".into(),
            out.to_str().unwrap().into(),
        ];
        a.extend(extra.iter().map(|s| s.to_string()));
        let args: Vec<&str> = a.iter().map(String::as_str).collect();
        let o = tdpcr(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        let cells: Vec<String> = std::fs::read_to_string(out.join("points.csv"))
            .unwrap()
            .lines()
            .map(|l| l.split(',').take(3).collect::<Vec<_>>().join(","))
            .collect();
        (v["jacobian_evaluations"].as_u64().unwrap(), cells)
    };
    let (one_sided, cells) = sweep("one", &[]);
    let (two_sided, cells_before) = sweep("two", &["--two-sided-kinks"]);
    assert!(cells.len() > 500, "{}", cells.len());
    assert_eq!(cells, cells_before);
    assert!(
        2 * one_sided < two_sided,
        "Jacobians: {one_sided} one-sided, {two_sided} two-sided"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn workspace_writes_points_summary_and_figures() {
    let dir = std::env::temp_dir().join(format!("tdpcr-cli-ws-{}", std::process::id()));
    let out = dir.join("out");
    let o = tdpcr(&[
        "workspace",
        &design(),
        "--step",
        "0.01",
        "--angle-step",
        "1.0",
        "--z-range",
        "-0.01,0.0",
        "--threads",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("reachable cells"), "{stdout}");
    let csv = std::fs::read_to_string(out.join("points.csv")).unwrap();
    let mut lines = csv.lines();
    let header = lines.next().unwrap();
    assert_eq!(
        header,
        "x,y,z,q1,q2,q3,q4,q5,q6,tau_1_1,tau_1_2,tau_2_1,tau_2_2,tau_3_1,tau_3_2,min_tension,\
         rcond_b_xu,rcond_b_qu,rcond_b_u,rcond_j_p,rcond_j_o,rcond_c_p,rcond_c_o,\
         rcond_scaled_b_xu,rcond_scaled_b_qu,rcond_scaled_b_u,rcond_scaled_j_p,\
         rcond_scaled_j_o,rcond_scaled_c_p,rcond_scaled_c_o,\
         near_type_i,near_type_ii,near_leg_singularity,collision,unstable,\
         min_compliance_eigenvalue"
    );
    let rows: Vec<&str> = lines.collect();
    assert!(rows.len() > 10);
    for row in &rows {
        let fields: Vec<&str> = row.split(',').collect();
        assert_eq!(fields.len(), 36, "{row}");
        assert!(
            fields
                .iter()
                .all(|f| f.parse::<f64>().is_ok_and(f64::is_finite)),
            "{row}"
        );
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for key in [
        "step",
        "angle_step",
        "rotvec",
        "z_range",
        "planes",
        "planes_reached",
        "z_reached",
        "path_ends",
        "rays_per_plane",
        "counts",
        "volume",
        "rcond",
        "rcond_scaled",
        "min_tension",
        "table_iii",
        "fractions",
        "ray_ends",
        "solves",
        "newton_iterations",
        "threads",
        "wall_time_s",
        "solves_per_second",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    for key in [
        "reachable",
        "non_singular",
        "near_type_i",
        "near_type_ii",
        "near_leg_singularity",
        "collision",
        "unstable",
    ] {
        assert!(
            v["counts"][key].is_u64() && v["volume"][key].is_f64(),
            "{key}"
        );
    }
    for per in ["per_cell", "per_sample"] {
        for variant in ["all", "without_type_ii", "regular"] {
            let t = &v["table_iii"][per];
            assert!(t[format!("{variant}_count")].is_u64(), "{per} {variant}");
            for key in ["j_p", "j_o", "c_p", "c_o"] {
                assert!(t[variant][key]["mean"].is_f64(), "{per} {variant} {key}");
            }
        }
    }
    assert!(v["ray_ends"]["unstable"].is_u64());
    for key in ["j_p", "j_o", "c_p", "c_o"] {
        for stat in ["mean", "min", "max"] {
            assert!(v["rcond"][key][stat].is_f64(), "rcond.{key}.{stat}");
        }
    }
    assert_eq!(
        v["counts"]["reachable"].as_u64().unwrap() as usize
            + v["counts"]["collision"].as_u64().unwrap() as usize,
        rows.len()
    );
    // Slice z = 0 only (the range holds no plane near ±0.06 m); no temporary files left.
    for name in [
        "reach_z+0.000.svg",
        "rcond_z+0.000.svg",
        "tension_z+0.000.svg",
    ] {
        let svg = std::fs::read_to_string(out.join(name)).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"),
            "{name}"
        );
    }
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    // points.csv, summary.json, the slice figures and the 3D page workspace.html (issue 18).
    assert_eq!(names.len(), 6, "{names:?}");
    assert!(names.iter().any(|n| n == "workspace.html"), "{names:?}");
    // Bad input exits 2 and names every problem.
    let o = tdpcr(&[
        "workspace",
        &design(),
        "--z-range",
        "0.1",
        "--threads",
        "0",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains("--z-range = 1 value: expected 2 values ZMIN,ZMAX [m]"),
        "{err}"
    );
    assert!(err.contains("--threads = 0: expected 1 to 1024"), "{err}");
    // A z-range without a plane z = k·Δ in it sweeps nothing: bad input.
    let o = tdpcr(&[
        "workspace",
        &design(),
        "--z-range=0.001,0.002",
        "--step",
        "0.01",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--z-range = 0.001,0.002: expected a range that holds a plane"),
        "{}",
        stderr(&o)
    );
    let o = tdpcr(&[
        "workspace",
        &design(),
        "--step",
        "-1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--step = -1: expected in [1e-5, 1] m"),
        "{}",
        stderr(&o)
    );
    // The redundancy flags as in `ik`: a reference needs --limits strict and n_q values.
    let redundant = design().replace("lilge2022.ron", "lilge2022_redundant.ron");
    for (extra, message) in [
        (
            &["--reference", "0,0,0,0,0,0,0,0,0"][..],
            "only with --limits strict",
        ),
        (
            &["--limits", "strict", "--reference", "0,0"][..],
            "--reference = 2 values: expected 9 values",
        ),
    ] {
        let mut a = vec!["workspace", &redundant, "--out", out.to_str().unwrap()];
        a.extend_from_slice(extra);
        let o = tdpcr(&a);
        assert_eq!(o.status.code(), Some(2), "{extra:?}");
        assert!(stderr(&o).contains(message), "{extra:?}: {}", stderr(&o));
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Every number in a JSON value is finite (serde_json writes NaN as null).
fn all_finite(v: &serde_json::Value) -> bool {
    match v {
        serde_json::Value::Null => false,
        serde_json::Value::Number(n) => n.as_f64().is_some_and(f64::is_finite),
        serde_json::Value::Array(a) => a.iter().all(all_finite),
        serde_json::Value::Object(o) => o.values().all(all_finite),
        _ => true,
    }
}

#[test]
fn analyze_json_has_the_documented_keys_no_nan_and_writes_plots() {
    let dir = std::env::temp_dir().join(format!("tdpcr-cli-plots-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let o = tdpcr(&[
        "analyze",
        &design(),
        "--position",
        "0,0,0",
        "--format",
        "json",
        "--plot",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in [
        "j_fk",
        "j_ik",
        "compliance",
        "rcond",
        "singularity",
        "ellipsoids",
        "min_tension",
        "lambda_fk",
        "lambda_ik",
        "lambda_c",
        "thresholds",
        "stability",
        "state",
        "plots",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    let st = &v["stability"];
    assert_eq!(st["stable"], serde_json::Value::Bool(true));
    for (key, n) in [
        ("eigenvalues", 6),
        ("eigenvalues_c_p", 3),
        ("eigenvalues_c_o", 3),
    ] {
        let e = st[key].as_array().unwrap();
        assert_eq!(e.len(), n, "{key}");
        assert!(e.iter().all(|x| x.as_f64().unwrap() > 0.0), "{key}: {e:?}");
    }
    assert!(st["asymmetry"].as_f64().unwrap() < 1e-4);
    let (plots, rest): (Vec<_>, Vec<_>) = v
        .as_object()
        .unwrap()
        .iter()
        .partition(|(k, _)| *k == "plots");
    assert!(
        rest.iter().all(|(_, x)| all_finite(x)),
        "a NaN or null in {v}"
    );
    assert_eq!(v["j_fk"].as_array().unwrap().len(), 6);
    assert_eq!(v["j_fk"][0].as_array().unwrap().len(), 6);
    assert_eq!(v["compliance"].as_array().unwrap().len(), 6);
    for kind in ["raw", "scaled"] {
        for m in ["b_xu", "b_qu", "b_u", "j_p", "j_o", "c_p", "c_o"] {
            assert!(v["rcond"][kind][m].as_f64().unwrap() > 0.0, "{kind}.{m}");
        }
    }
    assert_eq!(v["singularity"]["type_ii"], serde_json::Value::Bool(false));
    assert_eq!(
        v["ellipsoids"]["c_p"]["semi_axes"]
            .as_array()
            .unwrap()
            .len(),
        3
    );
    assert_eq!(plots[0].1.as_array().unwrap().len(), 4);
    for name in ["j_p", "j_o", "c_p", "c_o"] {
        let svg = std::fs::read_to_string(dir.join(format!("{name}.svg"))).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("xz view"), "{name}");
    }
    // No temporary files left behind: the four ellipsoids and configuration.svg (issue 18).
    assert!(dir.join("configuration.svg").exists());
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 5);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn analyze_of_an_fk_solution_prints_text_and_reports_bad_input() {
    let o = tdpcr(&[
        "analyze",
        &design(),
        "--q",
        "0.004,0.02,-0.003,-0.01,0.002,0.03",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    for part in [
        "J_FK",
        "rcond          raw          scaled",
        "singular: type I",
        "C_p [m/N]",
        "stability (actuators held): stable",
    ] {
        assert!(out.contains(part), "{out}");
    }
    // The −45° twist of the ψ = 0 design, solved cold, is an unstable equilibrium.
    let psi0 = design_path("lilge2022_psi0.ron").display().to_string();
    let o = tdpcr(&[
        "analyze",
        &psi0,
        "--position",
        "0,0,0",
        "--rotvec",
        "0,0,-0.7853981633974483",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("stability (actuators held): UNSTABLE"),
        "{out}"
    );
    let o = tdpcr(&["analyze", &design(), "--q", "0,0,0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("q = 3 values: expected 6 values"),
        "{}",
        stderr(&o)
    );
    let o = tdpcr(&[
        "analyze",
        &design(),
        "--q",
        "0,0,0,0,0,0",
        "--position",
        "0,0,0",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let o = tdpcr(&[
        "analyze",
        &design(),
        "--q",
        "0,0,0,0,0,0",
        "--type-ii-threshold=-1",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--type-ii-threshold = -1: expected >= 0 and finite"),
        "{}",
        stderr(&o)
    );
    // --rotvec belongs to --position: with --q it was silently ignored.
    let o = tdpcr(&[
        "analyze",
        &design(),
        "--q",
        "0,0,0,0,0,0",
        "--rotvec",
        "1,0,0",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--rotvec = given with --q"),
        "{}",
        stderr(&o)
    );
    let o = tdpcr(&[
        "analyze",
        &design(),
        "--position",
        "0,0,0.6",
        "--max-iterations",
        "3",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("did not converge"), "{}", stderr(&o));
}

#[test]
fn ik_limits_strict_keeps_the_9_dof_actuation_within_its_limits() {
    let redundant = design_path("lilge2022_redundant.ron").display().to_string();
    let o = tdpcr(&[
        "ik",
        &redundant,
        "--position",
        "0.01,0,0.02",
        "--limits",
        "strict",
        "--format",
        "json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let q: Vec<f64> = v["q"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(q.len(), 9);
    for (j, x) in q.iter().enumerate() {
        let limit = if j % 3 == 2 { 0.1 } else { 0.01 };
        assert!(x.abs() <= limit, "q[{j}] = {x}");
    }
    assert!(v["residual_norm"].as_f64().unwrap() <= 1e-10);
    // A reference must fit the design and needs --limits strict.
    let o = tdpcr(&[
        "ik",
        &redundant,
        "--position",
        "0,0,0",
        "--limits",
        "strict",
        "--reference",
        "0,0",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--reference = 2 values: expected 9 values"),
        "{}",
        stderr(&o)
    );
    let o = tdpcr(&[
        "ik",
        &redundant,
        "--position",
        "0,0,0",
        "--reference",
        "0,0,0,0,0,0,0,0,0",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("only with --limits strict"),
        "{}",
        stderr(&o)
    );
    let o = tdpcr(&["ik", &redundant, "--position", "0,0,0", "--limits", "loose"]);
    assert_eq!(o.status.code(), Some(2));
}

/// `tdpcr ... | head`: when the reader of stdout goes away, the program ends (killed by
/// SIGPIPE, like other Unix tools) instead of panicking in `println!`.
#[cfg(unix)]
#[test]
fn a_closed_stdout_ends_the_program_without_a_panic() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_tdpcr"))
        .args([
            "analyze",
            &design(),
            "--q",
            "0,0,0,0,0,0",
            "--format",
            "json",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary runs");
    // Close the read end before the solve finishes and the JSON is printed.
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
    assert!(
        o.status.success() || o.status.signal() == Some(13),
        "{:?}: {}",
        o.status,
        stderr(&o)
    );
}

/// A sweep that fails before it writes anything (its home configuration diverges) leaves
/// no empty `--out` directory behind; an existing one stays.
#[test]
fn a_failed_sweep_leaves_no_directory_it_made() {
    let heavy = design_with("heavy-ws", "mass: 0.0344", "mass: 1000.0");
    let out = std::env::temp_dir().join(format!("tdpcr-ws-failed-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let fails_into = |out: &std::path::Path| {
        let o = tdpcr(&[
            "workspace",
            heavy.to_str().unwrap(),
            "--step",
            "0.02",
            "--angle-step",
            "0.8",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains("diverged"), "{}", stderr(&o));
    };
    // Its parents too, and only what it made: `new/../kept` does not resolve before
    // `new` exists (judged missing by its path, `kept` was removed).
    let nested = out.join("a").join("b");
    fails_into(&nested);
    assert!(!out.exists(), "an empty directory was left behind");
    std::fs::create_dir_all(out.join("kept")).unwrap();
    fails_into(&out.join("new").join("..").join("kept"));
    assert!(
        out.join("kept").is_dir(),
        "the user's directory was removed"
    );
    assert!(
        !out.join("new").exists(),
        "a directory it made was left behind"
    );
    fails_into(&out);
    assert!(out.is_dir(), "the user's directory was removed");
    std::fs::remove_dir_all(&out).ok();
    std::fs::remove_file(heavy).ok();
}

/// A standard output that cannot be written (a full disk: `> /dev/full`) ends the program
/// with an error message and exit code 1; `println!` panicked (exit 101).
#[cfg(target_os = "linux")]
#[test]
fn an_unwritable_stdout_is_an_error_not_a_panic() {
    for args in [
        vec!["validate", &design()],
        vec!["fk", &design(), "--q", "0,0,0,0,0,0", "--format", "json"],
    ] {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let o = Command::new(env!("CARGO_BIN_EXE_tdpcr"))
            .args(&args)
            .stdout(full)
            .output()
            .expect("binary runs");
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(
            err.contains("error: cannot write to standard output"),
            "{err}"
        );
    }
}

/// A design file: the bundled paper design with `from` replaced by `to`.
fn design_with(name: &str, from: &str, to: &str) -> std::path::PathBuf {
    let text = std::fs::read_to_string(design()).unwrap();
    assert!(text.contains(from));
    let path = std::env::temp_dir().join(format!("tdpcr-{name}-{}.ron", std::process::id()));
    std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    path
}

/// A diverged solve exits 1 and names the input, its factor, what to try, then the stage.
fn assert_diverged(o: &Output, input: &str, factor: &str) {
    assert_eq!(o.status.code(), Some(1), "{}", stderr(o));
    let e = stderr(o);
    assert!(e.starts_with("error: the solve diverged: "), "{e}");
    assert!(
        e.contains(input) && e.contains(&format!("is {factor} times")),
        "{e}"
    );
    assert!(e.contains("Try a smaller step"), "{e}");
    assert!(
        e.contains("non-finite value in rod strain derivatives (eq. 5)"),
        "{e}"
    );
}

#[test]
fn a_diverged_solve_names_the_input_far_outside_the_design_range() {
    let o = tdpcr(&["fk", &design(), "--q", "1,1,1,1,1,1", "--format", "json"]);
    assert_diverged(&o, "q[0] = 1 m", "100");
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["converged"], serde_json::Value::Bool(false));
    assert!(v["error"].as_str().unwrap().contains("diverged"));
    assert!(v.get("stop_reason").is_some());
    assert_eq!(v["diverged_inputs"][0]["factor"].as_f64(), Some(100.0));
    let o = tdpcr(&[
        "fk",
        &design(),
        "--q",
        "0,0,0,0,0,0",
        "--wrench",
        "1e6,0,0,0,0,0",
    ]);
    assert_diverged(&o, "wrench force 1e6 N", "881312");
    let heavy = design_with("heavy", "mass: 0.0344", "mass: 1000.0");
    let o = tdpcr(&["fk", heavy.to_str().unwrap(), "--q", "0,0,0,0,0,0"]);
    assert_diverged(&o, "weight 9810 N of platform.mass", "8646");
    let o = tdpcr(&["tdcr", &robot(), "--tensions", "1e6,0"]);
    assert_diverged(&o, "tensions[0] = 1e6 N", "273511");
    // The input's own sign (it was dropped), and a wrench whose length overflows is
    // f64::MAX, not inf (`null` in JSON).
    let diverged_with = |o: &Output, part: &str| {
        assert_eq!(o.status.code(), Some(1), "{}", stderr(o));
        let e = stderr(o);
        assert!(
            e.starts_with("error: the solve diverged: ") && e.contains(part),
            "{e}"
        );
    };
    let o = tdpcr(&["tdcr", &robot(), "--displacements=-5,0"]);
    diverged_with(&o, "displacements[0] = -5 m is 1000 times");
    // Beyond any rod's length: bad input (a slack of 1e308 m "converged", `inf mm`).
    let o = tdpcr(&["tdcr", &robot(), "--displacements", "1e308,0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("displacements[0] = 1e308: expected within ±10 m"));
    let o = tdpcr(&[
        "fk",
        &design(),
        "--q",
        "0,0,0,0,0,0",
        "--wrench",
        "1e308,1e308,0,0,0,0",
        "--format",
        "json",
    ]);
    diverged_with(
        &o,
        "wrench force 1.414e308 N) = 1.414e308 N is 1.246e308 times",
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        v["diverged_inputs"][0]["value"].as_f64(),
        Some(2f64.sqrt() * 1e308)
    );
    // A 1e9 m leg is bad input: rejected by the design's rule, exit 2.
    let long = design_with("long", "length: 0.145,", "length: 1e9,");
    let o = tdpcr(&["fk", long.to_str().unwrap(), "--q", "0,0,0,0,0,0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("leg.length = 1000000000: expected <= 10 m"),
        "{}",
        stderr(&o)
    );
    std::fs::remove_file(heavy).ok();
    std::fs::remove_file(long).ok();
}

#[test]
fn a_trajectory_that_leaves_the_workspace_counts_its_failures_and_recovers() {
    let dir = std::env::temp_dir().join(format!("tdpcr-cli-leave-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("poses.csv");
    // Home, far out of reach, home again, a small step: the steps after re-entry converge.
    std::fs::write(
        &path,
        "x,y,z,rx,ry,rz\n0,0,-0.0124,0,0,0.1306\n0,0,0.6,0,0,0.1306\n\
         0,0,-0.0124,0,0,0.1306\n0.001,0,-0.0124,0,0,0.1306\n",
    )
    .unwrap();
    let o = tdpcr(&[
        "trajectory",
        &design(),
        "--ik",
        path.to_str().unwrap(),
        "--max-iterations",
        "15",
        "--format",
        "json",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let converged: Vec<bool> = v["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["converged"].as_bool().unwrap())
        .collect();
    assert_eq!(converged, [true, false, true, true]);
    assert_eq!(v["stats"]["failed"].as_u64(), Some(1));
    assert_eq!(v["stats"]["first_failed_step"].as_u64(), Some(1));
    let why = v["stats"]["first_failure"].as_str().unwrap();
    assert!(why.contains("did not converge"), "{why}");
    assert!(v["steps"][1]["error"].as_str().is_some());
    let e = stderr(&o);
    assert!(
        e.contains("1 of 4 trajectory steps failed; the first at step 1: ") && !e.contains("NaN"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `trajectory --limits free|strict --reference`: the IK steps of the 9-DoF design
/// resolved as `ik` resolves them (issue 19).
mod trajectory_limits {
    use std::path::{Path, PathBuf};
    use std::process::Output;

    use super::common::design_path;
    use super::{stderr, tdpcr};

    /// Bending limit of each tendon pair \[m\] and translation limit \[m\] of
    /// designs/lilge2022_redundant.ron (`actuation_limits`).
    const BEND_LIMIT: f64 = 0.01;
    const TRANSLATION_LIMIT: f64 = 0.1;

    fn redundant() -> String {
        design_path("lilge2022_redundant.ron").display().to_string()
    }

    /// A fresh directory for this test's files.
    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("tdpcr-traj-limits-{name}-{}", std::process::id()));
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

    /// A JSON array of numbers.
    fn numbers(v: &serde_json::Value) -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
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
                let p = numbers(&s["position"]);
                ([p[0], p[1], p[2]], numbers(&s["q"]))
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
    fn init_warm_starts_the_first_step() {
        let dir = scratch("init");
        let design = design_path("lilge2022.ron").display().to_string();
        // The state at the first pose's neighbour, from a single IK solve.
        let init = dir.join("init.json");
        let o = tdpcr(&["ik", &design, "--position", "0.002,0,0", "--format", "json"]);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::write(&init, &o.stdout).unwrap();
        let csv = dir.join("poses.csv");
        let targets = [[0.003, 0.0, 0.0], [0.004, 0.0, 0.0]];
        write_poses(&csv, &targets);
        let first_iterations = |o: &Output| {
            assert!(o.status.success(), "{}", stderr(o));
            let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            v["steps"][0]["iterations"].as_u64().unwrap()
        };
        let cold = run(&design, &csv, &[]);
        let warm = run(&design, &csv, &["--init", init.to_str().unwrap()]);
        assert_reached(&converged_steps(&warm), &targets);
        let (c, w) = (first_iterations(&cold), first_iterations(&warm));
        assert!(w < c, "first step: {w} iterations from --init, {c} cold");
        // A state of another design is refused before any step, naming it.
        let o = run(&redundant(), &csv, &["--init", init.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(o.stdout.is_empty());
        assert!(stderr(&o).contains("init.q = 6 values"), "{}", stderr(&o));
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

    /// `--reuse-factorization`: least-norm steps back and forth between two poses start
    /// from the first round trip's factorization, so q at each pose repeats (up to where
    /// each run stops under its tolerance); the flag is refused where there are no
    /// least-norm IK steps.
    #[test]
    fn reused_factorizations_repeat_q_going_back_and_forth() {
        let dir = scratch("reuse");
        let csv = dir.join("poses.csv");
        let targets: Vec<[f64; 3]> = (0..9).map(|k| [0.001 * (k % 2) as f64, 0.0, 0.0]).collect();
        write_poses(&csv, &targets);
        let steps = converged_steps(&run(&redundant(), &csv, &["--reuse-factorization"]));
        assert_reached(&steps, &targets);
        // (Fresh steps creep by ≈ 4e-8 m a round trip here; a run that stops at a weighted
        // residual of 9e-11 instead of 1e-11 lands about 1e-11 m away.)
        for k in 4..steps.len() {
            let (a, b) = (&steps[k].1, &steps[k - 2].1);
            let d = a
                .iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            assert!(
                d < 1e-10,
                "step {k}: q differs from step {} by {d:e} m",
                k - 2
            );
        }
        for extra in [
            &["--limits", "strict", "--reuse-factorization"][..],
            &["--reuse-factorization"][..],
        ] {
            let design = if extra.len() == 1 {
                design_path("lilge2022.ron").display().to_string()
            } else {
                redundant()
            };
            let o = run(&design, &csv, extra);
            assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
            assert!(
                stderr(&o).contains("--reuse-factorization"),
                "{}",
                stderr(&o)
            );
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
        assert_eq!(numbers(&v["q"]), strict[0].1);
        std::fs::remove_dir_all(&dir).ok();
    }
}

/// `workspace --out` is checked before the sweep: a file where the directory should be,
/// or a directory where one of its files should be, is refused at once (exit 2), and
/// nothing is written.
#[test]
fn workspace_checks_its_output_directory_before_sweeping() {
    let dir = std::env::temp_dir().join(format!("tdpcr-cli-out-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let sweep = |out: &std::path::Path| {
        tdpcr(&[
            "workspace",
            &design(),
            "--z-range=-0.003,0",
            "--angle-step",
            "0.5",
            "--out",
            &out.display().to_string(),
        ])
    };
    let o = sweep(&file);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("is not a directory"), "{}", stderr(&o));
    let out = dir.join("out");
    std::fs::create_dir_all(out.join("summary.json")).unwrap();
    let o = sweep(&out);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("summary.json is a directory"),
        "{}",
        stderr(&o)
    );
    let names: Vec<_> = std::fs::read_dir(&out).unwrap().collect();
    assert_eq!(
        names.len(),
        1,
        "only the directory that was there: {names:?}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `jacobian-check`: a sample count out of range is bad input (it printed NaN ratios for
/// 0); samples that do not solve are listed with their reasons, and a design none of
/// whose samples solves fails with the first sample's error (exit 1).
#[test]
fn jacobian_check_reports_samples_it_could_not_compare() {
    let o = tdpcr(&["jacobian-check", &design(), "--samples", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--samples = 0: expected 1 to 10000 configurations"),
        "{}",
        stderr(&o)
    );
    // A platform of a tonne on these legs: no sample solves.
    let heavy = design_with("cli-jc-heavy", "mass: 0.0344", "mass: 1e3");
    let o = tdpcr(&[
        "jacobian-check",
        &heavy.display().to_string(),
        "--samples",
        "2",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("sample 0: the solve diverged") && e.contains("sample 1: "),
        "{e}"
    );
    std::fs::remove_file(&heavy).ok();
}

/// A failed trajectory step says why Newton stopped (`stop_reason`), and a failed FK
/// step has no pose (null in JSON, empty fields in the text rows), where it showed a
/// made-up one at the origin.
#[test]
fn failed_trajectory_steps_carry_their_stop_reason_and_no_made_up_pose() {
    let dir = std::env::temp_dir().join(format!("tdpcr-cli-traj-failed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let q = dir.join("q.csv");
    std::fs::write(&q, "0,0,0,0,0,0\n1,1,1,1,1,1\n").unwrap();
    let q = q.display().to_string();
    let o = tdpcr(&["trajectory", &design(), "--fk", &q, "--format", "json"]);
    assert_eq!(o.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let failed = &v["steps"][1];
    assert_eq!(failed["converged"], false);
    assert!(
        failed["position"].is_null() && failed["rotvec"].is_null(),
        "{failed}"
    );
    assert_eq!(failed["stop_reason"], "iteration_limit");
    assert!(v["steps"][0]["stop_reason"].is_null());
    let o = tdpcr(&["trajectory", &design(), "--fk", &q]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.lines()
            .any(|l| l.starts_with("1,false,60,") && l.contains(",,,,,,1;1;1")),
        "{text}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
