//! The `tdpcr` command-line tool: a thin layer over the library (argument parsing,
//! output formatting, exit codes). Exit codes: 0 success, 1 a solve failed, 2 bad input.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use nalgebra::Vector3;
use serde::Serialize;

use tdpcr::analysis::{Analysis, AnalysisSettings, Rconds};
use tdpcr::boundary::FiniteDifference;
use tdpcr::error::Error;
use tdpcr::kinetostatics::{JacobianMethod, RobotState, Solution, Solver};
use tdpcr::redundancy::{Objective, Redundancy};
use tdpcr::rod::Wrench;
use tdpcr::tdcr::{TdcrSolver, TdcrState, TendonControl, TipWrench, rows};
use tdpcr::{Tdcr, Tdpcr};

/// Kinetostatics of tendon-driven (parallel) continuum robots with exact Jacobians.
#[derive(Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Solve one tendon-driven continuum robot (TDCR) under tendon tensions or displacements.
    Tdcr(TdcrArgs),
    /// Forward kinetostatics of a parallel robot: the platform pose for actuation q.
    Fk(FkArgs),
    /// Inverse kinetostatics of a parallel robot: the actuation for a pose.
    Ik(IkArgs),
    /// Kinetostatic analysis of a configuration (FK of --q or IK of --position):
    /// Jacobians, compliance, singularity measures, ellipsoids.
    Analyze(AnalyzeArgs),
    /// Solve a sequence of IK poses or FK actuations, each warm-started from the last.
    Trajectory(TrajectoryArgs),
    /// Compare the exact Jacobian blocks with finite differences and time both.
    JacobianCheck(JacobianCheckArgs),
    /// Translational workspace for a fixed orientation (paper Sec. V-B): rays of
    /// warm-started IK in xy-planes, with singularity and isotropy maps.
    Workspace(WorkspaceArgs),
    /// Load and validate a design file (TDCR or TDPCR) and print a summary.
    Validate(ValidateArgs),
}

#[derive(clap::Args)]
struct WorkspaceArgs {
    /// Design file (RON, `Tdpcr(...)`), e.g. designs/lilge2022.ron.
    design: PathBuf,
    /// Platform orientation R_ee as a rotation vector RX,RY,RZ (axis × angle) [rad], world
    /// frame (default: identity).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    rotvec: Option<Vector3<f64>>,
    /// Grid step Δ along rays and between xy-planes [m].
    #[arg(long, default_value_t = tdpcr::workspace::DEFAULT_STEP, allow_hyphen_values = true)]
    step: f64,
    /// Angle φ between rays [rad].
    #[arg(long, default_value_t = tdpcr::workspace::DEFAULT_ANGLE_STEP, allow_hyphen_values = true)]
    angle_step: f64,
    /// Lowest and highest plane ZMIN,ZMAX [m] (default -0.15,0.15: covers the reference
    /// design's workspace at R_ee = I).
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    z_range: Option<Values>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Follow rays through collisions (recording the colliding cells) instead of ending
    /// them there.
    #[arg(long)]
    through_collisions: bool,
    /// Output directory (created if missing): points.csv, summary.json, slice figures.
    #[arg(long)]
    out: PathBuf,
}

#[derive(clap::Args)]
struct TrajectoryArgs {
    /// Design file (RON, `Tdpcr(...)`).
    design: PathBuf,
    /// CSV of poses, columns x,y,z,rx,ry,rz [m, rad] (IK; 6-DoF design).
    #[arg(long, conflicts_with = "fk", required_unless_present = "fk")]
    ik: Option<PathBuf>,
    /// CSV of actuations, columns q1..qn [m] (FK).
    #[arg(long)]
    fk: Option<PathBuf>,
    #[command(flatten)]
    solve: SolveArgs,
}

#[derive(clap::Args)]
struct JacobianCheckArgs {
    /// Design file (RON, `Tdpcr(...)`).
    design: PathBuf,
    /// Number of configurations (seeded actuation vectors over half the actuation range).
    #[arg(long, default_value_t = 5)]
    samples: usize,
    /// Seed of the actuation vectors.
    #[arg(long, default_value_t = 42)]
    seed: u64,
    /// Output format.
    #[arg(long, value_enum, default_value_t)]
    format: Format,
}

/// Jacobian used by Newton.
#[derive(Clone, Copy, ValueEnum, Default)]
enum JacobianArg {
    /// Exact, from forward sensitivities.
    #[default]
    Exact,
    /// The paper's forward finite differences.
    Fd,
    /// Central finite differences.
    FdCentral,
}

