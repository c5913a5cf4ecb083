//! The design evaluation of the search: a coarse workspace sweep of `tdpcr` per
//! configured orientation ([`tdpcr::workspace::sweep_workspace`], MODEL.md §6), reduced to
//! the [`Measures`] of MODEL.md §7.
//!
//! Pooling over orientations: volumes are the mean over the orientations; the rcond
//! statistics, the singularity fractions, the margin and the minimum tension are taken
//! over all reachable cells of all orientations together. rcond(J_p), rcond(J_o),
//! rcond(C_p) and rcond(C_o) are those of the raw SI matrices (the paper's Tab. III; each
//! block has a single unit, so scaling does not change them); the \[B_x B_u\] measure is
//! the unit-scaled one of the analysis module.
//!
//! Infeasible: the home configuration (platform at the origin, R_ee of the orientation)
//! does not solve ([`Infeasibility::HomeNotSolved`]), or it is outside the actuation
//! limits or collides ([`Infeasibility::InvalidHome`]); any other sweep error is
//! [`Infeasibility::EvaluationFailed`].

use tdpcr::Tdpcr;
use tdpcr::error::Error;
use tdpcr::workspace::{
    PathEnd, WorkspaceMap, WorkspacePoint, WorkspaceSettings, figures::slice_figures,
    sweep_workspace,
};

use crate::config::{EvaluationConfig, FigureSweep};
use crate::evaluate::Evaluator;
use crate::objectives::{Infeasibility, MeanMin, Measures, Outcome};
use crate::report::SliceSet;
use crate::search::{SearchResult, Setup};

/// Evaluates designs by coarse workspace sweeps.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkspaceEvaluator {
    /// One sweep per orientation.
    settings: Vec<WorkspaceSettings>,
}

impl WorkspaceEvaluator {
    /// The evaluator of a (validated) evaluation config.
    pub fn new(config: &EvaluationConfig) -> Self {
        Self {
            settings: config
                .orientations
                .iter()
                .map(|&r| config.sweep_settings(r))
                .collect(),
        }
    }

    /// The sweeps of `design`, one per orientation, or why it is infeasible.
    ///
    /// # Errors
    /// The [`Infeasibility`] of the design.
    pub fn sweeps(&self, design: &Tdpcr) -> Result<Vec<WorkspaceMap>, Infeasibility> {
        self.settings
            .iter()
            .map(|s| {
                let map = sweep_workspace(design, s).map_err(|e| match e {
                    Error::Solve(e) => Infeasibility::HomeNotSolved {
                        message: e.to_string(),
                    },
                    e => Infeasibility::EvaluationFailed {
                        message: e.to_string(),
                    },
                })?;
                if map.summary.path_ends.contains(&PathEnd::InvalidHome) || map.summary.counts.reachable == 0 {
                    return Err(Infeasibility::InvalidHome {
                        message: format!(
                            "at R_ee = rotvec {:?} the home configuration is outside the actuation limits or collides",
                            s.rotvec
                        ),
                    });
                }
                Ok(map)
            })
            .collect()
    }
}

impl Evaluator for WorkspaceEvaluator {
    fn evaluate(&self, design: &Tdpcr) -> Outcome {
        match self.sweeps(design) {
            Ok(maps) => Outcome::Feasible(measures(&maps)),
            Err(reason) => Outcome::Infeasible { reason },
        }
    }
}

/// Mean and minimum of `values` (0, 0 when empty).
fn mean_min(values: impl Iterator<Item = f64>) -> MeanMin {
    let (n, sum, min) = values.fold((0usize, 0.0, f64::INFINITY), |(n, s, m), x| {
        (n + 1, s + x, m.min(x))
    });
    if n == 0 {
        MeanMin::default()
    } else {
        MeanMin {
            mean: sum / n as f64,
            min,
        }
    }
}

