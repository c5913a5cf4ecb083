//! Error types. Every message names the field or stage, the value and what was expected.

use std::fmt;
use std::path::PathBuf;

/// One violated rule in a design or in command-line input.
#[derive(Debug, Clone, PartialEq)]
pub struct Violation {
    /// Dotted path of the field, e.g. `leg.tendons[1].end`.
    pub field: String,
    /// The offending value, as written.
    pub value: String,
    /// The rule the value breaks, e.g. `> 0 m`.
    pub expected: String,
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} = {}: expected {}",
            self.field, self.value, self.expected
        )
    }
}

/// A list of violations, displayed one per line.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Violations(pub Vec<Violation>);

impl Violations {
    /// Records a violation. A number whose decimal text is long (1e300 has 301 digits)
    /// is written in exponent form.
    pub fn push(&mut self, field: impl Into<String>, value: impl fmt::Display, expected: &str) {
        let mut value = value.to_string();
        if value.len() > 24 {
            if let Ok(x) = value.parse::<f64>() {
                value = format!("{x:e}");
            }
        }
        self.0.push(Violation {
            field: field.into(),
            value,
            expected: expected.to_string(),
        });
    }

    /// `Ok(())` when empty, otherwise the list as a [`DesignError::Invalid`].
    pub fn into_result(self, source: &str) -> Result<(), DesignError> {
        if self.0.is_empty() {
            Ok(())
        } else {
            Err(DesignError::Invalid {
                origin: source.to_string(),
                violations: self,
            })
        }
    }
}

impl fmt::Display for Violations {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for v in &self.0 {
            write!(f, "\n  - {v}")?;
        }
        Ok(())
    }
}

/// A design file that cannot be read, parsed or accepted.
#[derive(Debug, thiserror::Error)]
pub enum DesignError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// File path.
        path: PathBuf,
        /// Underlying I/O error.
        source: std::io::Error,
    },
    /// The file is not valid RON for this schema.
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        /// File path (or `<string>`).
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What the parser expected.
        message: String,
    },
    /// The file parsed but some values break the rules; all of them are listed.
    #[error("invalid {origin} ({} problem{}):{violations}", violations.0.len(), if violations.0.len() == 1 { "" } else { "s" })]
    Invalid {
        /// What was validated (file path or input name).
        origin: String,
        /// Every broken rule.
        violations: Violations,
    },
}

/// Why a solve stopped without reaching its tolerance. `Display` gives the sentence of
/// the error messages; [`StopReason::as_str`] (and serde) a stable snake_case name for
/// scripts (the CLI's JSON key `stop_reason`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// [`crate::newton::NewtonSettings::max_iterations`] iterations done.
    IterationLimit,
    /// A [`crate::newton::ProgressCheck`] failed: too little progress in the first
    /// iterations (e.g. a step beyond a fold).
    TooLittleProgress,
    /// The trust region shrank to nothing: no step reduces the residual.
    TrustRegionCollapsed,
    /// The least-norm IK step of a redundant design is singular (\[B_q B_u\] lost rank).
    SingularLeastNormStep,
    /// The backtracking line search of a least-norm or within-limits IK step failed.
    LineSearchFailed,
    /// The QP of a within-limits IK step could not be set up or solved.
    QpStepFailed,
    /// No step within the actuation limits satisfies the linearized boundary conditions
    /// (the pose is out of reach within the limits?).
    NoStepWithinLimits,
    /// The continuation from the start towards the target stalled (a fold, or no
    /// equilibrium).
    ContinuationStalled,
    /// Some steps of a trajectory failed (the CLI's summary of a trajectory).
    TrajectoryStepsFailed,
    /// The iterates converge to a solution beyond the actuation limits, which the caller
    /// asked not to finish ([`crate::kinetostatics::Solver::stop_beyond_limits`]: the
    /// workspace sweep, whose rays end there either way).
    BeyondActuationLimits,
}

