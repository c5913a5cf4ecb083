//! The search configuration (RON, SI units, angles in radians), e.g. `optim/default.ron`.
//!
//! ```ron
//! OptimConfig(
//!     base_design: "../designs/lilge2022.ron",      // relative to this file; the reference
//!     parameters: [Bounds(parameter: Alpha, min: 0.35, max: 1.2), /* ... */],
//!     evaluation: Evaluation(step: 0.012, angle_step: 0.25, z_range: (-0.12, 0.12),
//!                            orientations: [(0.0, 0.0, 0.0)]),
//!     objectives: [Weighted(objective: WorkspaceVolume, weight: 1.0), /* ... */],
//!     budget: Budget(evaluations: Some(2000), wall_time_s: Some(1800.0)),
//!     seed: 1,
//! )
//! ```
//!
//! Unknown fields are rejected; [`OptimConfig::validate`] lists every broken rule with
//! its field, value and rule; malformed RON is reported as `file:line:column`.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use tdpcr::error::{DesignError, Error, Violation, Violations};
use tdpcr::workspace::{CollisionPolicy, WorkspaceSettings};

use crate::objectives::Objective;
use crate::space::{Bounds, ParameterSpace};

/// Default initial CMA-ES step size σ₀ (fraction of each parameter's range).
pub const DEFAULT_INITIAL_STEP: f64 = 0.25;

/// Largest CMA-ES population λ accepted: far beyond the tens to hundreds a search over a
/// few parameters uses (10 000 000 000 tried to allocate 40 GB before the first
/// evaluation).
pub const MAX_POPULATION: usize = 10_000;

/// The whole search configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OptimConfig {
    /// The base design file (a `Tdpcr(...)` RON file), relative to the config file's
    /// directory. Parameters not listed in `parameters` keep its values; it is also the
    /// reference every result is compared with.
    pub base_design: PathBuf,
    /// The varying parameters with their bounds (parameter units: rad, m, N).
    pub parameters: Vec<Bounds>,
    /// How a design is evaluated (a coarse workspace sweep per orientation).
    pub evaluation: EvaluationConfig,
    /// The weighted composite objective that drives CMA-ES.
    pub objectives: Vec<Weighted>,
    /// Optional: how the weighted terms combine (default [`Aggregation::Sum`]).
    #[serde(default)]
    pub aggregation: Aggregation,
    /// When to stop.
    pub budget: Budget,
    /// Seed of the optimizer's random numbers.
    pub seed: u64,
    /// Optional CMA-ES population size λ (default 4 + ⌊3 ln n⌋ for n parameters).
    #[serde(default)]
    pub population: Option<usize>,
    /// Optional initial CMA-ES step size σ₀ as a fraction of each parameter's range, in
    /// (0, 1] (default [`DEFAULT_INITIAL_STEP`]). The search starts at the base design's
    /// parameters (clamped into the bounds).
    #[serde(default = "default_initial_step")]
    pub initial_step: f64,
    /// Optional resolution of the workspace sweeps behind the report's slice figures
    /// (reference and best design; default: the evaluation's resolution).
    #[serde(default)]
    pub figures: Option<FigureSweep>,
}

fn default_initial_step() -> f64 {
    DEFAULT_INITIAL_STEP
}

/// Workspace evaluation settings (MODEL.md §6) shared by every design of the search.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename = "Evaluation")]
pub struct EvaluationConfig {
    /// Grid step Δ \[m\] (coarse: 8–15 mm keeps one evaluation at seconds).
    pub step: f64,
    /// Angle φ between rays \[rad\].
    pub angle_step: f64,
    /// Lowest and highest plane z \[m\] (must cover the candidates' workspaces).
    pub z_range: (f64, f64),
    /// Platform orientations R_ee as rotation vectors (axis × angle) \[rad\], world frame;
    /// each gets its own sweep and the measures pool them.
    pub orientations: Vec<(f64, f64, f64)>,
    /// Optional Newton iterations allowed per IK step of the sweep (default
    /// [`DEFAULT_MAX_ITERATIONS`]).
    #[serde(default = "default_max_iterations")]
    pub max_iterations: usize,
    /// Optional Newton tolerance ε_b on ‖b‖₂ (SI) of every IK step (default 1e-10).
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Optional chord contraction of the sweep's Newton runs, in \[0, 1)
    /// ([`WorkspaceSettings::chord_contraction`]; default 0.1, the library's, so a config
    /// without it evaluates as before). The default config takes 0.5: about 6 % less work
    /// per evaluation at Δ = 12 mm; a few cells at folds and Type II singularities move.
    #[serde(default = "default_chord_contraction")]
    pub chord_contraction: f64,
    /// Optional iterations of a sweep step's Newton run before it must have reduced ‖b‖
    /// tenfold to go on, ≥ 1 ([`WorkspaceSettings::probe_iterations`]; default 15, the
    /// library's, so a config without it evaluates as before). The default config takes
    /// 8: ray steps past a fold end sooner; all 26 feasible candidates of 30 drawn kept
    /// their cells.
    #[serde(default = "default_probe_iterations")]
    pub probe_iterations: usize,
}

