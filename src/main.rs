//! The `tdpcr` command-line tool: a thin layer over the library (argument parsing,
//! output formatting, exit codes). Exit codes: 0 success, 1 a solve failed, 2 bad input.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use nalgebra::Vector3;
use serde::Serialize;

use tdpcr::boundary::FiniteDifference;
use tdpcr::error::Error;
use tdpcr::kinetostatics::{JacobianMethod, RobotState, Solution, Solver};
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
    /// Inverse kinetostatics of a parallel robot (6-DoF design): the actuation for a pose.
    Ik(IkArgs),
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
    /// Platform orientation R_ee as a rotation vector RX,RY,RZ (axis × angle) \[rad\], world
    /// frame (default: identity).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    rotvec: Option<Vector3<f64>>,
    /// Grid step Δ along rays and between xy-planes \[m\].
    #[arg(long, default_value_t = tdpcr::workspace::DEFAULT_STEP, allow_hyphen_values = true)]
    step: f64,
    /// Angle φ between rays \[rad\].
    #[arg(long, default_value_t = tdpcr::workspace::DEFAULT_ANGLE_STEP, allow_hyphen_values = true)]
    angle_step: f64,
    /// Lowest and highest plane ZMIN,ZMAX \[m\] (default -0.12,0.12: covers the reference
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
    /// CSV of poses, columns x,y,z,rx,ry,rz \[m, rad\] (IK; 6-DoF design).
    #[arg(long, conflicts_with = "fk", required_unless_present = "fk")]
    ik: Option<PathBuf>,
    /// CSV of actuations, columns q1..qn \[m\] (FK).
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
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            let mut v = tdpcr::error::Violations::default();
            v.push("--tolerance", self.tolerance, "> 0");
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
    /// Extra wrench FX,FY,FZ,MX,MY,MZ \[N, N·m\] on the platform centre, world frame, added
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
    /// Actuation q \[m\]: per leg [bend_x, (bend_y), translation], 6 or 9 values.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    q: Values,
    #[command(flatten)]
    solve: SolveArgs,
}

#[derive(clap::Args)]
struct IkArgs {
    /// Design file (RON, `Tdpcr(...)`).
    design: PathBuf,
    /// Platform position X,Y,Z \[m\], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    position: Vector3<f64>,
    /// Platform orientation as a rotation vector RX,RY,RZ (axis × angle) \[rad\], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    rotvec: Option<Vector3<f64>>,
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
    /// Tendon tensions \[N\], one per tendon in file order, comma-separated.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true, conflicts_with = "displacements", required_unless_present = "displacements")]
    tensions: Option<Values>,
    /// Tendon length changes Δℓ \[m\] (negative = pulled), one per tendon, comma-separated.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    displacements: Option<Values>,
    /// Tip force FX,FY,FZ \[N\], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    tip_force: Option<Vector3<f64>>,
    /// Tip moment MX,MY,MZ \[N·m\], world frame.
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
    residual_norm: f64,
    solve_time_us: f64,
    state: RobotState,
}

#[derive(Serialize)]
struct FailureOutput {
    converged: bool,
    error: String,
    iterations: Option<usize>,
    residual_norm: Option<f64>,
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
    let mut solver = Solver::new(&design);
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
                let (iterations, residual_norm) = match se {
                    tdpcr::SolveError::NotConverged {
                        iterations,
                        residual_norm,
                        ..
                    } => (Some(*iterations), Some(*residual_norm)),
                    _ => (None, None),
                };
                let out = FailureOutput {
                    converged: false,
                    error: e.to_string(),
                    iterations,
                    residual_norm,
                };
                println!(
                    "{}",
                    serde_json::to_string_pretty(&out).expect("plain data serializes")
                );
            }
            return Err(e);
        }
    };
    let pose = sol.state.pose();
    let out = ParallelOutput {
        converged: true,
        position: sol.state.position,
        rotation: rows(&pose.rotation),
        rotvec: sol.state.rotvec,
        q: sol.state.q.clone(),
        tensions: sol.tensions(solver.model()),
        iterations: sol.report.iterations,
        residual_evaluations: sol.report.residual_evaluations,
        residual_norm: sol.report.residual_norm,
        solve_time_us: sol.solve_time_us,
        state: sol.state.clone(),
    };
    match format {
        Format::Json => println!(
            "{}",
            serde_json::to_string_pretty(&out).expect("plain data serializes")
        ),
        Format::Text => {
            let p = out.position;
            let r = out.rotvec;
            println!(
                "position [m]      {:>12.6} {:>12.6} {:>12.6}",
                p[0], p[1], p[2]
            );
            println!(
                "rotvec [rad]      {:>12.6} {:>12.6} {:>12.6}",
                r[0], r[1], r[2]
            );
            println!("q [m]             {:?}", out.q);
            for (i, t) in out.tensions.iter().enumerate() {
                println!("leg {i} tensions [N] {t:?}");
            }
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

fn run_ik(args: &IkArgs) -> Result<(), Error> {
    let (mut solver, wrench, init) = prepare(&args.design, &args.solve)?;
    let rotvec = args.rotvec.unwrap_or_default();
    if !rotvec
        .iter()
        .chain(args.position.iter())
        .all(|x| x.is_finite())
    {
        let mut v = tdpcr::error::Violations::default();
        v.push(
            "--position/--rotvec",
            "a non-finite value",
            "finite numbers",
        );
        return Err(Error::Input(v));
    }
    let pose = tdpcr::model::Pose {
        position: args.position,
        rotation: *nalgebra::Rotation3::new(rotvec).matrix(),
    };
    let result = solver.solve_ik(&pose, &wrench, init.as_ref());
    report(&solver, result, args.solve.format)
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
            reason: "some trajectory steps failed (see converged = false)",
        }));
    }
    Ok(())
}

fn run_jacobian_check(args: &JacobianCheckArgs) -> Result<(), Error> {
    let design = Tdpcr::from_ron_file(&args.design)?;
    let mut solver = Solver::new(&design);
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
        "{} reachable cells ({:.3e} m³), {} near Type II, {} collision; planes z {:.3}..{:.3} m",
        s.counts.reachable,
        s.volume.reachable,
        s.counts.near_type_ii,
        s.counts.collision,
        s.z_reached[0],
        s.z_reached[1]
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
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Tdcr(a) => run_tdcr(a),
        Command::Fk(a) => run_fk(a),
        Command::Ik(a) => run_ik(a),
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