impl StopReason {
    /// Every reason, in declaration order.
    pub const ALL: [Self; 10] = [
        Self::IterationLimit,
        Self::TooLittleProgress,
        Self::TrustRegionCollapsed,
        Self::SingularLeastNormStep,
        Self::LineSearchFailed,
        Self::QpStepFailed,
        Self::NoStepWithinLimits,
        Self::ContinuationStalled,
        Self::TrajectoryStepsFailed,
        Self::BeyondActuationLimits,
    ];

    /// The stable snake_case name, as serialized.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::IterationLimit => "iteration_limit",
            Self::TooLittleProgress => "too_little_progress",
            Self::TrustRegionCollapsed => "trust_region_collapsed",
            Self::SingularLeastNormStep => "singular_least_norm_step",
            Self::LineSearchFailed => "line_search_failed",
            Self::QpStepFailed => "qp_step_failed",
            Self::NoStepWithinLimits => "no_step_within_limits",
            Self::ContinuationStalled => "continuation_stalled",
            Self::TrajectoryStepsFailed => "trajectory_steps_failed",
            Self::BeyondActuationLimits => "beyond_actuation_limits",
        }
    }
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::IterationLimit => "iteration limit reached",
            Self::TooLittleProgress => "too little progress in the first iterations",
            Self::TrustRegionCollapsed => "trust region collapsed (no further progress)",
            Self::SingularLeastNormStep => "singular least-norm step ([B_q B_u] lost rank)",
            Self::LineSearchFailed => "line search failed",
            Self::QpStepFailed => "the QP step failed (clarabel stopped without a solution)",
            Self::NoStepWithinLimits => {
                "no step within the actuation limits satisfies the linearized boundary \
                 conditions (pose out of reach within the limits?)"
            }
            Self::ContinuationStalled => {
                "continuation towards the target stalled (a fold or no equilibrium?)"
            }
            Self::TrajectoryStepsFailed => "some trajectory steps failed (see converged = false)",
            Self::BeyondActuationLimits => {
                "the iterates converge to a solution beyond the actuation limits"
            }
        })
    }
}

/// A solve or an integration that failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// Newton stopped without reaching the tolerance.
    #[error(
        "solve did not converge: residual norm {residual_norm:.3e} (tolerance {tolerance:.1e}) after {}: {reason}", counted(*iterations, "iteration")
    )]
    NotConverged {
        /// Newton iterations (Jacobian evaluations) performed.
        iterations: usize,
        /// Euclidean norm of the SI residual at the best point found.
        residual_norm: f64,
        /// Requested tolerance.
        tolerance: f64,
        /// Why it stopped.
        reason: StopReason,
    },
    /// A NaN or infinity appeared.
    #[error("non-finite value in {stage}")]
    NonFinite {
        /// Where it appeared.
        stage: &'static str,
    },
    /// Some steps of a trajectory failed ([`crate::trajectory`]).
    #[error(
        "{failed} of {steps} trajectory steps failed; the first at step {first_step}: {first_failure}"
    )]
    TrajectoryStepsFailed {
        /// Steps that failed.
        failed: usize,
        /// Steps in the trajectory.
        steps: usize,
        /// Index of the first failed step (0-based, header excluded).
        first_step: usize,
        /// Why it failed.
        first_failure: String,
    },
    /// The solution's leg integration does not resolve the leg: its tip frame came out
    /// `drift` off a rotation (max |RᵀR − I|, above [`MAX_FRAME_DRIFT`]): the leg bends or
    /// twists more within a step than the `steps` integration steps can follow, and its
    /// shape and tip are not to be trusted.
    #[error(
        "the leg's integration does not resolve this solution: its tip frame is {drift:.1e} off a rotation (max |RᵀR − I|, at most {MAX_FRAME_DRIFT:.0e}) with {steps} integration steps; raise leg.integration_steps (the leg bends or twists too far within a step)"
    )]
    UnderResolved {
        /// max |RᵀR − I| of the tip frame.
        drift: f64,
        /// The leg's integration steps.
        steps: usize,
    },
    /// The solve diverged (a NaN or infinity appeared), told in the user's terms: the
    /// inputs beyond their natural scale, largest factor first ([`crate::input_range`]),
    /// what to try, then where it went non-finite.
    #[error("{}", diverged_message(inputs, stage))]
    Diverged {
        /// Where the state went non-finite (the technical detail).
        stage: &'static str,
        /// The inputs beyond their natural scale (factor > 1), largest factor first.
        inputs: Vec<OutOfRange>,
    },
}