/// Default Newton iterations per sweep step of an evaluation.
pub const DEFAULT_MAX_ITERATIONS: usize = 30;

fn default_max_iterations() -> usize {
    DEFAULT_MAX_ITERATIONS
}

fn default_tolerance() -> f64 {
    1e-10
}

fn default_chord_contraction() -> f64 {
    WorkspaceSettings::default().chord_contraction
}

fn default_probe_iterations() -> usize {
    WorkspaceSettings::default().probe_iterations
}

/// How the terms of the composite combine; r_k = v_k / v_k(reference) (see
/// [`crate::objectives`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Aggregation {
    /// Weighted mean Σ w_k r_k / Σ w_k: trades one objective against another.
    #[default]
    Sum,
    /// Weighted minimum min_k r_k^(w_k / max w) over the terms with w_k > 0, plus 1e-3 ×
    /// (weighted mean − 1) to break ties: the worst ratio to the reference counts (with
    /// equal weights, c > 1 means about "better than the reference on every term"), so the
    /// search is driven towards designs that dominate the reference.
    Min,
}

/// One term of the composite objective.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Weighted {
    /// The measure.
    pub objective: Objective,
    /// Its weight, ≥ 0 (the weights need not sum to 1).
    pub weight: f64,
}

/// When to stop the search (whichever comes first; at least one must be given).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Budget {
    /// Candidate evaluations (the reference's evaluation is not counted).
    #[serde(default)]
    pub evaluations: Option<usize>,
    /// Wall time of this invocation \[s\]: no evaluation starts after it (a resumed run
    /// gets the full time again).
    #[serde(default)]
    pub wall_time_s: Option<f64>,
}

/// Resolution of the sweeps behind the report's figures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FigureSweep {
    /// Grid step Δ \[m\].
    pub step: f64,
    /// Angle φ between rays \[rad\].
    pub angle_step: f64,
}

impl OptimConfig {
    /// Loads and validates a config file.
    ///
    /// # Errors
    /// [`DesignError::Io`], [`DesignError::Parse`] (`file:line:column`), or
    /// [`DesignError::Invalid`] listing every broken rule.
    pub fn from_ron_file(path: impl AsRef<Path>) -> Result<Self, DesignError> {
        let path = path.as_ref();
        let config = Self::parse_ron_file(path)?;
        config.validate(&path.display().to_string())?;
        Ok(config)
    }