/// Newton options shared by every solving subcommand.
#[derive(clap::Args)]
struct NewtonArgs {
    /// Newton tolerance on the Euclidean norm of the SI residual.
    #[arg(long, default_value_t = 1e-10)]
    tolerance: f64,
    /// Most Newton iterations.
    #[arg(long, default_value_t = 60)]
    max_iterations: usize,
}

impl NewtonArgs {
    /// Checks the values and writes them into `settings`.
    fn apply(&self, settings: &mut tdpcr::newton::NewtonSettings) -> Result<(), Error> {
        let mut v = tdpcr::error::Violations::default();
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            v.push("--tolerance", self.tolerance, "> 0");
        }
        if self.max_iterations == 0 {
            v.push("--max-iterations", 0, ">= 1");
        }
        if !v.0.is_empty() {
            return Err(Error::Input(v));
        }
        settings.tolerance = self.tolerance;
        settings.max_iterations = self.max_iterations;
        Ok(())
    }
}

/// Options shared by `fk` and `ik`.
#[derive(clap::Args)]
struct SolveArgs {
    /// Extra wrench FX,FY,FZ,MX,MY,MZ [N, N·m] on the platform centre, world frame, added
    /// to the platform's weight.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    wrench: Option<Values>,
    /// Warm start: a JSON file with a `state` (the output of fk/ik) or the state itself.
    #[arg(long)]
    init: Option<PathBuf>,
    /// Jacobian used by Newton.
    #[arg(long, value_enum, default_value_t)]
    jacobian: JacobianArg,
    #[command(flatten)]
    newton: NewtonArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t)]
    format: Format,
}

#[derive(clap::Args)]
struct FkArgs {
    /// Design file (RON, `Tdpcr(...)`), e.g. designs/lilge2022.ron.
    design: PathBuf,
    /// Actuation q [m]: per leg [bend_x, (bend_y), translation], 6 or 9 values.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    q: Values,
    #[command(flatten)]
    solve: SolveArgs,
}

#[derive(clap::Args)]
struct IkArgs {
    /// Design file (RON, `Tdpcr(...)`).
    design: PathBuf,
    /// Platform position X,Y,Z [m], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    position: Vector3<f64>,
    /// Platform orientation as a rotation vector RX,RY,RZ (axis × angle) [rad], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    rotvec: Option<Vector3<f64>>,
    #[command(flatten)]
    redundancy: RedundancyArgs,
    #[command(flatten)]
    solve: SolveArgs,
}

/// How IK of the 9-DoF design treats the actuation limits.
#[derive(Clone, Copy, ValueEnum, Default, PartialEq)]
enum LimitsArg {
    /// Least-norm steps; q may leave its limits (the default).
    #[default]
    Free,
    /// Every Newton step a QP that keeps q within its limits.
    Strict,
}

/// Redundancy resolution of the 9-DoF design (ignored by the 6-DoF design).
#[derive(clap::Args)]
struct RedundancyArgs {
    /// Actuation limits in IK of the 9-DoF design: `free` (least-norm steps, limits not
    /// enforced) or `strict` (QP steps within the design's actuation_limits).
    #[arg(long, value_enum, default_value_t)]
    limits: LimitsArg,
    /// With --limits strict: stay close to this actuation Q1,...,Q9 [m] instead of
    /// changing q least.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    reference: Option<Values>,
}

impl RedundancyArgs {
    /// Checks the values and sets the solver's redundancy resolution.
    fn apply(&self, solver: &mut Solver) -> Result<(), Error> {
        let n = solver.model().n_actuators();
        let mut v = tdpcr::error::Violations::default();
        if let Some(r) = &self.reference {
            if self.limits != LimitsArg::Strict {
                v.push("--reference", "given", "only with --limits strict");
            }
            if r.0.len() != n {
                v.push(
                    "--reference",
                    format!("{} values", r.0.len()),
                    &format!("{n} values: per leg [bend_x, (bend_y), translation]"),
                );
            }
            if !r.0.iter().all(|x| x.is_finite()) {
                v.push("--reference", "a non-finite value", "finite numbers [m]");
            }
        }
        if !v.0.is_empty() {
            return Err(Error::Input(v));
        }
        solver.redundancy = match (self.limits, &self.reference) {
            (LimitsArg::Free, _) => Redundancy::LeastNorm,
            (LimitsArg::Strict, None) => Redundancy::WithinLimits(Objective::LeastChange),
            (LimitsArg::Strict, Some(r)) => {
                Redundancy::WithinLimits(Objective::ClosestTo(r.0.clone()))
            }
        };
        Ok(())
    }
}

