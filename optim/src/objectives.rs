//! What an evaluation measures (MODEL.md §7), the three Pareto objectives, the weighted
//! composite that drives CMA-ES, and how infeasible designs rank.
//!
//! **Pareto objectives** (all maximized): [`Objective::WorkspaceVolume`] (volume of the
//! valid, non-singular cells), [`Objective::MeanRcondJp`] (isotropy of the positional
//! Jacobian) and [`Objective::SingularityMargin`] (see [`Measures::singularity_margin`]).
//!
//! **Composite.** With r_k = v_k / s_k for each configured term, where v_k is the measure
//! of the design and s_k the same measure of the reference (base) design, or 1 when the
//! reference's value is not positive (e.g. a minimum tension of 0 N, or an infeasible
//! reference): c = Σ_k w_k r_k / Σ_k w_k ([`Aggregation::Sum`]), or
//! c = min_k r_k^(w_k / max w) over the terms with w_k > 0 ([`Aggregation::Min`]). So
//! c = 1 for the reference; c = 1.2 means "20 % better on the weighted average" (Sum) or
//! "at least 20 % better on every term" (Min, equal weights). All measures are ≥ 0,
//! hence c ≥ 0. CMA-ES minimizes the
//! fitness −c; an infeasible design gets the fitness [`Infeasibility::severity`] (≥ 1),
//! which ranks it below every feasible design, and ranks the reasons among themselves
//! (a design that solves at home but collides there beats one whose geometry is
//! invalid).

use serde::{Deserialize, Serialize};

use crate::config::{Aggregation, Weighted};

/// Mean and minimum of a measure over the reachable cells.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct MeanMin {
    /// Mean.
    pub mean: f64,
    /// Minimum.
    pub min: f64,
}

/// The measures of one feasible design, pooled over the evaluation's orientations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct Measures {
    /// Volume of the reachable cells that are not near any singularity (count × Δ³,
    /// mean over orientations) \[m³\]. Pareto objective.
    pub volume_non_singular: f64,
    /// Volume of all reachable cells (mean over orientations) \[m³\].
    pub volume_reachable: f64,
    /// Reachable cells (sum over orientations).
    pub reachable_cells: usize,
    /// Reachable cells clear of every singularity (sum over orientations).
    pub non_singular_cells: usize,
    /// rcond(J_p) over the reachable cells (paper Tab. III). The mean is a Pareto
    /// objective.
    pub rcond_j_p: MeanMin,
    /// rcond(J_o).
    pub rcond_j_o: MeanMin,
    /// rcond(C_p).
    pub rcond_c_p: MeanMin,
    /// rcond(C_o).
    pub rcond_c_o: MeanMin,
    /// Fraction of reachable cells near a Type I singularity.
    pub near_type_i_fraction: f64,
    /// Fraction near a Type II singularity.
    pub near_type_ii_fraction: f64,
    /// Fraction near a leg singularity.
    pub near_leg_fraction: f64,
    /// Minimum over the reachable cells of the unit-scaled rcond(\[B_x B_u\]).
    pub min_scaled_rcond_b_xu: f64,
    /// Mean over the reachable cells of the unit-scaled rcond(\[B_x B_u\]).
    pub mean_scaled_rcond_b_xu: f64,
    /// Minimum tendon tension over the reachable cells \[N\].
    pub min_tension: f64,
    /// The singularity margin, Pareto objective: the fraction of the reachable cells that
    /// are clear of Type I, Type II and leg singularities (none of the three flags of
    /// MODEL.md §4 raised at the cell's solved configuration), in \[0, 1\].
    ///
    /// One scalar for the front, chosen over the other two sub-measures: the minimum
    /// scaled rcond(\[B_x B_u\]) is a worst case set by the cells where rays end next to
    /// a singularity (it measures the boundary, not the bulk, of the workspace), and the
    /// minimum tendon tension is 0 N whenever a tendon pair has one slack tendon
    /// somewhere (always, without pretension).
    pub singularity_margin: f64,
}

impl Measures {
    /// The three Pareto objectives (volume \[m³\], mean rcond(J_p), singularity margin).
    pub fn pareto(&self) -> [f64; 3] {
        PARETO_OBJECTIVES.map(|o| o.value(self))
    }

    /// The name of the first non-finite measure, if any.
    pub fn non_finite(&self) -> Option<&'static str> {
        Objective::ALL
            .iter()
            .find(|o| !o.value(self).is_finite())
            .map(|o| o.name())
    }
}