impl SolveError {
    /// Why the solve failed, snake_case: the [`StopReason`] of a Newton run that stopped
    /// short (its [`StopReason::as_str`]), else the kind of failure (`"non_finite"`,
    /// `"diverged"`, `"under_resolved"`, `"trajectory_steps_failed"`); Python's
    /// `ConvergenceError.reason`.
    pub fn reason(&self) -> &'static str {
        match self {
            Self::NotConverged { reason, .. } => reason.as_str(),
            Self::NonFinite { .. } => "non_finite",
            Self::Diverged { .. } => "diverged",
            Self::UnderResolved { .. } => "under_resolved",
            Self::TrajectoryStepsFailed { .. } => StopReason::TrajectoryStepsFailed.as_str(),
        }
    }
}

/// The largest drift of an integrated frame off a rotation, max |RᵀR − I|, that a
/// solution may have ([`SolveError::UnderResolved`]). The default 10 steps of the leg's
/// fifth-order method keep the reference design's legs within 1e-7 (one leg bent by
/// 150–158°: 5e-7–5e-6, with tip errors of 5e-8–2e-7 m); one tendon of the reference leg
/// at 25 N (a coil of 6.8 rad) drifts 1.2e-4 with a tip 4.9e-6 m off, at 40 N 3.1e-3
/// and 6.5e-5 m (measured against 4 000 steps, 2026-11-28). The drift grows with the
/// error but not in step with it: this bound catches a leg the steps cannot follow at
/// all, not every error above a micrometre.
pub const MAX_FRAME_DRIFT: f64 = 1e-4;

/// max |RᵀR − I|: how far `r` is from a rotation.
pub fn frame_drift(r: &nalgebra::Matrix3<f64>) -> f64 {
    (r.transpose() * r - nalgebra::Matrix3::identity())
        .abs()
        .max()
}

/// `n` and the noun, singular for one: "1 value", "2 values" (for the error messages).
pub fn counted(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// The message of [`SolveError::Diverged`].
fn diverged_message(inputs: &[OutOfRange], stage: &str) -> String {
    let mut s = String::from("the solve diverged");
    if inputs.is_empty() {
        // Nothing the caller asked for is large for this design: the design itself, or a
        // warm start, is the suspect.
        s.push_str(
            ": no actuation or load is beyond the design's natural scales, so check the \
             target pose, if any (a platform metres away), then the design's own values \
             (moduli, radii, masses, stiffnesses, lengths: one far outside its physical \
             range makes the rod equations overflow) and the warm start, if any. \
             Detail: ",
        );
    } else {
        for (k, i) in inputs.iter().enumerate() {
            s.push_str(if k == 0 { ": " } else { "; " });
            s.push_str(&i.to_string());
        }
        s.push_str(
            ". Try a smaller step: solve an input nearer the design's range first, then \
             approach the target in steps, each warm-started from the last solution \
             (CLI: --init of fk, ik, analyze and trajectory). Detail: ",
        );
    }
    s.push_str(&format!("non-finite value in {stage}"));
    s
}

/// An input of a solve measured against its natural scale in the design (e.g. q against
/// the actuation limit): the words of [`SolveError::Diverged`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct OutOfRange {
    /// The input, e.g. `q[0]` or `tensions[1]`.
    pub input: String,
    /// Its value (signed for a single number, a length for a vector), in `unit`; finite
    /// (a vector's length past f64's range is f64::MAX).
    pub value: f64,
    /// Unit of `value` and `scale`.
    pub unit: &'static str,
    /// The natural scale of the input in the design, in `unit`.
    pub scale: f64,
    /// How many times its scale the input is (|`value`| / `scale`).
    pub factor: f64,
    /// What the scale is, e.g. `the actuation limit actuation_limits.tendon_displacement`.
    pub meaning: String,
}

