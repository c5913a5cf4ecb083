//! The cold guess of one leg (MODEL.md §9): tensions from a linear constant-curvature
//! model with slack, and base strains that balance them and the load on a straight rod.
//! The start of every cold solve, of one TDCR ([`crate::tdcr`]) and of the parallel
//! robot's legs ([`crate::kinetostatics::home_guess`]).

use nalgebra::{DMatrix, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::LegModel;
use super::tendon::gamma_from;
use crate::spatial::Wrench;

/// How the tendons are driven (one value per tendon, in file order).
#[derive(Debug, Clone, PartialEq)]
pub enum TendonControl {
    /// Given tensions τ_k \[N\], each ≥ 0.
    Tension(Vec<f64>),
    /// Given length changes Δℓ_k \[m\] (negative = pulled); tensions are solved for.
    Displacement(Vec<f64>),
}

/// The unknowns of a solved robot; pass back as a warm start.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TdcrState {
    /// u(0) \[1/m\].
    pub u0: [f64; 3],
    /// v(0) \[–\].
    pub v0: [f64; 3],
    /// γ_k per tendon (τ = γ² if γ ≥ 0, slack Θ = γ² otherwise); empty in tension control.
    pub gammas: Vec<f64>,
}

/// The cold guess of MODEL.md §9 for a robot whose base is the world frame: tensions
/// from a linear constant-curvature model with slack (a small linear complementarity
/// problem), strains at the base that balance those tensions and the external load on a
/// straight rod.
pub fn cold_guess(model: &LegModel, control: &TendonControl, wrench: &Wrench) -> TdcrState {
    cold_guess_at(model, &Matrix3::identity(), control, wrench)
}

/// [`cold_guess`] for a base with orientation `base_rotation` (the tip `wrench` and the
/// weight are in the world frame).
pub fn cold_guess_at(
    model: &LegModel,
    base_rotation: &Matrix3<f64>,
    control: &TendonControl,
    wrench: &Wrench,
) -> TdcrState {
    let nt = model.n_tendons;
    let (tensions, gammas) = match control {
        TendonControl::Tension(t) => (t.clone(), Vec::new()),
        TendonControl::Displacement(d) => {
            let (tau, theta) = constant_curvature_tensions(model, d);
            let g = (0..nt).map(|k| gamma_from(tau[k], theta[k])).collect();
            (tau, g)
        }
    };
    let len = model.length;
    // Everything in the base frame.
    let force = base_rotation.tr_mul(&wrench.force);
    let moment = base_rotation.tr_mul(&wrench.moment);
    let weight = base_rotation.tr_mul(&(model.weight_per_length * len));
    let axis = Vector3::z();
    let mut n0 = force + weight;
    let mut m0 = moment + (axis * len).cross(&force) + (axis * (len / 2.0)).cross(&weight);
    for k in 0..nt {
        n0 -= axis * tensions[k];
        m0 -= model.tendon_offsets[k].cross(&axis) * tensions[k];
    }
    let v0 = axis + n0.component_div(&model.k_se);
    let u0 = m0.component_div(&model.k_bt);
    TdcrState {
        u0: u0.into(),
        v0: v0.into(),
        gammas,
    }
}

/// Tensions τ ≥ 0 and slacks Θ ≥ 0 with Θ = Δℓ + P τ and τ_k Θ_k = 0, where P is the
/// compliance of the tendon lengths of a straight rod bent at constant curvature per
/// segment: P_kl = (r_k · r_l / EI + 1/(EA)) min(e_k, e_l) + δ_kl e_k/(EA)_t.
/// Solved by projected Gauss–Seidel (P is symmetric positive definite).
fn constant_curvature_tensions(model: &LegModel, displacements: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let nt = model.n_tendons;
    let ei = model.bending_stiffness();
    let ea = model.axial_stiffness();
    let p = DMatrix::from_fn(nt, nt, |k, l| {
        let (rk, rl) = (&model.tendon_offsets[k], &model.tendon_offsets[l]);
        let common = model.tendon_ends[k].min(model.tendon_ends[l]);
        let stretch = if k == l {
            model.tendon_ends[k] / model.tendon_stiffness
        } else {
            0.0
        };
        (rk.dot(rl) / ei + 1.0 / ea) * common + stretch
    });
    let mut tau = vec![0.0; nt];
    for _ in 0..2000 {
        let mut change: f64 = 0.0;
        for k in 0..nt {
            let off: f64 = (0..nt)
                .filter(|&l| l != k)
                .map(|l| p[(k, l)] * tau[l])
                .sum();
            let new = ((-displacements[k] - off) / p[(k, k)]).max(0.0);
            change = change.max((new - tau[k]).abs());
            tau[k] = new;
        }
        if change < 1e-13 {
            break;
        }
    }
    let theta = (0..nt)
        .map(|k| (displacements[k] + (0..nt).map(|l| p[(k, l)] * tau[l]).sum::<f64>()).max(0.0))
        .collect();
    (tau, theta)
}