#[derive(clap::Args)]
struct AnalyzeArgs {
    /// Design file (RON, `Tdpcr(...)`).
    design: PathBuf,
    /// Analyse the FK solution of this actuation Q1,...,Qn [m].
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true, conflicts_with = "position", required_unless_present = "position")]
    q: Option<Values>,
    /// Analyse the IK solution of this platform position X,Y,Z [m], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    position: Option<Vector3<f64>>,
    /// With --position: platform orientation as a rotation vector RX,RY,RZ [rad].
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, requires = "position")]
    rotvec: Option<Vector3<f64>>,
    /// Write the ellipsoids' xy and xz views as SVG files into this directory.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Type I flag threshold on the raw rcond of [B_q B_u] (default 3.5e-9).
    #[arg(long)]
    type_i_threshold: Option<f64>,
    /// Type II flag threshold on the raw rcond of [B_x B_u] (default 3.5e-9, the paper's).
    #[arg(long)]
    type_ii_threshold: Option<f64>,
    /// Leg-singularity flag threshold on the raw rcond of B_u (default 3.5e-9).
    #[arg(long)]
    leg_threshold: Option<f64>,
    #[command(flatten)]
    redundancy: RedundancyArgs,
    #[command(flatten)]
    solve: SolveArgs,
}

#[derive(Clone, Copy, ValueEnum, Default)]
enum Format {
    /// Human-readable text.
    #[default]
    Text,
    /// One JSON object on stdout.
    Json,
}

#[derive(clap::Args)]
struct TdcrArgs {
    /// Robot file (RON, `Tdcr(...)`), e.g. designs/tdcr_one_segment.ron.
    robot: PathBuf,
    /// Tendon tensions [N], one per tendon in file order, comma-separated.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true, conflicts_with = "displacements", required_unless_present = "displacements")]
    tensions: Option<Values>,
    /// Tendon length changes Δℓ [m] (negative = pulled), one per tendon, comma-separated.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    displacements: Option<Values>,
    /// Tip force FX,FY,FZ [N], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    tip_force: Option<Vector3<f64>>,
    /// Tip moment MX,MY,MZ [N·m], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    tip_moment: Option<Vector3<f64>>,
    #[command(flatten)]
    newton: NewtonArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t)]
    format: Format,
}

#[derive(clap::Args)]
struct ValidateArgs {
    /// Design file (RON): `Tdcr(...)` or `Tdpcr(...)`.
    design: PathBuf,
}

/// A comma-separated list of numbers (one clap value).
#[derive(Clone, Debug)]
struct Values(Vec<f64>);

fn parse_list(s: &str) -> Result<Values, String> {
    parse_numbers(s).map(Values)
}

fn parse_numbers(s: &str) -> Result<Vec<f64>, String> {
    s.split(',')
        .map(|x| {
            x.trim()
                .parse::<f64>()
                .map_err(|_| format!("expected comma-separated numbers, got '{x}' in '{s}'"))
        })
        .collect()
}

fn parse_vec3(s: &str) -> Result<Vector3<f64>, String> {
    let v = parse_numbers(s)?;
    if v.len() != 3 {
        return Err(format!(
            "expected 3 comma-separated numbers, got {} in '{s}'",
            v.len()
        ));
    }
    Ok(Vector3::new(v[0], v[1], v[2]))
}

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

fn run_tdcr(args: &TdcrArgs) -> Result<(), Error> {
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
    let sol = solver.solve(&control, &wrench, None)?;
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
    match args.format {
        Format::Json => println!(
            "{}",
            serde_json::to_string_pretty(&out).expect("plain data serializes")
        ),
        Format::Text => {
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
        }
    }
    Ok(())
}

#[derive(Serialize)]
struct ParallelOutput {
    converged: bool,
    position: [f64; 3],
    rotation: [[f64; 3]; 3],
    rotvec: [f64; 3],
    q: Vec<f64>,
    /// Tendon tensions per leg \[N\].
    tensions: Vec<Vec<f64>>,
    iterations: usize,
    residual_evaluations: usize,
    /// Exact Jacobians evaluated (fewer than `iterations` when chord steps reuse one).
    jacobian_evaluations: usize,
    residual_norm: f64,
    solve_time_us: f64,
    state: RobotState,
}