impl OutOfRange {
    /// `input` of value `value` against its `scale` (which `meaning` explains).
    pub fn new(input: String, value: f64, unit: &'static str, scale: f64, meaning: &str) -> Self {
        Self {
            input,
            value,
            unit,
            scale,
            // Past f64's range (1e308 against 0.1): the largest finite factor.
            factor: (value.abs() / scale).min(f64::MAX),
            meaning: meaning.to_string(),
        }
    }
}

impl fmt::Display for OutOfRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} = {} {} is {} times {} ({} {})",
            self.input,
            short_number(self.value),
            self.unit,
            if self.factor == f64::MAX {
                "more than 1e308".to_string()
            } else {
                short_number(self.factor)
            },
            self.meaning,
            short_number(self.scale),
            self.unit
        )
    }
}

/// `x` with four significant digits, trailing zeros dropped: `100`, `0.01`, `1.13e6`.
pub(crate) fn short_number(x: f64) -> String {
    let trim = |t: String| {
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        }
    };
    if x == 0.0 || !x.is_finite() {
        return x.to_string();
    }
    let exponent = x.abs().log10().floor() as i32;
    if (-3..6).contains(&exponent) {
        let decimals = (3 - exponent).max(0) as usize;
        trim(format!("{x:.decimals$}"))
    } else {
        let t = format!("{x:.3e}");
        let (mantissa, exp) = t.split_once('e').unwrap_or((&t, "0"));
        format!("{}e{exp}", trim(mantissa.to_string()))
    }
}

/// An analysis that cannot be carried out.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    /// A matrix that must be inverted is exactly singular (or its solution overflows).
    #[error("{matrix} is singular (rcond {rcond:.2e}): {undefined} do not exist here")]
    Singular {
        /// Which matrix, e.g. `[B_x B_u]`.
        matrix: &'static str,
        /// Its raw rcond.
        rcond: f64,
        /// What cannot be computed because of it.
        undefined: &'static str,
    },
    /// A block or vector does not fit the model.
    #[error("{what} is {found}: expected {expected} for this model")]
    Shape {
        /// Which input.
        what: &'static str,
        /// Its size.
        found: String,
        /// The size the model needs.
        expected: String,
    },
    /// An input holds NaN or infinity.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
}

/// A plot that could not be written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The directory or a file could not be created or written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// plotters failed to draw.
    #[error("cannot draw {name}: {message}")]
    Draw {
        /// The ellipsoid.
        name: &'static str,
        /// plotters' message.
        message: String,
    },
}

/// Any failure of a library entry point.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A design file could not be loaded.
    #[error(transparent)]
    Design(#[from] DesignError),
    /// A solve failed.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The inputs of a solve (actuation, loads, ...) break a rule; all are listed.
    #[error("invalid input:{0}")]
    Input(Violations),
    /// A kinetostatic analysis failed (an exactly singular matrix).
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
    /// A plot could not be written (feature `plots`).
    #[cfg(feature = "plots")]
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// The caller asked a long run to stop (its stop flag: a workspace sweep's
    /// [`crate::workspace::sweep_workspace_until`]); nothing of the run is returned.
    #[error("stopped on request after {done} of {total} {what}")]
    Stopped {
        /// What the run counts (`"rays"`).
        what: &'static str,
        /// Units finished.
        done: usize,
        /// Units in the run.
        total: usize,
    },
    /// An output file or directory could not be written.
    #[error("cannot write {path}: {source}")]
    Output {
        /// The file or directory.
        path: PathBuf,
        /// Underlying I/O error.
        source: std::io::Error,
    },
}

