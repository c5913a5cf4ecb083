//! A path step's start across one or two tendons' kinks (MODEL.md "Starts across a
//! kink"): where the extrapolated start of the 6-DoF design's step takes a tendon from
//! taut into slack or back ([`super::predict`] then puts it at its kink, ζ = 0, and every
//! other unknown on the old side's extrapolation), the start follows the exact tangent
//! at the last solution to the crossing and the other side's tangent beyond it.
//!
//! With J the exact IK Jacobian at the last solution (in \[q, ζ\]), the step d \[m\] and
//! t = −J⁻¹ B_x\[:, 0..3\] d the tangent along it, the first tendon crosses at
//! s* = −ζ_i / t_i (0 < s* < 1). Beyond it the crossing tendons' columns are the other
//! side's: −e of the tendon's length row for slack (its tension, and with it every other
//! row, no longer depends on ζ), ∂b/∂τ for taut (kept from the analysis of the last
//! solution, [`Solver::taut_column_at`]). The tangent with those columns is a rank-one or
//! rank-two update of the same factors (Woodbury, [`tangent_with_columns`]), and the
//! start is the extrapolation moved by (1 − s*) times the change of slope, the crossing
//! tendons at (1 − s*) times their new slopes. The solver's seeded Jacobian
//! ([`super::chord_jacobian`]) gets the same columns.
//!
//! Why: on the design search's grid (the reference, Δ = 12 mm) 44 % of the steps switch
//! a tendon's side, and those whose start lay at a kink took a third of the Newton time
//! with 4.7 fresh Jacobians each; most predicted crossings are a pair handing its tension
//! from one tendon to the other (two crossings in one step). Measured with this start
//! (BENCHMARKS.md "Starts across a tendon's kink"): the design search's evaluation of the
//! reference 5 146.3 M → 4 434.4 M instructions, the same 1 977 cells; the reference's
//! Δ = 3 mm sweep 31 786 → 25 836 Newton Jacobians, the same cells.

use nalgebra::{DMatrix, DVector, Matrix2, Vector2, Vector3};

use crate::boundary::{convert_tendon_unknowns, slack_side_column};
use crate::kinetostatics::{RobotState, Solver};
use crate::linalg::DenseLu;
use crate::model::Model;
use crate::rod::tendon::TendonUnknown;

use super::predict::in_zeta;

/// What the start needs of the last solution of a path, and buffers.
#[derive(Debug, Clone)]
pub(super) struct KinkStart {
    /// Whether the fields below belong to a solution (q `at`).
    valid: bool,
    /// q of that solution.
    at: Vec<f64>,
    /// Its exact IK Jacobian (n × n).
    jacobian: DMatrix<f64>,
    /// ∂b/∂(position) there (n × 3).
    b_x: DMatrix<f64>,
    /// ∂b/∂τ of its slack tendons (column leg · n_t + k), if kept.
    taut: Option<DMatrix<f64>>,
    lu: DenseLu,
    /// The tangent, then the two columns' solves.
    work: [DVector<f64>; 3],
    /// The other sides' columns of the last start across kinks and their indices in
    /// \[q, ζ\] (`count` of them).
    columns: [DVector<f64>; 2],
    indices: [usize; 2],
    count: usize,
}

impl KinkStart {
    /// Buffers for `model`'s IK.
    pub(super) fn new(model: &Model) -> Self {
        let n = model.n_residuals();
        Self {
            valid: false,
            at: Vec::new(),
            jacobian: DMatrix::zeros(n, n),
            b_x: DMatrix::zeros(n, 3),
            taut: None,
            lu: DenseLu::new(n),
            work: std::array::from_fn(|_| DVector::zeros(n)),
            columns: std::array::from_fn(|_| DVector::zeros(n)),
            indices: [0; 2],
            count: 0,
        }
    }