    /// Reads and parses a config file without checking the values (for callers that
    /// change some before [`OptimConfig::validate`]).
    ///
    /// # Errors
    /// [`DesignError::Io`], [`DesignError::Parse`].
    pub fn parse_ron_file(path: &Path) -> Result<Self, DesignError> {
        let text = tdpcr::design::read_text_at_most(
            path,
            tdpcr::design::MAX_DESIGN_FILE_BYTES,
            "a search configuration",
        )
        .map_err(|source| DesignError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse_ron_str(&text, path)
    }

    /// Parses and validates RON text (`path` names it in errors).
    ///
    /// # Errors
    /// As [`OptimConfig::from_ron_file`].
    pub fn from_ron_str(text: &str, path: &Path) -> Result<Self, DesignError> {
        let config = Self::parse_ron_str(text, path)?;
        config.validate(&path.display().to_string())?;
        Ok(config)
    }

    fn parse_ron_str(text: &str, path: &Path) -> Result<Self, DesignError> {
        ron::de::from_str(text).map_err(|e| DesignError::Parse {
            path: path.to_path_buf(),
            line: e.span.start.line,
            column: e.span.start.col,
            message: e.code.to_string(),
        })
    }

    /// The config as RON text (loads back with [`OptimConfig::from_ron_str`]).
    pub fn to_ron_string(&self) -> String {
        let pretty = ron::ser::PrettyConfig::new().struct_names(true);
        ron::ser::to_string_pretty(self, pretty).expect("config structs always serialize")
    }

    /// Checks every rule that needs no other file; all violations are reported together
    /// (`source` names the config in the message).
    ///
    /// # Errors
    /// [`DesignError::Invalid`].
    pub fn validate(&self, source: &str) -> Result<(), DesignError> {
        let mut v = Violations::default();
        self.check(None, &mut v);
        v.into_result(source)
    }

    /// Appends every broken rule to `v`; with the base design, also the rules that
    /// depend on it (a tendon offset must fit inside the disks).
    pub fn check(&self, base: Option<&tdpcr::Tdpcr>, v: &mut Violations) {
        if self.base_design.as_os_str().is_empty() {
            v.push("base_design", "\"\"", "a design file path");
        }
        ParameterSpace::check_bounds(&self.parameters, base, "parameters", v);
        self.evaluation.check(v);
        if self.objectives.is_empty() {
            v.push("objectives", "[]", "at least one weighted objective");
        }
        for (i, w) in self.objectives.iter().enumerate() {
            if self.objectives[..i]
                .iter()
                .any(|o| o.objective == w.objective)
            {
                v.push(
                    format!("objectives[{i}].objective"),
                    format!("{:?}", w.objective),
                    "each objective at most once",
                );
            }
            if !(w.weight.is_finite() && w.weight >= 0.0) {
                v.push(format!("objectives[{i}].weight"), w.weight, ">= 0");
            }
        }
        if !self.objectives.is_empty() && !self.objectives.iter().any(|w| w.weight > 0.0) {
            let weights: Vec<f64> = self.objectives.iter().map(|w| w.weight).collect();
            v.push(
                "objectives",
                format!("weights {weights:?}"),
                "at least one weight > 0",
            );
        }
        let b = &self.budget;
        if b.evaluations.is_none() && b.wall_time_s.is_none() {
            v.push(
                "budget",
                "no limit",
                "evaluations: Some(N) and/or wall_time_s: Some(SECONDS)",
            );
        }
        if b.evaluations == Some(0) {
            v.push("budget.evaluations", 0, ">= 1");
        }
        if let Some(t) = b.wall_time_s
            && !(t.is_finite() && t > 0.0)
        {
            v.push("budget.wall_time_s", t, "> 0 s");
        }
        if let Some(p) = self.population
            && !(2..=MAX_POPULATION).contains(&p)
        {
            v.push("population", p, &format!("in 2..={MAX_POPULATION}"));
        }
        if !(self.initial_step > 0.0 && self.initial_step <= 1.0) {
            v.push(
                "initial_step",
                self.initial_step,
                "in (0, 1] (fraction of each range)",
            );
        }
        if let Some(f) = &self.figures {
            let mut settings = self.evaluation.sweep_settings((0.0, 0.0, 0.0));
            settings.step = f.step;
            settings.angle_step = f.angle_step;
            push_sweep_violations(v, &settings, |field| {
                ["step", "angle_step"]
                    .contains(&field)
                    .then(|| format!("figures.{field}"))
            });
        }
    }

    /// The base design's path: `base_design` relative to the directory of `config_path`.
    pub fn base_design_path(&self, config_path: &Path) -> PathBuf {
        config_path
            .parent()
            .unwrap_or(Path::new("."))
            .join(&self.base_design)
    }

    /// The CMA-ES population size λ (configured, or 4 + ⌊3 ln n⌋).
    pub fn population_size(&self) -> usize {
        self.population
            .unwrap_or_else(|| crate::cmaes::default_population(self.parameters.len()))
    }
}

impl EvaluationConfig {
    /// The library's sweep settings for the orientation `rotvec` \[rad\] (collisions end
    /// rays, default singularity thresholds).
    pub fn sweep_settings(&self, rotvec: (f64, f64, f64)) -> WorkspaceSettings {
        WorkspaceSettings {
            rotvec: [rotvec.0, rotvec.1, rotvec.2],
            step: self.step,
            angle_step: self.angle_step,
            z_range: [self.z_range.0, self.z_range.1],
            collisions: CollisionPolicy::Stop,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            chord_contraction: self.chord_contraction,
            probe_iterations: self.probe_iterations,
            ..WorkspaceSettings::default()
        }
    }

