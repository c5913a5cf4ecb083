//! `tdpcr fk` and `tdpcr ik`: one parallel-robot solve and its output (shared with
//! `analyze`, which prints the same solution first), and the solver set up from the shared
//! options (also used by `trajectory`).

use std::path::Path;

use nalgebra::Vector3;
use serde::Serialize;

use tdpcr::Tdpcr;
use tdpcr::boundary::FiniteDifference;
use tdpcr::error::Error;
use tdpcr::kinetostatics::{JacobianMethod, RobotState, Solution, Solver};
use tdpcr::rod::Wrench;
use tdpcr::tdcr::rows;

use crate::args::{FkArgs, Format, IkArgs, JacobianArg, SolveArgs, pose_arg};
use crate::output;

#[derive(Serialize)]
pub struct ParallelOutput {
    pub converged: bool,
    pub position: [f64; 3],
    pub rotation: [[f64; 3]; 3],
    pub rotvec: [f64; 3],
    pub q: Vec<f64>,
    /// Tendon tensions per leg \[N\].
    pub tensions: Vec<Vec<f64>>,
    pub iterations: usize,
    pub residual_evaluations: usize,
    /// Exact Jacobians evaluated (fewer than `iterations` when chord steps reuse one).
    pub jacobian_evaluations: usize,
    pub residual_norm: f64,
    pub solve_time_us: f64,
    pub state: RobotState,
}

impl ParallelOutput {
    /// Pose, actuation and tensions, one per line.
    pub fn print_configuration(&self) {
        let (p, r) = (self.position, self.rotvec);
        println!(
            "position [m]      {:>12.6} {:>12.6} {:>12.6}",
            p[0], p[1], p[2]
        );
        println!(
            "rotvec [rad]      {:>12.6} {:>12.6} {:>12.6}",
            r[0], r[1], r[2]
        );
        println!("q [m]             {:?}", self.q);
        for (i, t) in self.tensions.iter().enumerate() {
            println!("leg {i} tensions [N] {t:?}");
        }
    }

    pub fn new(solver: &Solver, sol: &Solution) -> Self {
        Self {
            converged: true,
            position: sol.state.position,
            rotation: rows(&sol.state.pose().rotation),
            rotvec: sol.state.rotvec,
            q: sol.state.q.clone(),
            tensions: sol.tensions(solver.model()),
            iterations: sol.report.iterations,
            residual_evaluations: sol.report.residual_evaluations,
            jacobian_evaluations: sol.report.jacobian_evaluations,
            residual_norm: sol.report.residual_norm,
            solve_time_us: sol.solve_time_us,
            state: sol.state.clone(),
        }
    }
}

/// A solver configured from the shared options, and the extra wrench.
pub fn prepare(
    design: &Path,
    args: &SolveArgs,
) -> Result<(Solver, Wrench, Option<RobotState>), Error> {
    let design = Tdpcr::from_ron_file(design)?;
    let mut v = tdpcr::error::Violations::default();
    let wrench = match &args.wrench {
        None => Wrench::default(),
        Some(w) if w.0.len() == 6 => Wrench {
            force: Vector3::new(w.0[0], w.0[1], w.0[2]),
            moment: Vector3::new(w.0[3], w.0[4], w.0[5]),
        },
        Some(w) => {
            v.push(
                "--wrench",
                tdpcr::error::counted(w.0.len(), "value"),
                "6 values FX,FY,FZ,MX,MY,MZ",
            );
            Wrench::default()
        }
    };
    let init = match &args.init {
        None => None,
        Some(path) => match read_state(path) {
            Ok(s) => Some(s),
            Err(e) => {
                v.push("--init", path.display(), &e);
                None
            }
        },
    };
    if !v.0.is_empty() {
        return Err(Error::Input(v));
    }
    let mut solver = Solver::new(&design)?;
    args.newton.apply(&mut solver.settings)?;
    solver.jacobian = match args.jacobian {
        JacobianArg::Exact => JacobianMethod::Exact,
        JacobianArg::Fd => JacobianMethod::FiniteDifference(FiniteDifference::Forward),
        JacobianArg::FdCentral => JacobianMethod::FiniteDifference(FiniteDifference::Central),
    };
    Ok((solver, wrench, init))
}

/// The most bytes an `--init` file may have.
const MAX_STATE_FILE_BYTES: u64 = 16 << 20;

/// Reads a warm-start state: a JSON object with a `state` field, or the state itself.
fn read_state(path: &Path) -> Result<RobotState, String> {
    // A saved state is a few kB (a 9-DoF one about 2 kB).
    let text = tdpcr::design::read_text_at_most(path, MAX_STATE_FILE_BYTES, "a saved state")
        .map_err(|e| format!("a readable JSON file ({e})"))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("valid JSON ({e})"))?;
    let state = value.get("state").cloned().unwrap_or(value);
    serde_json::from_value(state)
        .map_err(|e| format!("a state with position, rotvec, q, y_u ({e})"))
}

/// Prints a parallel-robot result (or failure) in the chosen format.
pub fn report(
    solver: &Solver,
    result: Result<Solution, Error>,
    format: Format,
) -> Result<(), Error> {
    let sol = match result {
        Ok(sol) => sol,
        Err(e) => {
            output::print_solve_failure(format, &e);
            return Err(e);
        }
    };
    let out = ParallelOutput::new(solver, &sol);
    output::print(format, &out, |out| {
        out.print_configuration();
        println!(
            "converged in {} iterations ({} residual evaluations, {:.0} µs), residual norm {:.2e}",
            out.iterations, out.residual_evaluations, out.solve_time_us, out.residual_norm
        );
    });
    Ok(())
}

/// Runs `tdpcr fk`.
pub fn run_fk(args: &FkArgs) -> Result<(), Error> {
    let (mut solver, wrench, init) = prepare(&args.design, &args.solve)?;
    let result = solver.solve_fk(&args.q.0, &wrench, init.as_ref());
    if let (Ok(sol), Some(path)) = (&result, &args.view) {
        crate::view::write_configuration(path, "fk", &solver, sol, None)?;
    }
    if let (Ok(sol), Some(dir)) = (&result, &args.plot) {
        crate::view::write_sketch(dir, &solver, sol)?;
    }
    report(&solver, result, args.solve.format)
}

/// Runs `tdpcr ik`.
pub fn run_ik(args: &IkArgs) -> Result<(), Error> {
    let (mut solver, wrench, init) = prepare(&args.design, &args.solve)?;
    args.redundancy.apply(&mut solver)?;
    let pose = pose_arg(args.position, args.rotvec)?;
    let result = solver.solve_ik(&pose, &wrench, init.as_ref());
    if let (Ok(sol), Some(path)) = (&result, &args.view) {
        crate::view::write_configuration(path, "ik", &solver, sol, None)?;
    }
    if let (Ok(sol), Some(dir)) = (&result, &args.plot) {
        crate::view::write_sketch(dir, &solver, sol)?;
    }
    report(&solver, result, args.solve.format)
}