    /// Keeps what a start from `state` needs, from the solver's analysis of `state` (its
    /// last exact evaluation): its IK Jacobian (the 6-DoF design only; else nothing is
    /// kept), B_x's position columns and its slack tendons' taut columns.
    pub(super) fn record(&mut self, model: &Model, solver: &Solver, state: &RobotState) {
        self.valid = solver.ik_jacobian_from_blocks(state, &mut self.jacobian);
        if !self.valid {
            return;
        }
        self.at.clone_from(&state.q);
        self.b_x.copy_from(&solver.last_blocks().b_x.columns(0, 3));
        let (n, nu, nt) = (
            model.n_residuals(),
            model.n_leg_unknowns(),
            model.n_tendons(),
        );
        let taut = self.taut.get_or_insert_with(|| DMatrix::zeros(n, 3 * nt));
        let kept = model.tendon_unknown_indices().all(|i| {
            let (leg, k) = (i / nu, i % nu);
            state.y_u[i] >= 0.0
                || solver.taut_column_at(state, leg, k, taut.column_mut(leg * nt + k))
        });
        if !kept {
            self.taut = None;
        }
    }

    /// The start across kinks from `predicted` (`predict`'s start, the crossing tendons at
    /// their kinks, γ = 0) to the pose `position` \[m\], moved as the module docs say, if
    /// `last` is the recorded solution and one or two tendons cross within the step;
    /// `None` otherwise (most steps: no tendon crosses, and nothing is computed).
    pub(super) fn across(
        &mut self,
        model: &Model,
        last: &RobotState,
        predicted: &RobotState,
        position: &Vector3<f64>,
    ) -> Option<RobotState> {
        self.count = 0;
        if !self.valid || self.at != last.q {
            return None;
        }
        let mut crossing = [0usize; 2];
        let mut count = 0;
        for i in model.tendon_unknown_indices() {
            if predicted.y_u[i] == 0.0 && last.y_u[i] != 0.0 {
                if count == 2 {
                    return None;
                }
                crossing[count] = i;
                count += 1;
            }
        }
        if count == 0 {
            return None;
        }
        let nq = model.n_actuators();
        let last_zeta = in_zeta(model, last);
        let mut y = predicted.q.clone();
        y.extend(in_zeta(model, predicted));
        let d = position - Vector3::from(last.position);
        if !self.move_across(model, &last_zeta, &crossing[..count], &mut y, &d) {
            return None;
        }
        let mut y_u = y.split_off(nq);
        convert_tendon_unknowns(model, &mut y_u, TendonUnknown::Linear, TendonUnknown::Gamma);
        Some(RobotState {
            position: predicted.position,
            rotvec: predicted.rotvec,
            q: y,
            y_u,
        })
    }

    /// [`KinkStart::across`] in \[q, ζ\]: `y` moved for the tendons `crossing` (indices in
    /// y_u) along the step `d` from the recorded solution (its leg unknowns in ζ
    /// `last_zeta`); false where they do not cross within the step or would not change
    /// sides (`y` then partly moved, to be dropped).
    fn move_across(
        &mut self,
        model: &Model,
        last_zeta: &[f64],
        crossing: &[usize],
        y: &mut [f64],
        d: &Vector3<f64>,
    ) -> bool {
        let count = crossing.len();
        let nq = model.n_actuators();
        let (nu, nt) = (model.n_leg_unknowns(), model.n_tendons());
        for (column, &i) in self.columns.iter_mut().zip(crossing) {
            if last_zeta[i] > 0.0 {
                slack_side_column(model, i / nu, i % nu, column);
            } else if let Some(taut) = &self.taut {
                column.copy_from(&taut.column((i / nu) * nt + i % nu));
            } else {
                return false;
            }
        }
        if self.lu.factor(&self.jacobian).is_err() {
            return false;
        }
        let [t, z0, z1] = &mut self.work;
        t.gemv(-1.0, &self.b_x, d, 0.0);
        self.lu.solve_in_place(t);
        let index = |m: usize| nq + crossing[m];
        let crossing_at = (0..count)
            .map(|m| -last_zeta[crossing[m]] / t[index(m)])
            .filter(|s| *s > 0.0 && *s < 1.0)
            .fold(f64::INFINITY, f64::min);
        if crossing_at >= 1.0 {
            return false;
        }
        let indices = [index(0), if count == 2 { index(1) } else { 0 }];
        let Some(coefficients) =
            tangent_with_columns(&self.lu, t, [z0, z1], &self.columns, &indices[..count])
        else {
            return false;
        };
        let after = 1.0 - crossing_at;
        let [t, z0, z1] = &self.work;
        for (k, yk) in y.iter_mut().enumerate() {
            let other = other_tangent(t, [z0, z1], &indices[..count], coefficients, k);
            if indices[..count].contains(&k) {
                *yk = after * other;
            } else {
                *yk += after * (other - t[k]);
            }
        }
        let switched = (0..count).all(|m| last_zeta[crossing[m]] * y[index(m)] < 0.0);
        if !(switched && y.iter().all(|v| v.is_finite())) {
            return false;
        }
        self.indices = indices;
        self.count = count;
        true
    }