impl ParallelOutput {
    /// Pose, actuation and tensions, one per line.
    fn print_configuration(&self) {
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

    fn new(solver: &Solver, sol: &Solution) -> Self {
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

#[derive(Serialize)]
struct FailureOutput {
    converged: bool,
    error: String,
    iterations: Option<usize>,
    residual_norm: Option<f64>,
    /// Why Newton stopped, as a stable snake_case name (`tdpcr::StopReason`).
    stop_reason: Option<tdpcr::StopReason>,
}

/// A solver configured from the shared options, and the extra wrench.
fn prepare(
    design: &std::path::Path,
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
                format!("{} values", w.0.len()),
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

/// Reads a warm-start state: a JSON object with a `state` field, or the state itself.
fn read_state(path: &std::path::Path) -> Result<RobotState, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("a readable JSON file ({e})"))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("valid JSON ({e})"))?;
    let state = value.get("state").cloned().unwrap_or(value);
    serde_json::from_value(state)
        .map_err(|e| format!("a state with position, rotvec, q, y_u ({e})"))
}

/// Prints a parallel-robot result (or failure) in the chosen format.
fn report(solver: &Solver, result: Result<Solution, Error>, format: Format) -> Result<(), Error> {
    let sol = match result {
        Ok(sol) => sol,
        Err(e) => {
            if let (Format::Json, Error::Solve(se)) = (format, &e) {
                let (iterations, residual_norm, stop_reason) = match se {
                    tdpcr::SolveError::NotConverged {
                        iterations,
                        residual_norm,
                        reason,
                        ..
                    } => (Some(*iterations), Some(*residual_norm), Some(*reason)),
                    _ => (None, None, None),
                };
                let out = FailureOutput {
                    converged: false,
                    error: e.to_string(),
                    iterations,
                    residual_norm,
                    stop_reason,
                };
                println!(
                    "{}",
                    serde_json::to_string_pretty(&out).expect("plain data serializes")
                );
            }
            return Err(e);
        }
    };
    let out = ParallelOutput::new(solver, &sol);
    match format {
        Format::Json => println!(
            "{}",
            serde_json::to_string_pretty(&out).expect("plain data serializes")
        ),
        Format::Text => {
            out.print_configuration();
            println!(
                "converged in {} iterations ({} residual evaluations, {:.0} µs), residual norm {:.2e}",
                out.iterations, out.residual_evaluations, out.solve_time_us, out.residual_norm
            );
        }
    }
    Ok(())
}

fn run_fk(args: &FkArgs) -> Result<(), Error> {
    let (mut solver, wrench, init) = prepare(&args.design, &args.solve)?;
    let result = solver.solve_fk(&args.q.0, &wrench, init.as_ref());
    report(&solver, result, args.solve.format)
}

/// The pose of --position and --rotvec.
fn pose_arg(
    position: Vector3<f64>,
    rotvec: Option<Vector3<f64>>,
) -> Result<tdpcr::model::Pose, Error> {
    let rotvec = rotvec.unwrap_or_default();
    if !rotvec.iter().chain(position.iter()).all(|x| x.is_finite()) {
        let mut v = tdpcr::error::Violations::default();
        v.push(
            "--position/--rotvec",
            "a non-finite value",
            "finite numbers",
        );
        return Err(Error::Input(v));
    }
    Ok(tdpcr::model::Pose {
        position,
        rotation: *nalgebra::Rotation3::new(rotvec).matrix(),
    })
}

fn run_ik(args: &IkArgs) -> Result<(), Error> {
    let (mut solver, wrench, init) = prepare(&args.design, &args.solve)?;
    args.redundancy.apply(&mut solver)?;
    let pose = pose_arg(args.position, args.rotvec)?;
    let result = solver.solve_ik(&pose, &wrench, init.as_ref());
    report(&solver, result, args.solve.format)
}

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
}

/// A matrix as nested rows.
fn nested_rows(m: &nalgebra::DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}

fn run_analyze(args: &AnalyzeArgs) -> Result<(), Error> {
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
    };
    match args.solve.format {
        Format::Json => println!(
            "{}",
            serde_json::to_string_pretty(&out).expect("plain data serializes")
        ),
        Format::Text => print_analysis(&out),
    }
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
    for path in &out.plots {
        println!("wrote {}", path.display());
    }
    println!(
        "solved in {} iterations ({:.0} µs), residual norm {:.2e}; analysis {:.0} µs",
        sol.iterations, sol.solve_time_us, sol.residual_norm, out.analysis_time_us
    );
}