/// A measure usable as an objective (all maximized).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Objective {
    /// [`Measures::volume_non_singular`] \[m³\].
    WorkspaceVolume,
    /// [`Measures::volume_reachable`] \[m³\].
    ReachableVolume,
    /// Mean rcond(J_p).
    MeanRcondJp,
    /// Minimum rcond(J_p).
    MinRcondJp,
    /// Mean rcond(J_o).
    MeanRcondJo,
    /// Minimum rcond(J_o).
    MinRcondJo,
    /// Mean rcond(C_p).
    MeanRcondCp,
    /// Minimum rcond(C_p).
    MinRcondCp,
    /// Mean rcond(C_o).
    MeanRcondCo,
    /// Minimum rcond(C_o).
    MinRcondCo,
    /// [`Measures::singularity_margin`] (fraction of cells clear of singularities).
    SingularityMargin,
    /// [`Measures::min_scaled_rcond_b_xu`].
    MinScaledRcondBxu,
    /// [`Measures::min_tension`] \[N\].
    MinTension,
}

/// The three objectives of the Pareto front, in this order.
pub const PARETO_OBJECTIVES: [Objective; 3] = [
    Objective::WorkspaceVolume,
    Objective::MeanRcondJp,
    Objective::SingularityMargin,
];

impl Objective {
    /// Every objective, in the order of the report.
    pub const ALL: [Self; 13] = [
        Self::WorkspaceVolume,
        Self::ReachableVolume,
        Self::MeanRcondJp,
        Self::MinRcondJp,
        Self::MeanRcondJo,
        Self::MinRcondJo,
        Self::MeanRcondCp,
        Self::MinRcondCp,
        Self::MeanRcondCo,
        Self::MinRcondCo,
        Self::SingularityMargin,
        Self::MinScaledRcondBxu,
        Self::MinTension,
    ];

    /// The measure's value in `m`.
    pub fn value(self, m: &Measures) -> f64 {
        match self {
            Self::WorkspaceVolume => m.volume_non_singular,
            Self::ReachableVolume => m.volume_reachable,
            Self::MeanRcondJp => m.rcond_j_p.mean,
            Self::MinRcondJp => m.rcond_j_p.min,
            Self::MeanRcondJo => m.rcond_j_o.mean,
            Self::MinRcondJo => m.rcond_j_o.min,
            Self::MeanRcondCp => m.rcond_c_p.mean,
            Self::MinRcondCp => m.rcond_c_p.min,
            Self::MeanRcondCo => m.rcond_c_o.mean,
            Self::MinRcondCo => m.rcond_c_o.min,
            Self::SingularityMargin => m.singularity_margin,
            Self::MinScaledRcondBxu => m.min_scaled_rcond_b_xu,
            Self::MinTension => m.min_tension,
        }
    }

    /// Column name in `pareto.csv` and the log (`workspace_volume`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Self::WorkspaceVolume => "workspace_volume",
            Self::ReachableVolume => "reachable_volume",
            Self::MeanRcondJp => "mean_rcond_j_p",
            Self::MinRcondJp => "min_rcond_j_p",
            Self::MeanRcondJo => "mean_rcond_j_o",
            Self::MinRcondJo => "min_rcond_j_o",
            Self::MeanRcondCp => "mean_rcond_c_p",
            Self::MinRcondCp => "min_rcond_c_p",
            Self::MeanRcondCo => "mean_rcond_c_o",
            Self::MinRcondCo => "min_rcond_c_o",
            Self::SingularityMargin => "singularity_margin",
            Self::MinScaledRcondBxu => "min_scaled_rcond_b_xu",
            Self::MinTension => "min_tension",
        }
    }

    /// Human label with unit, for the report and figures.
    pub fn label(self) -> &'static str {
        match self {
            Self::WorkspaceVolume => "non-singular workspace volume [cm³]",
            Self::ReachableVolume => "reachable workspace volume [cm³]",
            Self::MeanRcondJp => "mean rcond(J_p)",
            Self::MinRcondJp => "min rcond(J_p)",
            Self::MeanRcondJo => "mean rcond(J_o)",
            Self::MinRcondJo => "min rcond(J_o)",
            Self::MeanRcondCp => "mean rcond(C_p)",
            Self::MinRcondCp => "min rcond(C_p)",
            Self::MeanRcondCo => "mean rcond(C_o)",
            Self::MinRcondCo => "min rcond(C_o)",
            Self::SingularityMargin => "singularity margin (fraction clear)",
            Self::MinScaledRcondBxu => "min scaled rcond([B_x B_u])",
            Self::MinTension => "min tendon tension [N]",
        }
    }

    /// Factor from the SI value to the unit of [`Objective::label`] (m³ → cm³).
    pub fn display_factor(self) -> f64 {
        match self {
            Self::WorkspaceVolume | Self::ReachableVolume => 1e6,
            _ => 1.0,
        }
    }
}