    /// The other sides' columns of the last start across kinks (index in \[q, ζ\],
    /// column), none if it did not cross.
    pub(super) fn columns(&self) -> impl Iterator<Item = (usize, &DVector<f64>)> {
        self.indices[..self.count]
            .iter()
            .copied()
            .zip(&self.columns[..self.count])
    }
}

/// The Woodbury coefficients of the tangent with columns `indices` of J replaced by
/// `columns`: with t = J⁻¹ r (`t`, from `lu`), Z = J⁻¹ \[columns\] (written into `z`) and
/// E the unit vectors of `indices` (one or two), the new tangent is
/// t − (Z − E) c with c = (Eᵀ Z)⁻¹ Eᵀ t ([`other_tangent`]); `None` where Eᵀ Z is
/// singular.
fn tangent_with_columns(
    lu: &DenseLu,
    t: &DVector<f64>,
    z: [&mut DVector<f64>; 2],
    columns: &[DVector<f64>; 2],
    indices: &[usize],
) -> Option<Vector2<f64>> {
    let [z0, z1] = z;
    z0.copy_from(&columns[0]);
    lu.solve_in_place(z0);
    if indices.len() == 1 {
        let pivot = z0[indices[0]];
        return (pivot.abs() > 1e-12 && pivot.is_finite())
            .then(|| Vector2::new(t[indices[0]] / pivot, 0.0));
    }
    z1.copy_from(&columns[1]);
    lu.solve_in_place(z1);
    let (a, b) = (indices[0], indices[1]);
    Matrix2::new(z0[a], z1[a], z0[b], z1[b])
        .try_inverse()
        .map(|inverse| inverse * Vector2::new(t[a], t[b]))
        .filter(|c| c.iter().all(|v| v.is_finite()))
}

/// Entry `k` of the tangent with replaced columns ([`tangent_with_columns`]).
fn other_tangent(
    t: &DVector<f64>,
    z: [&DVector<f64>; 2],
    indices: &[usize],
    coefficients: Vector2<f64>,
    k: usize,
) -> f64 {
    let mut w = 0.0;
    for (m, &index) in indices.iter().enumerate() {
        w += z[m][k] * coefficients[m];
        if k == index {
            w -= coefficients[m];
        }
    }
    t[k] - w
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A well-conditioned test matrix.
    fn matrix(n: usize) -> DMatrix<f64> {
        DMatrix::from_fn(n, n, |i, j| {
            let x = ((i * 7 + j * 13) % 17) as f64 / 17.0 - 0.5;
            if i == j { 4.0 + x } else { x }
        })
    }

    /// The updated tangent solves the matrix with the columns replaced, to round-off, for
    /// one and two columns.
    #[test]
    fn the_woodbury_tangent_solves_the_matrix_with_replaced_columns() {
        let n = 9;
        let j = matrix(n);
        let r = DVector::from_fn(n, |i, _| (i as f64 * 0.37).sin());
        let mut lu = DenseLu::new(n);
        lu.factor(&j).unwrap();
        let mut t = r.clone();
        lu.solve_in_place(&mut t);
        let columns = [
            DVector::from_fn(n, |i, _| if i == 5 { -1.0 } else { 0.0 }),
            DVector::from_fn(n, |i, _| (i as f64 * 1.3).cos()),
        ];
        for indices in [&[3usize][..], &[3, 7][..]] {
            let (mut z0, mut z1) = (DVector::zeros(n), DVector::zeros(n));
            let c = tangent_with_columns(&lu, &t, [&mut z0, &mut z1], &columns, indices).unwrap();
            let other = DVector::from_fn(n, |k, _| other_tangent(&t, [&z0, &z1], indices, c, k));
            let mut replaced = j.clone();
            for (m, &index) in indices.iter().enumerate() {
                replaced.set_column(index, &columns[m]);
            }
            let residual = (&replaced * &other - &r).norm();
            assert!(
                residual < 1e-12 * r.norm(),
                "{indices:?}: residual {residual:e}"
            );
            let plain = (&j * &other - &r).norm();
            assert!(plain > 1e-3, "{indices:?}: the columns made no difference");
        }
    }
}
