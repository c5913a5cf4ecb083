//! Stability of an equilibrium with the actuators held (MODEL.md §4b): displacement
//! control of every actuator, elastic tendons, gravity and the platform's dead load.
//!
//! The system is conservative, so an equilibrium is stable when the second variation of
//! its potential energy is positive definite. Condensing the legs onto the platform pose
//! gives the platform stiffness K = C⁻¹ (6 × 6; δw = K δx, the wrench that holds the
//! platform displaced by δx with the legs in equilibrium), and along a continuous path of
//! equilibria from a stable one the first loss of stability is a negative eigenvalue of
//! sym(K), equivalently of sym(C) (derivation and its limits in MODEL.md §4b). This
//! module computes:
//! - K from the boundary blocks by the Schur complement over the legs,
//!   K = B_x,p − B_u,p B_u,l⁻¹ B_x,l (platform rows p, leg rows l; each leg's B_u,l block
//!   is square and solved on its own, 3 LU factorizations of (6 + n_t) × (6 + n_t)): it
//!   is invariant under any change of the leg unknowns, so the solver's ζ blocks give it
//!   as well as the paper's γ blocks;
//! - the signed eigenvalues of the unit-scaled symmetric part, D⁻¹ C D⁻¹ with
//!   D = diag(√(L³/EI) I₃, √(L/EI) I₃) (a congruence: the signs are those of sym(C),
//!   Sylvester's law of inertia), and of sym(C_p) \[m/N\] and sym(C_o) \[rad/(N·m)\].

use nalgebra::{Dim, Matrix, Matrix3, Matrix6, RawStorage, Vector3};
use serde::Serialize;

use crate::boundary::BoundaryJacobians;
use crate::model::Model;

use super::UnitScaling;

/// Whether an equilibrium is stable with the actuators held, and the evidence.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Stability {
    /// Every eigenvalue of the scaled sym(C) is positive.
    pub stable: bool,
    /// Eigenvalues of sym(D⁻¹ C D⁻¹), ascending (dimensionless; D in the module docs): their
    /// signs are those of sym(C).
    pub eigenvalues: [f64; 6],
    /// Eigenvalues of sym(C_p), ascending \[m/N\].
    pub eigenvalues_c_p: [f64; 3],
    /// Eigenvalues of sym(C_o), ascending \[rad/(N·m)\].
    pub eigenvalues_c_o: [f64; 3],
    /// ‖D⁻¹ C D⁻¹ − (D⁻¹ C D⁻¹)ᵀ‖_F / ‖D⁻¹ C D⁻¹‖_F: zero for the exact conservative model; what is
    /// left is the discretization's and round-off's.
    pub asymmetry: f64,
}

impl Stability {
    /// The stability read from a compliance C (6 × 6, raw SI, columns f_ext then l_ext).
    pub fn of_compliance<R: Dim, C: Dim, S: RawStorage<f64, R, C>>(
        model: &Model,
        compliance: &Matrix<f64, R, C, S>,
    ) -> Self {
        let c = Matrix6::from_fn(|r, k| compliance[(r, k)]);
        let scaled = scale_congruent(model, &c);
        let c_p = symmetric_part3(&c.fixed_view::<3, 3>(0, 0).into_owned());
        let c_o = symmetric_part3(&c.fixed_view::<3, 3>(3, 3).into_owned());
        let norm = scaled.norm();
        Self {
            eigenvalues_c_p: eigenvalues3(&c_p),
            eigenvalues_c_o: eigenvalues3(&c_o),
            asymmetry: if norm > 0.0 {
                (scaled - scaled.transpose()).norm() / norm
            } else {
                0.0
            },
            ..Self::of_scaled(&scaled)
        }
    }

    /// [`Stability::of_compliance`]'s `stable` and `eigenvalues` (bit for bit), the other
    /// fields NaN: what the workspace sweep records of every point (two 3 × 3 eigenvalue
    /// problems and a norm fewer).
    pub(crate) fn of_compliance_sign<R: Dim, C: Dim, S: RawStorage<f64, R, C>>(
        model: &Model,
        compliance: &Matrix<f64, R, C, S>,
    ) -> Self {
        let c = Matrix6::from_fn(|r, k| compliance[(r, k)]);
        Self::of_scaled(&scale_congruent(model, &c))
    }

