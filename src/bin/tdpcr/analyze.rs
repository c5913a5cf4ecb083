//! `tdpcr analyze`: the kinetostatic analysis of one solved configuration (Jacobians,
//! compliance, singularity measures, ellipsoids, stability), optionally with SVG views of
//! the ellipsoids.

use std::path::PathBuf;

use serde::Serialize;

use tdpcr::analysis::{Analysis, AnalysisSettings, Rconds};
use tdpcr::error::Error;

use crate::args::{AnalyzeArgs, pose_arg};
use crate::output;
use crate::solve::{ParallelOutput, prepare, report};

/// rcond of the raw SI and of the unit-scaled matrices.
#[derive(Serialize)]
struct RcondOutput {
    raw: Rconds,
    scaled: Rconds,
}

#[derive(Serialize)]
struct AnalyzeOutput {
    /// The solve (as `fk`/`ik` print it).
    #[serde(flatten)]
    solution: ParallelOutput,
    analysis_time_us: f64,
    /// J_FK (6 × n_q, nested rows).
    j_fk: Vec<Vec<f64>>,
    /// J_IK (n_q × 6).
    j_ik: Vec<Vec<f64>>,
    /// C (6 × 6).
    compliance: Vec<Vec<f64>>,
    lambda_fk: Vec<Vec<f64>>,
    lambda_ik: Vec<Vec<f64>>,
    lambda_c: Vec<Vec<f64>>,
    rcond: RcondOutput,
    singularity: tdpcr::analysis::Singularity,
    thresholds: AnalysisSettings,
    ellipsoids: tdpcr::analysis::Ellipsoids,
    min_tension: f64,
    /// Stability with the actuators held (signs of sym(C), MODEL.md §4b).
    stability: tdpcr::analysis::Stability,
    /// SVG files written by --plot.
    plots: Vec<PathBuf>,
    /// `configuration.svg` written by --plot: three orthographic views of the
    /// configuration (absent without --plot).
    #[serde(skip_serializing_if = "Option::is_none")]
    configuration_plot: Option<PathBuf>,
}

/// A matrix as nested rows.
fn nested_rows(m: &nalgebra::DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}

/// Runs `tdpcr analyze`.
pub fn run(args: &AnalyzeArgs) -> Result<(), Error> {
    // The flags are checked before anything is solved.
    let mut v = tdpcr::error::Violations::default();
    if args.q.is_some() && args.rotvec.is_some() {
        v.push(
            "--rotvec",
            "given with --q",
            "only with --position (FK solves for the orientation)",
        );
    }
    for (flag, x) in [
        ("--type-i-threshold", args.type_i_threshold),
        ("--type-ii-threshold", args.type_ii_threshold),
        ("--leg-threshold", args.leg_threshold),
    ] {
        if let Some(x) = x.filter(|x| !(x.is_finite() && *x >= 0.0)) {
            v.push(flag, x, ">= 0 and finite");
        }
    }
    if !v.0.is_empty() {
        return Err(Error::Input(v));
    }
    let (mut solver, wrench, init) = prepare(&args.design, &args.solve)?;
    args.redundancy.apply(&mut solver)?;
    let defaults = AnalysisSettings::default();
    let settings = AnalysisSettings {
        type_i_threshold: args.type_i_threshold.unwrap_or(defaults.type_i_threshold),
        type_ii_threshold: args.type_ii_threshold.unwrap_or(defaults.type_ii_threshold),
        leg_threshold: args.leg_threshold.unwrap_or(defaults.leg_threshold),
    };
    let result = match (&args.q, args.position) {
        (Some(q), _) => solver.solve_fk(&q.0, &wrench, init.as_ref()),
        (None, Some(p)) => solver.solve_ik(&pose_arg(p, args.rotvec)?, &wrench, init.as_ref()),
        (None, None) => unreachable!("clap requires --q or --position"),
    };
    let sol = match result {
        Ok(sol) => sol,
        Err(e) => return report(&solver, Err(e), args.solve.format),
    };
    let start = std::time::Instant::now();
    let a: Analysis = solver.analyze(&sol.state, &wrench, &settings)?;
    let analysis_time_us = start.elapsed().as_secs_f64() * 1e6;
    let plots = match &args.plot {
        Some(dir) => tdpcr::analysis::plot::write_ellipsoid_plots(dir, &a.ellipsoids)?,
        None => Vec::new(),
    };
    let configuration_plot = match &args.plot {
        Some(dir) => Some(crate::view::write_sketch(dir, &solver, &sol)?),
        None => None,
    };
    if let Some(path) = &args.view {
        crate::view::write_configuration(path, "analyze", &solver, &sol, Some(&a.ellipsoids))?;
    }
    let out = AnalyzeOutput {
        solution: ParallelOutput::new(&solver, &sol),
        analysis_time_us,
        j_fk: nested_rows(&a.j_fk),
        j_ik: nested_rows(&a.j_ik),
        compliance: nested_rows(&a.compliance),
        lambda_fk: nested_rows(&a.lambda_fk),
        lambda_ik: nested_rows(&a.lambda_ik),
        lambda_c: nested_rows(&a.lambda_c),
        rcond: RcondOutput {
            raw: a.rcond,
            scaled: a.rcond_scaled,
        },
        singularity: a.singularity,
        thresholds: settings,
        ellipsoids: a.ellipsoids.clone(),
        min_tension: a.min_tension,
        stability: a.stability,
        plots,
        configuration_plot,
    };
    output::print(args.solve.format, &out, print_analysis);
    Ok(())
}