impl Error {
    /// Why it failed, snake_case: a solve's [`SolveError::reason`], else the kind of
    /// error (`"invalid_design"`, `"invalid_input"`, `"analysis_failed"`,
    /// `"output_failed"`): the reason of a failed row of a batch.
    pub fn reason(&self) -> &'static str {
        match self {
            Self::Design(_) => "invalid_design",
            Self::Solve(e) => e.reason(),
            Self::Input(_) => "invalid_input",
            Self::Analysis(_) => "analysis_failed",
            Self::Stopped { .. } => "stopped",
            #[cfg(feature = "plots")]
            Self::Plot(_) => "output_failed",
            Self::Output { .. } => "output_failed",
        }
    }
}

impl From<crate::output::WriteError> for Error {
    fn from(e: crate::output::WriteError) -> Self {
        Self::Output {
            path: e.path,
            source: e.source,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{OutOfRange, SolveError, StopReason, short_number};

    #[test]
    fn short_numbers_keep_four_significant_digits() {
        let shown: Vec<String> = [100.0, 0.01, 1.13456, 1.13456e6, 2.5e-5, 0.0]
            .iter()
            .map(|&x| short_number(x))
            .collect();
        assert_eq!(shown, ["100", "0.01", "1.135", "1.135e6", "2.5e-5", "0"]);
    }

    #[test]
    fn a_divergence_names_the_input_its_factor_what_to_try_and_the_stage() {
        let e = SolveError::Diverged {
            stage: "rod strain derivatives (eq. 5)",
            inputs: vec![OutOfRange::new(
                "q[0]".to_string(),
                1.0,
                "m",
                0.01,
                "the actuation limit",
            )],
        };
        assert_eq!(
            e.to_string(),
            "the solve diverged: q[0] = 1 m is 100 times the actuation limit (0.01 m). \
             Try a smaller step: solve an input nearer the design's range first, then \
             approach the target in steps, each warm-started from the last solution \
             (CLI: --init of fk, ik, analyze and trajectory). Detail: non-finite value in rod strain derivatives (eq. 5)"
        );
        // With no input beyond its scale the target and the design's own values are the
        // suspects, and a smaller step is no advice.
        let e = SolveError::Diverged {
            stage: "rod strain system (eq. 5)",
            inputs: Vec::new(),
        };
        let text = e.to_string();
        assert!(
            text.contains("check the target pose")
                && text.contains("the design's own values")
                && !text.contains("smaller step"),
            "{text}"
        );
    }

    #[test]
    fn long_numbers_are_written_in_exponent_form() {
        let mut v = super::Violations::default();
        v.push("alpha", 1e300, "in (0, pi/2) rad");
        v.push("leg.backbone_radius", 1e-300, "> 0 m");
        v.push("q[0]", 0.004, "finite");
        v.push("name", "a long text that is no number at all", "short");
        let text = v.to_string();
        assert!(text.contains("alpha = 1e300: expected"), "{text}");
        assert!(
            text.contains("leg.backbone_radius = 1e-300: expected"),
            "{text}"
        );
        assert!(text.contains("q[0] = 0.004: expected"), "{text}");
        assert!(
            text.contains("name = a long text that is no number at all"),
            "{text}"
        );
    }

    #[test]
    fn stop_reasons_serialize_as_their_stable_names_and_read_as_sentences() {
        for r in StopReason::ALL {
            let json = serde_json::to_string(&r).unwrap();
            assert_eq!(json, format!("\"{}\"", r.as_str()));
            let sentence = r.to_string();
            assert!(
                sentence.contains(' ') && sentence != r.as_str(),
                "{sentence}"
            );
        }
    }
}