    /// The sign part from the scaled compliance D⁻¹ C D⁻¹ (the rest NaN).
    fn of_scaled(scaled: &Matrix6<f64>) -> Self {
        let eigenvalues = sorted(symmetric_part(scaled).symmetric_eigenvalues().as_slice());
        Self {
            stable: eigenvalues.iter().all(|&l| l > 0.0),
            eigenvalues,
            eigenvalues_c_p: [f64::NAN; 3],
            eigenvalues_c_o: [f64::NAN; 3],
            asymmetry: f64::NAN,
        }
    }
}

/// The compliance in units of the leg, D⁻¹ C D⁻¹ with D = diag(√(L³/EI) I₃, √(L/EI) I₃)
/// (a congruence: the signs of its eigenvalues are those of C's).
fn scale_congruent(model: &Model, c: &Matrix6<f64>) -> Matrix6<f64> {
    let s = UnitScaling::new(model);
    // Position: L / F = L³/EI; rotation: 1 / M = L/EI.
    let (dp, dr) = ((s.length / s.force).sqrt(), (1.0 / s.moment).sqrt());
    let d = |i: usize| if i < 3 { dp } else { dr };
    Matrix6::from_fn(|r, col| c[(r, col)] / (d(r) * d(col)))
}

fn symmetric_part(m: &Matrix6<f64>) -> Matrix6<f64> {
    (m + m.transpose()) * 0.5
}

fn symmetric_part3(m: &Matrix3<f64>) -> Matrix3<f64> {
    (m + m.transpose()) * 0.5
}

fn eigenvalues3(m: &Matrix3<f64>) -> [f64; 3] {
    let e: Vector3<f64> = m.symmetric_eigenvalues();
    sorted(e.as_slice())
}

/// The N values of `x` in ascending order.
fn sorted<const N: usize>(x: &[f64]) -> [f64; N] {
    let mut v: [f64; N] = x.try_into().expect("N values");
    v.sort_by(f64::total_cmp);
    v
}

/// The platform stiffness K = C⁻¹ \[N/m, N/rad, N·m/m, N·m/rad\] from boundary blocks (any
/// tendon unknown), by the Schur complement over the legs (module docs). `None` where a
/// leg's block B_u,l is singular (the platform-held legs have no unique equilibrium
/// there) or the result is not finite.
pub fn platform_stiffness(model: &Model, blocks: &BoundaryJacobians) -> Option<Matrix6<f64>> {
    let nu = model.n_leg_unknowns();
    let mut k = Matrix6::from_fn(|r, c| blocks.b_x[(r, c)]);
    for leg in 0..3 {
        let (row, col) = (6 + leg * nu, leg * nu);
        let b_ul = blocks.b_u.view((row, col), (nu, nu)).into_owned();
        let b_xl = blocks.b_x.view((row, 0), (nu, 6)).into_owned();
        let z = b_ul.lu().solve(&b_xl)?;
        let update = blocks.b_u.view((0, col), (6, nu)) * z;
        k -= Matrix6::from_fn(|r, c| update[(r, c)]);
    }
    k.iter().all(|x| x.is_finite()).then_some(k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::Tdpcr;

    #[test]
    fn the_sign_part_is_that_of_the_whole_stability_bit_for_bit() {
        let design = Tdpcr::from_ron_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/designs/lilge2022.ron"
        ))
        .unwrap();
        let model = Model::new(&design);
        let wave = |k: usize| (k as f64 * 0.61).sin() * 1e-3;
        // Positive definite, indefinite and asymmetric compliances.
        for shift in [2e-3, 0.0, -2e-3] {
            let c = Matrix6::from_fn(|r, k| wave(7 * r + k * k) + if r == k { shift } else { 0.0 });
            let whole = Stability::of_compliance(&model, &c);
            let sign = Stability::of_compliance_sign(&model, &c);
            assert_eq!(sign.stable, whole.stable);
            assert_eq!(
                sign.eigenvalues.map(f64::to_bits),
                whole.eigenvalues.map(f64::to_bits)
            );
            assert!(sign.asymmetry.is_nan() && sign.eigenvalues_c_p[0].is_nan());
            assert!(whole.asymmetry > 0.0);
        }
    }
}
