//! `tdpcr tdcr`: one tendon-driven continuum robot under tendon tensions or displacements.

use serde::Serialize;

use tdpcr::Tdcr;
use tdpcr::error::Error;
use tdpcr::tdcr::{TdcrSolver, TdcrState, TendonControl, TipWrench, rows};

use crate::args::TdcrArgs;
use crate::output;

#[derive(Serialize)]
struct TdcrOutput {
    tip_position: [f64; 3],
    tip_rotation: [[f64; 3]; 3],
    tensions: Vec<f64>,
    slacks: Vec<f64>,
    iterations: usize,
    residual_evaluations: usize,
    residual_norm: f64,
    /// Backbone positions at the disks \[m\], base excluded.
    shape: Vec<[f64; 3]>,
    shape_arcs: Vec<f64>,
    state: TdcrState,
}

/// Runs `tdpcr tdcr`.
pub fn run(args: &TdcrArgs) -> Result<(), Error> {
    let robot = Tdcr::from_ron_file(&args.robot)?;
    let control = match (&args.tensions, &args.displacements) {
        (Some(t), _) => TendonControl::Tension(t.0.clone()),
        (None, Some(d)) => TendonControl::Displacement(d.0.clone()),
        (None, None) => unreachable!("clap requires one of --tensions, --displacements"),
    };
    let wrench = TipWrench {
        force: args.tip_force.unwrap_or_default(),
        moment: args.tip_moment.unwrap_or_default(),
    };
    let mut solver = TdcrSolver::new(&robot);
    args.newton.apply(&mut solver.settings)?;
    let sol = solver
        .solve(&control, &wrench, None)
        .inspect_err(|e| output::print_solve_failure(args.format, e))?;
    let out = TdcrOutput {
        tip_position: sol.tip.position.into(),
        tip_rotation: rows(&sol.tip.rotation),
        tensions: sol.tensions.clone(),
        slacks: sol.slacks.clone(),
        iterations: sol.report.iterations,
        residual_evaluations: sol.report.residual_evaluations,
        residual_norm: sol.report.residual_norm,
        shape: sol.shape.positions[1..]
            .iter()
            .map(|p| (*p).into())
            .collect(),
        shape_arcs: sol.shape.arcs[1..].to_vec(),
        state: sol.state.clone(),
    };
    output::print(args.format, &out, |out| {
        let p = out.tip_position;
        println!(
            "tip position [m]   {:>12.6} {:>12.6} {:>12.6}",
            p[0], p[1], p[2]
        );
        for (i, r) in out.tip_rotation.iter().enumerate() {
            let label = if i == 0 { "tip rotation" } else { "" };
            println!("{label:<18} {:>12.6} {:>12.6} {:>12.6}", r[0], r[1], r[2]);
        }
        for (k, (t, s)) in out.tensions.iter().zip(&out.slacks).enumerate() {
            println!("tendon {k}: tension {t:.6} N, slack {:.6} mm", s * 1e3);
        }
        println!(
            "converged in {} iterations ({} residual evaluations), residual norm {:.2e}",
            out.iterations, out.residual_evaluations, out.residual_norm
        );
    });
    Ok(())
}
