//! The command line: one clap struct per subcommand, the option groups they share, and
//! the value parsers of comma-separated numbers. Checks that clap cannot express (value
//! ranges, list lengths) are here too, as `apply` methods returning [`Error::Input`].

use std::path::PathBuf;

use clap::{Parser, Subcommand, ValueEnum};
use nalgebra::Vector3;

use tdpcr::error::Error;
use tdpcr::kinetostatics::Solver;
use tdpcr::redundancy::{Objective, Redundancy};

/// Kinetostatics of tendon-driven (parallel) continuum robots with exact Jacobians.
#[derive(Parser)]
#[command(version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
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
pub struct WorkspaceArgs {
    /// Design file (RON, `Tdpcr(...)`), e.g. designs/lilge2022.ron.
    pub design: PathBuf,
    /// Platform orientation R_ee as a rotation vector RX,RY,RZ (axis × angle) [rad], world
    /// frame (default: identity).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub rotvec: Option<Vector3<f64>>,
    /// Grid step Δ along rays and between xy-planes [m].
    #[arg(long, default_value_t = tdpcr::workspace::DEFAULT_STEP, allow_hyphen_values = true)]
    pub step: f64,
    /// Angle φ between rays [rad].
    #[arg(long, default_value_t = tdpcr::workspace::DEFAULT_ANGLE_STEP, allow_hyphen_values = true)]
    pub angle_step: f64,
    /// Lowest and highest plane ZMIN,ZMAX [m] (default -0.15,0.15: covers the reference
    /// design's workspace at R_ee = I).
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    pub z_range: Option<Values>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Follow rays through collisions (recording the colliding cells) instead of ending
    /// them there.
    #[arg(long)]
    pub through_collisions: bool,
    /// Newton steps with the Jacobian's taut slope only, as before one-sided kink columns
    /// (library: `WorkspaceSettings::one_sided_kinks = false`): the map of before up to
    /// round-off, about 15 % slower than the default; for the 9-DoF design no retry
    /// with one-sided steps where a step across a tendon's kink fails (its ray ends
    /// there, as before 2026-11-28).
    #[arg(long)]
    pub two_sided_kinks: bool,
    /// Newton keeps each step's Jacobian while its chord steps contract ‖b‖ by at least
    /// this factor, in [0, 1) (library: `WorkspaceSettings::chord_contraction`): 0.5
    /// saves about 6 % at coarse steps (Δ = 12 mm), but cells at folds and Type II
    /// singularities may move.
    #[arg(long, default_value_t = 0.1)]
    pub chord_contraction: f64,
    /// Newton iterations a ray step gets before it must have reduced ‖b‖ tenfold to go
    /// on, ≥ 1 (library: `WorkspaceSettings::probe_iterations`): fewer end steps past a
    /// fold sooner (the design search's default config takes 8 at Δ = 12 mm), but could
    /// end slow steps that make progress later; the path along z keeps at least 15.
    #[arg(long, default_value_t = tdpcr::workspace::DEFAULT_PROBE_ITERATIONS)]
    pub probe_iterations: usize,
    /// Output directory (created if missing): points.csv, summary.json, slice figures.
    #[arg(long)]
    pub out: PathBuf,
    /// Redundancy resolution of every IK step of the 9-DoF design, as in `ik` (`free`:
    /// a q beyond its limits ends the ray; `strict`: the steps keep q within them).
    #[command(flatten)]
    pub redundancy: RedundancyArgs,
}

#[derive(clap::Args)]
pub struct TrajectoryArgs {
    /// Design file (RON, `Tdpcr(...)`).
    pub design: PathBuf,
    /// CSV of poses, columns x,y,z,rx,ry,rz [m, rad] (IK).
    #[arg(long, conflicts_with = "fk", required_unless_present = "fk")]
    pub ik: Option<PathBuf>,
    /// CSV of actuations, columns q1..qn [m] (FK).
    #[arg(long)]
    pub fk: Option<PathBuf>,
    /// Redundancy resolution of every IK step, as in `ik` (only with --ik).
    #[command(flatten)]
    pub redundancy: RedundancyArgs,
    /// Least-norm IK steps of the 9-DoF design (--ik, --limits free) start with chord
    /// steps on the latest least-norm factorization (back and forth about 2× faster per
    /// step), but q lands elsewhere on the set of solutions than with each start's own
    /// Jacobian (library: `Solver::reuse_least_norm_factorization`).
    #[arg(long)]
    pub reuse_factorization: bool,
    #[command(flatten)]
    pub solve: SolveArgs,
}