#[derive(Serialize)]
struct TrajectoryOutput {
    steps: Vec<tdpcr::trajectory::StepResult>,
    stats: tdpcr::trajectory::Stats,
}

fn run_trajectory(args: &TrajectoryArgs) -> Result<(), Error> {
    let (mut solver, wrench, _) = prepare(&args.design, &args.solve)?;
    let targets = match (&args.ik, &args.fk) {
        (Some(path), _) => {
            let rows = tdpcr::trajectory::read_csv(path, 6, "x,y,z,rx,ry,rz")?;
            tdpcr::trajectory::Targets::Poses(tdpcr::trajectory::poses_from_rows(&rows))
        }
        (None, Some(path)) => {
            let n = solver.model().n_actuators();
            let what = format!("q1..q{n}");
            tdpcr::trajectory::Targets::Actuations(tdpcr::trajectory::read_csv(path, n, &what)?)
        }
        (None, None) => unreachable!("clap requires --ik or --fk"),
    };
    let (steps, stats) = tdpcr::trajectory::run_trajectory(&mut solver, &targets, &wrench);
    let failed = stats.failed;
    match args.solve.format {
        Format::Json => {
            let out = TrajectoryOutput { steps, stats };
            println!(
                "{}",
                serde_json::to_string_pretty(&out).expect("plain data serializes")
            );
        }
        Format::Text => {
            println!("step,converged,iterations,solve_time_us,x,y,z,rx,ry,rz,q");
            for s in &steps {
                let q: Vec<String> = s.q.iter().map(|x| x.to_string()).collect();
                println!(
                    "{},{},{},{:.1},{},{},{},{},{},{},{}",
                    s.step,
                    s.converged,
                    s.iterations,
                    s.solve_time_us,
                    s.position[0],
                    s.position[1],
                    s.position[2],
                    s.rotvec[0],
                    s.rotvec[1],
                    s.rotvec[2],
                    q.join(";")
                );
            }
            eprintln!(
                "{} steps, {} failed; per step: median {:.0} µs, mean {:.0} µs, max {:.0} µs, median {} iterations",
                stats.steps,
                stats.failed,
                stats.median_us,
                stats.mean_us,
                stats.max_us,
                stats.median_iterations
            );
        }
    }
    if failed > 0 {
        return Err(Error::Solve(tdpcr::SolveError::NotConverged {
            iterations: 0,
            residual_norm: f64::NAN,
            tolerance: args.solve.newton.tolerance,
            reason: tdpcr::error::StopReason::TrajectoryStepsFailed,
        }));
    }
    Ok(())
}

fn run_jacobian_check(args: &JacobianCheckArgs) -> Result<(), Error> {
    let design = Tdpcr::from_ron_file(&args.design)?;
    let mut solver = Solver::new(&design)?;
    let check = tdpcr::jacobian_check::jacobian_check(&mut solver, args.samples, args.seed);
    match args.format {
        Format::Json => println!(
            "{}",
            serde_json::to_string_pretty(&check).expect("plain data serializes")
        ),
        Format::Text => {
            let e = &check.max_rel_error;
            println!("configurations solved: {}/{}", check.solved, check.samples);
            println!(
                "max relative error vs central FD: B_x {:.1e}, B_q {:.1e}, B_w {:.1e}, B_u {:.1e}",
                e.b_x, e.b_q, e.b_w, e.b_u
            );
            println!(
                "one Jacobian: exact {:.0} µs, forward FD {:.0} µs ({:.1}x), central FD {:.0} µs ({:.1}x)",
                check.time_exact_us,
                check.time_fd_forward_us,
                check.time_fd_forward_us / check.time_exact_us,
                check.time_fd_central_us,
                check.time_fd_central_us / check.time_exact_us
            );
        }
    }
    if check.solved == 0 {
        let mut v = tdpcr::error::Violations::default();
        v.push(
            "--samples",
            args.samples,
            "at least one configuration that solves",
        );
        return Err(Error::Input(v));
    }
    Ok(())
}