/// Why a design could not be scored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Infeasibility {
    /// The parameter combination breaks a design rule.
    InvalidDesign {
        /// The broken rules.
        message: String,
    },
    /// The home configuration (platform at the origin) has no IK solution the solver
    /// finds, e.g. the legs cannot reach.
    HomeNotSolved {
        /// The solver's message.
        message: String,
    },
    /// The home configuration solves but is invalid (outside the actuation limits or
    /// colliding).
    InvalidHome {
        /// What is wrong (per orientation).
        message: String,
    },
    /// The evaluation failed in another way (an error of the sweep).
    EvaluationFailed {
        /// The error.
        message: String,
    },
    /// A measure came out NaN or infinite.
    NonFinite {
        /// The measure.
        measure: String,
    },
}

impl Infeasibility {
    /// Penalty fitness (≥ 1, above every feasible fitness ≤ 0): 1 invalid home,
    /// 2 home not solved or evaluation failed, 3 non-finite measures, 4 invalid design.
    pub fn severity(&self) -> f64 {
        match self {
            Self::InvalidHome { .. } => 1.0,
            Self::HomeNotSolved { .. } | Self::EvaluationFailed { .. } => 2.0,
            Self::NonFinite { .. } => 3.0,
            Self::InvalidDesign { .. } => 4.0,
        }
    }

    /// Short category name (`invalid_design`, ...).
    pub fn kind(&self) -> &'static str {
        match self {
            Self::InvalidDesign { .. } => "invalid_design",
            Self::HomeNotSolved { .. } => "home_not_solved",
            Self::InvalidHome { .. } => "invalid_home",
            Self::EvaluationFailed { .. } => "evaluation_failed",
            Self::NonFinite { .. } => "non_finite",
        }
    }
}

impl std::fmt::Display for Infeasibility {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::InvalidDesign { message } => write!(f, "invalid design: {message}"),
            Self::HomeNotSolved { message } => {
                write!(f, "home configuration does not solve: {message}")
            }
            Self::InvalidHome { message } => write!(f, "home configuration invalid: {message}"),
            Self::EvaluationFailed { message } => write!(f, "evaluation failed: {message}"),
            Self::NonFinite { measure } => write!(f, "non-finite measure {measure}"),
        }
    }
}

/// The result of evaluating one design.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum Outcome {
    /// Scored.
    Feasible(Measures),
    /// Not scored, with the reason.
    Infeasible {
        /// Why.
        reason: Infeasibility,
    },
}

impl Outcome {
    /// A feasible outcome, or [`Infeasibility::NonFinite`] if a measure is not finite.
    pub fn checked(measures: Measures) -> Self {
        match measures.non_finite() {
            None => Self::Feasible(measures),
            Some(name) => Self::Infeasible {
                reason: Infeasibility::NonFinite {
                    measure: name.to_string(),
                },
            },
        }
    }

    /// The measures when feasible.
    pub fn measures(&self) -> Option<&Measures> {
        match self {
            Self::Feasible(m) => Some(m),
            Self::Infeasible { .. } => None,
        }
    }
}

/// Weight of the weighted mean in the [`Aggregation::Min`] composite: it breaks ties
/// between designs with the same worst ratio, e.g. when a term saturates (a singularity
/// margin of 1), which would otherwise leave CMA-ES without a direction.
pub const MIN_TIE_BREAK: f64 = 1e-3;

/// The weighted composite objective, normalized by the reference's measures.
#[derive(Debug, Clone, PartialEq)]
pub struct Composite {
    /// (objective, weight, scale s_k).
    terms: Vec<(Objective, f64, f64)>,
    aggregation: Aggregation,
}

impl Composite {
    /// The composite of `weights`, each measure divided by the reference's value (or 1
    /// when that is not positive or the reference is infeasible).
    pub fn new(
        weights: &[Weighted],
        aggregation: Aggregation,
        reference: Option<&Measures>,
    ) -> Self {
        let terms = weights
            .iter()
            .map(|w| {
                let r = reference.map_or(0.0, |m| w.objective.value(m));
                let scale = if r.is_finite() && r > 0.0 { r } else { 1.0 };
                (w.objective, w.weight, scale)
            })
            .collect();
        Self { terms, aggregation }
    }