#[derive(clap::Args)]
pub struct JacobianCheckArgs {
    /// Design file (RON, `Tdpcr(...)`).
    pub design: PathBuf,
    /// Number of configurations (seeded actuation vectors over half the actuation range).
    #[arg(long, default_value_t = 5)]
    pub samples: usize,
    /// Seed of the actuation vectors.
    #[arg(long, default_value_t = 42)]
    pub seed: u64,
    /// Output format.
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

/// Jacobian used by Newton.
#[derive(Clone, Copy, ValueEnum, Default)]
pub enum JacobianArg {
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
pub struct NewtonArgs {
    /// Newton tolerance on the Euclidean norm of the residual in test units: SI, with the
    /// rows of a robot below 1 m / 1 N / 1 N·m relative to its length L, F* and M*
    /// (docs/MODEL.md §9b).
    #[arg(long, default_value_t = 1e-10)]
    pub tolerance: f64,
    /// Most Newton iterations.
    #[arg(long, default_value_t = 60)]
    pub max_iterations: usize,
}

impl NewtonArgs {
    /// Checks the values and writes them into `settings`.
    pub fn apply(&self, settings: &mut tdpcr::newton::NewtonSettings) -> Result<(), Error> {
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
pub struct SolveArgs {
    /// Extra wrench FX,FY,FZ,MX,MY,MZ [N, N·m] on the platform centre, world frame, added
    /// to the platform's weight.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    pub wrench: Option<Values>,
    /// Warm start: a JSON file with a `state` (the output of fk/ik) or the state itself
    /// (`trajectory`: of its first step).
    #[arg(long)]
    pub init: Option<PathBuf>,
    /// Jacobian used by Newton.
    #[arg(long, value_enum, default_value_t)]
    pub jacobian: JacobianArg,
    #[command(flatten)]
    pub newton: NewtonArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(clap::Args)]
pub struct FkArgs {
    /// Design file (RON, `Tdpcr(...)`), e.g. designs/lilge2022.ron.
    pub design: PathBuf,
    /// Actuation q [m]: per leg [bend_x, (bend_y), translation], 6 or 9 values.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    pub q: Values,
    /// Also write the solved configuration as an interactive 3D page (one self-contained
    /// HTML file, opens offline).
    #[arg(long, value_name = "FILE.html")]
    pub view: Option<PathBuf>,
    /// Also write the solved configuration in three orthographic views (top, front, side;
    /// one mm scale) as DIR/configuration.svg, for papers (the directory is created).
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub solve: SolveArgs,
}

#[derive(clap::Args)]
pub struct IkArgs {
    /// Design file (RON, `Tdpcr(...)`).
    pub design: PathBuf,
    /// Platform position X,Y,Z [m], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub position: Vector3<f64>,
    /// Platform orientation as a rotation vector RX,RY,RZ (axis × angle) [rad], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub rotvec: Option<Vector3<f64>>,
    /// Also write the solved configuration as an interactive 3D page (one self-contained
    /// HTML file, opens offline).
    #[arg(long, value_name = "FILE.html")]
    pub view: Option<PathBuf>,
    /// Also write the solved configuration in three orthographic views (top, front, side;
    /// one mm scale) as DIR/configuration.svg, for papers (the directory is created).
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub redundancy: RedundancyArgs,
    #[command(flatten)]
    pub solve: SolveArgs,
}

/// How IK of the 9-DoF design treats the actuation limits.
#[derive(Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum LimitsArg {
    /// Least-norm steps; q may leave its limits (the default).
    #[default]
    Free,
    /// Every Newton step a QP that keeps q within its limits.
    Strict,
}

/// Redundancy resolution of the 9-DoF design (ignored by the 6-DoF design).
#[derive(clap::Args)]
pub struct RedundancyArgs {
    /// Actuation limits in IK of the 9-DoF design: `free` (least-norm steps, limits not
    /// enforced) or `strict` (QP steps within the design's actuation_limits).
    #[arg(long, value_enum, default_value_t)]
    pub limits: LimitsArg,
    /// With --limits strict: stay close to this actuation Q1,...,Q9 [m] instead of
    /// changing q least.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    pub reference: Option<Values>,
}

impl RedundancyArgs {
    /// Whether either flag asks for more than the default (`--limits free`, no reference).
    pub fn given(&self) -> bool {
        self.limits != LimitsArg::Free || self.reference.is_some()
    }

    /// Checks the values and sets the solver's redundancy resolution.
    pub fn apply(&self, solver: &mut Solver) -> Result<(), Error> {
        solver.redundancy = self.resolve(solver.model().n_actuators())?;
        Ok(())
    }