/// The human-readable form of `analyze`.
fn print_analysis(out: &AnalyzeOutput) {
    let sol = &out.solution;
    sol.print_configuration();
    let matrix = |title: &str, m: &[Vec<f64>]| {
        println!("{title}");
        for row in m {
            let cells: Vec<String> = row.iter().map(|x| format!("{x:>11.4e}")).collect();
            println!("  {}", cells.join(" "));
        }
    };
    matrix("J_FK (rows dp [m], dtheta [rad]; columns q [m])", &out.j_fk);
    matrix("J_IK (rows q [m]; columns dp [m], dtheta [rad])", &out.j_ik);
    matrix(
        "C (rows dp [m], dtheta [rad]; columns f [N], l [N m])",
        &out.compliance,
    );
    println!("rcond          raw          scaled");
    let (raw, scaled) = (&out.rcond.raw, &out.rcond.scaled);
    for (name, a, b) in [
        ("[B_x B_u]", raw.b_xu, scaled.b_xu),
        ("[B_q B_u]", raw.b_qu, scaled.b_qu),
        ("B_u", raw.b_u, scaled.b_u),
        ("J_p", raw.j_p, scaled.j_p),
        ("J_o", raw.j_o, scaled.j_o),
        ("C_p", raw.c_p, scaled.c_p),
        ("C_o", raw.c_o, scaled.c_o),
    ] {
        println!("  {name:<11} {a:>11.4e}  {b:>11.4e}");
    }
    let yes = |b: bool| if b { "yes" } else { "no" };
    let s = &out.singularity;
    let t = &out.thresholds;
    println!(
        "singular: type I {} (< {:.1e}), type II {} (< {:.1e}), leg {} (< {:.1e} or a slack pair)",
        yes(s.type_i),
        t.type_i_threshold,
        yes(s.type_ii),
        t.type_ii_threshold,
        yes(s.leg),
        t.leg_threshold
    );
    println!("ellipsoids (semi-axes along unit axes):");
    let e = &out.ellipsoids;
    for (name, unit, el) in [
        ("J_p", "m/m", &e.j_p),
        ("J_o", "rad/m", &e.j_o),
        ("C_p", "m/N", &e.c_p),
        ("C_o", "rad/(N m)", &e.c_o),
    ] {
        let axes: Vec<String> = (0..3)
            .map(|k| {
                let d = el.directions[k];
                format!(
                    "{:.4e} ({:+.3}, {:+.3}, {:+.3})",
                    el.semi_axes[k], d[0], d[1], d[2]
                )
            })
            .collect();
        println!("  {name} [{unit}]: {}", axes.join(", "));
    }
    println!("min tendon tension [N]: {:.6}", out.min_tension);
    let st = &out.stability;
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:+.4e}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    println!(
        "stability (actuators held): {}; eig sym(C) scaled [{}]",
        if st.stable {
            "stable"
        } else {
            "UNSTABLE (sym(C) has a negative eigenvalue)"
        },
        list(&st.eigenvalues)
    );
    println!(
        "  eig sym(C_p) [m/N] [{}]; eig sym(C_o) [rad/(N m)] [{}]; asymmetry {:.1e}",
        list(&st.eigenvalues_c_p),
        list(&st.eigenvalues_c_o),
        st.asymmetry
    );
    for path in out.plots.iter().chain(&out.configuration_plot) {
        println!("wrote {}", path.display());
    }
    println!(
        "solved in {} iterations ({:.0} µs), residual norm {:.2e}; analysis {:.0} µs",
        sol.iterations, sol.solve_time_us, sol.residual_norm, out.analysis_time_us
    );
}