    /// The rules of the library's sweep settings ([`WorkspaceSettings::validate`]), with
    /// the fields renamed as in this file.
    fn check(&self, v: &mut Violations) {
        if self.orientations.is_empty() {
            v.push(
                "evaluation.orientations",
                "[]",
                "at least one rotation vector",
            );
        }
        let first = self.orientations.first().copied().unwrap_or_default();
        push_sweep_violations(v, &self.sweep_settings(first), |field| {
            Some(match field {
                "rotvec" => "evaluation.orientations[0]".to_string(),
                _ => format!("evaluation.{field}"),
            })
        });
        for (i, &r) in self.orientations.iter().enumerate().skip(1) {
            push_sweep_violations(v, &self.sweep_settings(r), |field| {
                (field == "rotvec").then(|| format!("evaluation.orientations[{i}]"))
            });
        }
    }
}

/// Appends the violations of `settings.validate()` whose field `rename` maps to a name
/// of this file (the others are dropped).
fn push_sweep_violations(
    v: &mut Violations,
    settings: &WorkspaceSettings,
    rename: impl Fn(&str) -> Option<String>,
) {
    if let Err(Error::Input(list)) = settings.validate() {
        for x in list.0 {
            if let Some(field) = rename(&x.field) {
                v.0.push(Violation { field, ..x });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEFAULT: &str = include_str!("../default.ron");

    #[test]
    fn the_default_config_loads_and_round_trips() {
        let c = OptimConfig::from_ron_str(DEFAULT, Path::new("default.ron")).unwrap();
        let again = OptimConfig::from_ron_str(&c.to_ron_string(), Path::new("again")).unwrap();
        assert_eq!(c, again);
        assert_eq!(c.population_size(), c.population.unwrap_or(9));
    }

    /// A rotation vector whose length overflows, a population that would not fit in
    /// memory and a bound range that overflows are refused up front (they ran: every
    /// evaluation failed, the run aborted on allocation, every value became infinite).
    #[test]
    fn overflowing_orientations_populations_and_ranges_are_refused() {
        let text = r#"OptimConfig(
            base_design: "../designs/lilge2022.ron",
            parameters: [Bounds(parameter: Beta, min: -1e308, max: 1e308)],
            evaluation: Evaluation(step: 0.03, angle_step: 0.8, z_range: (-0.1, 0.1),
                                   orientations: [(0.0, 0.0, 0.0), (1e200, 0.0, 0.0)]),
            objectives: [Weighted(objective: WorkspaceVolume, weight: 1.0)],
            budget: Budget(evaluations: Some(6)),
            seed: 1,
            population: Some(10000000000),
        )"#;
        let err = OptimConfig::from_ron_str(text, Path::new("bad.ron"))
            .unwrap_err()
            .to_string();
        for part in [
            "parameters[0].max = 1e308: expected a finite range",
            "evaluation.orientations[1] = [1e200, 0.0, 0.0]: expected finite numbers of length <= 1000 rad",
            "population = 10000000000: expected in 2..=10000",
        ] {
            assert!(err.contains(part), "missing '{part}' in: {err}");
        }
    }

    #[test]
    fn every_bad_field_is_listed_with_value_and_rule() {
        let text = r#"OptimConfig(
            base_design: "",
            parameters: [Bounds(parameter: Pretension, min: -1.0, max: 2.0)],
            evaluation: Evaluation(step: 0.0, angle_step: 4.0, z_range: (0.1, -0.1),
                                   orientations: [], max_iterations: 0,
                                   chord_contraction: 1.5, probe_iterations: 0),
            objectives: [Weighted(objective: WorkspaceVolume, weight: -1.0),
                         Weighted(objective: WorkspaceVolume, weight: 0.0)],
            budget: Budget(),
            seed: 1,
            population: Some(1),
            initial_step: 0.0,
        )"#;
        let err = OptimConfig::from_ron_str(text, Path::new("bad.ron")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "invalid bad.ron (15 problems):
  - base_design = \"\": expected a design file path
  - parameters[0].min = -1: expected in [0, 1e6] N (a design's largest pretension) (pretension)
  - evaluation.orientations = []: expected at least one rotation vector
  - evaluation.step = 0: expected in [1e-5, 1] m
  - evaluation.angle_step = 4: expected in [1e-4, pi] rad
  - evaluation.z_range = 0.1,-0.1: expected two finite numbers ZMIN <= ZMAX [m]
  - evaluation.max_iterations = 0: expected >= 1
  - evaluation.chord_contraction = 1.5: expected in [0, 1)
  - evaluation.probe_iterations = 0: expected >= 1
  - objectives[0].weight = -1: expected >= 0
  - objectives[1].objective = WorkspaceVolume: expected each objective at most once
  - objectives = weights [-1.0, 0.0]: expected at least one weight > 0
  - budget = no limit: expected evaluations: Some(N) and/or wall_time_s: Some(SECONDS)
  - population = 1: expected in 2..=10000
  - initial_step = 0: expected in (0, 1] (fraction of each range)"
        );
    }

    #[test]
    fn malformed_ron_and_unknown_fields_give_file_line_column() {
        let err = OptimConfig::from_ron_str(
            "OptimConfig(\n  seed: 1,\n  colour: 3,\n)",
            Path::new("x.ron"),
        )
        .unwrap_err()
        .to_string();
        assert!(err.starts_with("x.ron:3:"), "{err}");
        assert!(err.contains("colour"), "{err}");
        let err = OptimConfig::from_ron_str("OptimConfig(\n  seed: ,\n)", Path::new("y.ron"))
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("y.ron:2:"), "{err}");
    }
}