fn run_workspace(args: &WorkspaceArgs) -> Result<(), Error> {
    use std::io::IsTerminal;
    use tdpcr::workspace::{
        CollisionPolicy, WorkspaceSettings, files, sweep_workspace_with_progress,
    };
    let design = Tdpcr::from_ron_file(&args.design)?;
    let mut v = tdpcr::error::Violations::default();
    let defaults = WorkspaceSettings::default();
    let z_range = match &args.z_range {
        None => defaults.z_range,
        Some(z) if z.0.len() == 2 => [z.0[0], z.0[1]],
        Some(z) => {
            v.push(
                "--z-range",
                format!("{} values", z.0.len()),
                "2 values ZMIN,ZMAX [m]",
            );
            defaults.z_range
        }
    };
    if args.threads == Some(0) {
        v.push("--threads", 0, ">= 1");
    }
    if !v.0.is_empty() {
        return Err(Error::Input(v));
    }
    let settings = WorkspaceSettings {
        rotvec: args.rotvec.unwrap_or_default().into(),
        step: args.step,
        angle_step: args.angle_step,
        z_range,
        collisions: if args.through_collisions {
            CollisionPolicy::Continue
        } else {
            CollisionPolicy::Stop
        },
        ..defaults
    };
    settings.validate()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.unwrap_or(0))
        .build()
        .map_err(|e| {
            let mut v = tdpcr::error::Violations::default();
            v.push(
                "--threads",
                args.threads.unwrap_or(0),
                &format!("a thread count the system allows ({e})"),
            );
            Error::Input(v)
        })?;
    let bar = if std::io::stderr().is_terminal() {
        let bar = indicatif::ProgressBar::new(0);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:40}] {pos}/{len} rays, ETA {eta}",
            )
            .expect("constant template"),
        );
        Some(bar)
    } else {
        None
    };
    let progress = |p: tdpcr::workspace::Progress| {
        if let Some(bar) = &bar {
            bar.set_length(p.rays_total as u64);
            bar.set_position(p.rays_done as u64);
        }
    };
    let map = pool.install(|| sweep_workspace_with_progress(&design, &settings, &progress))?;
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let written = files::write_outputs(&map, &args.out)?;
    let s = &map.summary;
    println!(
        "{} reachable cells ({:.3e} m³), {} near Type II, {} collision, {} unstable; planes z \
         {:.3}..{:.3} m",
        s.counts.reachable,
        s.volume.reachable,
        s.counts.near_type_ii,
        s.counts.collision,
        s.counts.unstable,
        s.z_reached[0],
        s.z_reached[1]
    );
    let t = &s.table_iii.per_sample.without_type_ii;
    println!(
        "Tab. III means over {} ray samples (near Type II excluded): rcond J_p {:.3}, J_o {:.3}, \
         C_p {:.3}, C_o {:.3}",
        s.table_iii.per_sample.without_type_ii_count,
        t.j_p.mean,
        t.j_o.mean,
        t.c_p.mean,
        t.c_o.mean
    );
    println!(
        "{} solves in {:.1} s on {} threads ({:.0} solves/s)",
        s.solves, s.wall_time_s, s.threads, s.solves_per_second
    );
    for path in written {
        println!("wrote {}", path.display());
    }
    Ok(())
}

fn run_validate(args: &ValidateArgs) -> Result<(), Error> {
    let text = std::fs::read_to_string(&args.design).map_err(|source| tdpcr::DesignError::Io {
        path: args.design.clone(),
        source,
    })?;
    let source = args.design.display().to_string();
    if text
        .trim_start_matches(|c: char| c.is_whitespace())
        .lines()
        .any(|l| l.trim_start().starts_with("Tdpcr("))
    {
        let d = Tdpcr::from_ron_str(&text, &source)?;
        println!(
            "{source}: valid TDPCR, {}-DoF ({} tendons per leg), leg length {} m",
            d.n_actuators(),
            d.leg.tendons.len(),
            d.leg.length
        );
    } else {
        let r = Tdcr::from_ron_str(&text, &source)?;
        println!(
            "{source}: valid TDCR, {} tendons, length {} m, {} integration steps",
            r.leg.tendons.len(),
            r.leg.length,
            r.leg.integration_steps
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    tdpcr::output::end_quietly_on_broken_pipe();
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Tdcr(a) => run_tdcr(a),
        Command::Fk(a) => run_fk(a),
        Command::Ik(a) => run_ik(a),
        Command::Analyze(a) => run_analyze(a),
        Command::Trajectory(a) => run_trajectory(a),
        Command::JacobianCheck(a) => run_jacobian_check(a),
        Command::Workspace(a) => run_workspace(a),
        Command::Validate(a) => run_validate(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            match e {
                Error::Solve(_) | Error::Analysis(_) => ExitCode::from(1),
                _ => ExitCode::from(2),
            }
        }
    }
}