/// The measures of the sweeps of one design (pooled as in the module documentation).
pub fn measures(maps: &[WorkspaceMap]) -> Measures {
    let reachable: Vec<&WorkspacePoint> = maps
        .iter()
        .flat_map(|m| m.points.iter().filter(|p| p.reachable()))
        .collect();
    let n = reachable.len();
    let fraction = |f: &dyn Fn(&WorkspacePoint) -> bool| {
        if n == 0 {
            0.0
        } else {
            reachable.iter().filter(|p| f(p)).count() as f64 / n as f64
        }
    };
    let mean_over_maps = |f: &dyn Fn(&WorkspaceMap) -> f64| {
        if maps.is_empty() {
            0.0
        } else {
            maps.iter().map(f).sum::<f64>() / maps.len() as f64
        }
    };
    let rcond = |f: fn(&WorkspacePoint) -> f64| mean_min(reachable.iter().map(|p| f(p)));
    let scaled_b_xu = rcond(|p| p.metrics.rcond_scaled.b_xu);
    let non_singular_cells = maps.iter().map(|m| m.summary.counts.non_singular).sum();
    Measures {
        volume_non_singular: mean_over_maps(&|m| m.summary.volume.non_singular),
        volume_reachable: mean_over_maps(&|m| m.summary.volume.reachable),
        reachable_cells: n,
        non_singular_cells,
        rcond_j_p: rcond(|p| p.metrics.rcond.j_p),
        rcond_j_o: rcond(|p| p.metrics.rcond.j_o),
        rcond_c_p: rcond(|p| p.metrics.rcond.c_p),
        rcond_c_o: rcond(|p| p.metrics.rcond.c_o),
        near_type_i_fraction: fraction(&|p| p.metrics.singularity.type_i),
        near_type_ii_fraction: fraction(&|p| p.metrics.singularity.type_ii),
        near_leg_fraction: fraction(&|p| p.metrics.singularity.leg),
        min_scaled_rcond_b_xu: scaled_b_xu.min,
        mean_scaled_rcond_b_xu: scaled_b_xu.mean,
        min_tension: if n == 0 {
            0.0
        } else {
            reachable
                .iter()
                .map(|p| p.metrics.min_tension)
                .fold(f64::INFINITY, f64::min)
        },
        singularity_margin: if n == 0 {
            0.0
        } else {
            non_singular_cells as f64 / n as f64
        },
    }
}

/// The slice figures of `design` (the workspace module's: reachable/Type II/collision,
/// rcond and tension maps at z = −0.06, 0, 0.06 m) from one sweep at the resolution of
/// `figures` (default: the evaluation's) for the first orientation, in `dir`.
///
/// # Errors
/// The design's [`Infeasibility`] (no figures then).
pub fn slice_set(
    design: &Tdpcr,
    config: &EvaluationConfig,
    figures: Option<&FigureSweep>,
    label: &str,
    dir: &str,
) -> Result<SliceSet, Infeasibility> {
    let first = config.orientations.first().copied().unwrap_or_default();
    let mut settings = config.sweep_settings(first);
    if let Some(f) = figures {
        settings.step = f.step;
        settings.angle_step = f.angle_step;
    }
    let map = WorkspaceEvaluator {
        settings: vec![settings],
    }
    .sweeps(design)?
    .remove(0);
    Ok(SliceSet {
        label: label.to_string(),
        dir: dir.to_string(),
        files: slice_figures(&map),
        measures: Some(measures(std::slice::from_ref(&map))),
    })
}

/// Slice figures of the reference and the best composite design of `result` (one sweep
/// each, at the figures' resolution), and the report's note on them; `progress` gets a
/// line before each sweep and for each design without figures.
pub fn slice_sets(
    setup: &Setup,
    result: &SearchResult,
    progress: &dyn Fn(&str),
) -> (Vec<SliceSet>, Option<String>) {
    let eval = &setup.config.evaluation;
    let figures = setup.config.figures.as_ref();
    let mut designs = vec![("reference", "slices/reference", setup.space.base().clone())];
    if let Some(best) = result.best_composite()
        && let Ok(d) = setup.space.design(&best.x)
    {
        designs.push(("best composite", "slices/best_composite", d));
    }
    let mut out = Vec::new();
    for (label, dir, design) in designs {
        progress(&format!("slice figures: sweeping the {label} design ..."));
        match slice_set(&design, eval, figures, label, dir) {
            Ok(s) => out.push(s),
            Err(reason) => progress(&format!("no slice figures of the {label} design: {reason}")),
        }
    }
    let (step, angle) = figures.map_or((eval.step, eval.angle_step), |f| (f.step, f.angle_step));
    let note = format!(
        "From one sweep per design at Δ = {} mm, φ = {angle} rad, R_ee = rotvec {:?} (grey reachable, red near Type II, blue collision).",
        step * 1e3,
        eval.orientations.first().copied().unwrap_or_default()
    );
    (out, Some(note))
}