    /// Checks the values (`n` actuators) and gives the redundancy resolution they ask for.
    pub fn resolve(&self, n: usize) -> Result<Redundancy, Error> {
        let mut v = tdpcr::error::Violations::default();
        if let Some(r) = &self.reference {
            if self.limits != LimitsArg::Strict {
                v.push("--reference", "given", "only with --limits strict");
            }
            if r.0.len() != n {
                v.push(
                    "--reference",
                    tdpcr::error::counted(r.0.len(), "value"),
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
        Ok(match (self.limits, &self.reference) {
            (LimitsArg::Free, _) => Redundancy::LeastNorm,
            (LimitsArg::Strict, None) => Redundancy::WithinLimits(Objective::LeastChange),
            (LimitsArg::Strict, Some(r)) => {
                Redundancy::WithinLimits(Objective::ClosestTo(r.0.clone()))
            }
        })
    }
}

#[derive(clap::Args)]
pub struct AnalyzeArgs {
    /// Design file (RON, `Tdpcr(...)`).
    pub design: PathBuf,
    /// Analyse the FK solution of this actuation Q1,...,Qn [m].
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true, conflicts_with = "position", required_unless_present = "position")]
    pub q: Option<Values>,
    /// Analyse the IK solution of this platform position X,Y,Z [m], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub position: Option<Vector3<f64>>,
    /// With --position: platform orientation as a rotation vector RX,RY,RZ [rad].
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, requires = "position")]
    pub rotvec: Option<Vector3<f64>>,
    /// Write the ellipsoids' xy and xz views as SVG files into this directory, and
    /// `configuration.svg` (the configuration in three orthographic views).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Also write the solved configuration with the J_p and C_p ellipsoids as an interactive 3D page (one self-contained
    /// HTML file, opens offline).
    #[arg(long, value_name = "FILE.html")]
    pub view: Option<PathBuf>,

    /// Type I flag threshold on the raw rcond of [B_q B_u] (default 3.5e-9).
    #[arg(long)]
    pub type_i_threshold: Option<f64>,
    /// Type II flag threshold on the raw rcond of [B_x B_u] (default 3.5e-9, the paper's).
    #[arg(long)]
    pub type_ii_threshold: Option<f64>,
    /// Leg-singularity flag threshold on the raw rcond of B_u (default 3.5e-9).
    #[arg(long)]
    pub leg_threshold: Option<f64>,
    #[command(flatten)]
    pub redundancy: RedundancyArgs,
    #[command(flatten)]
    pub solve: SolveArgs,
}

#[derive(Clone, Copy, ValueEnum, Default)]
pub enum Format {
    /// Human-readable text.
    #[default]
    Text,
    /// One JSON object on stdout.
    Json,
}

#[derive(clap::Args)]
pub struct TdcrArgs {
    /// Robot file (RON, `Tdcr(...)`), e.g. designs/tdcr_one_segment.ron.
    pub robot: PathBuf,
    /// Tendon tensions [N], one per tendon in file order, comma-separated.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true, conflicts_with = "displacements", required_unless_present = "displacements")]
    pub tensions: Option<Values>,
    /// Tendon length changes Δℓ [m] (negative = pulled), one per tendon, comma-separated.
    #[arg(long, value_parser = parse_list, allow_hyphen_values = true)]
    pub displacements: Option<Values>,
    /// Tip force FX,FY,FZ [N], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub tip_force: Option<Vector3<f64>>,
    /// Tip moment MX,MY,MZ [N·m], world frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub tip_moment: Option<Vector3<f64>>,
    #[command(flatten)]
    pub newton: NewtonArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

#[derive(clap::Args)]
pub struct ValidateArgs {
    /// Design file (RON): `Tdcr(...)` or `Tdpcr(...)`.
    pub design: PathBuf,
}

/// A comma-separated list of numbers (one clap value).
#[derive(Clone, Debug)]
pub struct Values(pub Vec<f64>);

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

/// `x,y,z` as a flag takes it (shortest round-trip digits: 1e200, not 201 digits).
fn vec3_text(x: &Vector3<f64>) -> String {
    format!("{:?},{:?},{:?}", x.x, x.y, x.z)
}

/// The pose of --position and --rotvec.
pub fn pose_arg(
    position: Vector3<f64>,
    rotvec: Option<Vector3<f64>>,
) -> Result<tdpcr::model::Pose, Error> {
    let rotvec = rotvec.unwrap_or_default();
    let mut v = tdpcr::error::Violations::default();
    if !position.iter().all(|x| x.is_finite()) {
        v.push("--position", vec3_text(&position), "finite numbers [m]");
    }
    if !tdpcr::spatial::is_rotation_vector(&rotvec) {
        v.push("--rotvec", vec3_text(&rotvec), tdpcr::spatial::ROTVEC_RULE);
    }
    if !v.0.is_empty() {
        return Err(Error::Input(v));
    }
    Ok(tdpcr::model::Pose {
        position,
        rotation: *nalgebra::Rotation3::new(rotvec).matrix(),
    })
}