    /// (objective, weight, scale) of each term.
    pub fn terms(&self) -> &[(Objective, f64, f64)] {
        &self.terms
    }

    /// How the terms combine.
    pub fn aggregation(&self) -> Aggregation {
        self.aggregation
    }

    /// c (≥ 0; 1 for the reference), see the module documentation.
    pub fn value(&self, m: &Measures) -> f64 {
        let ratios: Vec<(f64, f64)> = self
            .terms
            .iter()
            .map(|&(o, w, s)| (w, o.value(m) / s))
            .collect();
        let total: f64 = self.terms.iter().map(|t| t.1).sum();
        let mean = ratios.iter().map(|(w, r)| w * r).sum::<f64>() / total;
        match self.aggregation {
            Aggregation::Sum => mean,
            Aggregation::Min => {
                let w_max = self.terms.iter().map(|t| t.1).fold(0.0, f64::max);
                let worst = ratios
                    .iter()
                    .filter(|&&(w, _)| w > 0.0)
                    .map(|&(w, r)| r.powf(w / w_max))
                    .fold(f64::INFINITY, f64::min);
                worst + MIN_TIE_BREAK * (mean - 1.0)
            }
        }
    }

    /// The composite of a feasible outcome.
    pub fn of(&self, outcome: &Outcome) -> Option<f64> {
        outcome.measures().map(|m| self.value(m))
    }

    /// CMA-ES fitness (minimized): −c when feasible, the severity (≥ 1) otherwise.
    pub fn fitness(&self, outcome: &Outcome) -> f64 {
        match outcome {
            Outcome::Feasible(m) => {
                let c = self.value(m);
                if c.is_finite() { -c } else { 3.0 }
            }
            Outcome::Infeasible { reason } => reason.severity(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn measures(volume: f64, rcond: f64, margin: f64, tension: f64) -> Measures {
        Measures {
            volume_non_singular: volume,
            rcond_j_p: MeanMin {
                mean: rcond,
                min: rcond / 2.0,
            },
            singularity_margin: margin,
            min_tension: tension,
            ..Default::default()
        }
    }

    #[test]
    fn composite_is_one_for_the_reference_and_falls_back_to_unit_scales() {
        let weights = [
            Weighted {
                objective: Objective::WorkspaceVolume,
                weight: 2.0,
            },
            Weighted {
                objective: Objective::MeanRcondJp,
                weight: 1.0,
            },
            Weighted {
                objective: Objective::MinTension,
                weight: 1.0,
            },
        ];
        let reference = measures(1e-4, 0.5, 0.9, 0.0);
        let c = Composite::new(&weights, Aggregation::Sum, Some(&reference));
        // Tension reference 0 N: scale 1, so the reference scores (2 + 1 + 0) / 4.
        assert!((c.value(&reference) - 0.75).abs() < 1e-12);
        let better = measures(2e-4, 0.5, 0.9, 0.5);
        assert!((c.value(&better) - (4.0 + 1.0 + 0.5) / 4.0).abs() < 1e-12);
        let infeasible = Outcome::Infeasible {
            reason: Infeasibility::InvalidHome {
                message: "collision".into(),
            },
        };
        assert!(
            c.fitness(&infeasible) > c.fitness(&Outcome::Feasible(measures(0.0, 0.0, 0.0, 0.0)))
        );
        assert_eq!(
            c.fitness(&Outcome::Feasible(better.clone())),
            -c.value(&better)
        );
    }

    #[test]
    fn non_finite_measures_make_the_outcome_infeasible() {
        let mut m = measures(1e-4, 0.5, 0.9, 0.1);
        assert!(matches!(Outcome::checked(m.clone()), Outcome::Feasible(_)));
        m.rcond_c_o.min = f64::NAN;
        assert_eq!(
            Outcome::checked(m),
            Outcome::Infeasible {
                reason: Infeasibility::NonFinite {
                    measure: "min_rcond_c_o".into()
                }
            }
        );
    }

    #[test]
    fn outcomes_round_trip_through_json() {
        for o in [
            Outcome::Feasible(measures(1.25e-4, 0.31, 0.87, 0.01)),
            Outcome::Infeasible {
                reason: Infeasibility::HomeNotSolved {
                    message: "did not converge".into(),
                },
            },
        ] {
            let text = serde_json::to_string(&o).unwrap();
            assert_eq!(serde_json::from_str::<Outcome>(&text).unwrap(), o, "{text}");
        }
    }
}
