//! The per-point measures of the workspace map (MODEL.md §4, §6): reciprocal condition
//! numbers, singularity flags and the minimum tendon tension at a solved state.
//!
//! Every point of a sweep goes through [`point_metrics`] and nothing else, so the source of
//! these numbers is one function. INTERIM: until the analysis module (issue 4) lands, the
//! types mirror its API (`AnalysisSettings`, `Rconds`, `Singularity`, same field names)
//! and the numbers are computed here from [`Solver::blocks_at`].

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::error::Error;
use crate::kinetostatics::{RobotState, Solver};
use crate::linalg::DenseLu;
use crate::model::Model;
use crate::rod::Wrench;
use crate::rod::tendon::tension;

/// Thresholds of the singularity flags (on the raw SI rcond values, as the paper).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AnalysisSettings {
    /// Near a Type I singularity when rcond(\[B_q B_u\]) is below this.
    pub type_i_threshold: f64,
    /// Near a Type II singularity when rcond(\[B_x B_u\]) is below this (paper: 3.5e-9).
    pub type_ii_threshold: f64,
    /// Near a leg singularity when rcond(B_u) is below this.
    pub leg_threshold: f64,
}

impl Default for AnalysisSettings {
    fn default() -> Self {
        Self {
            type_i_threshold: 3.5e-9,
            type_ii_threshold: 3.5e-9,
            leg_threshold: 3.5e-9,
        }
    }
}

/// Reciprocal condition numbers σ_min/σ_max (MODEL.md §4), each in \[0, 1\].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Rconds {
    /// rcond(\[B_x B_u\]) (Type II).
    pub b_xu: f64,
    /// rcond(\[B_q B_u\]) (Type I).
    pub b_qu: f64,
    /// rcond(B_u) (leg singularity).
    pub b_u: f64,
    /// rcond(J_p), J_p = ∂p/∂q (3 × n_q).
    pub j_p: f64,
    /// rcond(J_o), J_o = ∂θ/∂q (3 × n_q).
    pub j_o: f64,
    /// rcond(C_p), C_p = ∂p/∂f_ext (3 × 3).
    pub c_p: f64,
    /// rcond(C_o), C_o = ∂θ/∂l_ext (3 × 3).
    pub c_o: f64,
}

/// Singularity flags (thresholds in [`AnalysisSettings`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Singularity {
    /// Near Type I: \[B_q B_u\] close to losing rank.
    pub type_i: bool,
    /// Near Type II: \[B_x B_u\] close to losing rank.
    pub type_ii: bool,
    /// Near a leg singularity: B_u close to losing rank.
    pub leg: bool,
}

/// Everything the workspace map records about one solved point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PointMetrics {
    /// rcond of the raw SI matrices (as the paper).
    pub rcond: Rconds,
    /// rcond of the unit-scaled matrices (for design scoring).
    pub rcond_scaled: Rconds,
    /// Singularity flags.
    pub singularity: Singularity,
    /// Smallest tendon tension over all legs \[N\].
    pub min_tension: f64,
}

/// The measures at a solved `state` (platform weight only, no extra wrench).
///
/// # Errors
/// [`Error::Solve`] if the boundary blocks cannot be evaluated (a leg integration blows
/// up; not for a converged state).
pub fn point_metrics(
    solver: &mut Solver,
    state: &RobotState,
    settings: &AnalysisSettings,
) -> Result<PointMetrics, Error> {
    let model = solver.model().clone();
    let (_, blocks) = solver.blocks_at(state, &Wrench::default())?;
    let (m, nq, nu) = (blocks.b_x.nrows(), blocks.b_q.ncols(), blocks.b_u.ncols());
    let mut bxu = DMatrix::zeros(m, 6 + nu);
    bxu.columns_mut(0, 6).copy_from(&blocks.b_x);
    bxu.columns_mut(6, nu).copy_from(&blocks.b_u);
    let mut bqu = DMatrix::zeros(m, nq + nu);
    bqu.columns_mut(0, nq).copy_from(&blocks.b_q);
    bqu.columns_mut(nq, nu).copy_from(&blocks.b_u);
    let b_u = blocks.b_u.clone();
    let b_q = blocks.b_q.clone();
    let b_w = blocks.b_w.clone();

    // J_FK = top rows of −[B_x B_u]⁻¹ B_q, C = top rows of −[B_x B_u]⁻¹ B_w (MODEL.md §4).
    let mut lu = DenseLu::new(m);
    let (j_fk, c) = if lu.factor(&bxu).is_ok() {
        let solve_cols = |b: &DMatrix<f64>| {
            let mut out = DMatrix::zeros(6, b.ncols());
            for j in 0..b.ncols() {
                let mut col: DVector<f64> = -b.column(j);
                lu.solve_in_place(&mut col);
                out.column_mut(j).copy_from(&col.rows(0, 6));
            }
            out
        };
        (Some(solve_cols(&b_q)), Some(solve_cols(&b_w)))
    } else {
        (None, None)
    };
    let sub = |a: &Option<DMatrix<f64>>, r: usize, c0: usize, cols: usize| {
        a.as_ref()
            .map_or(0.0, |a| rcond(&a.view((r, c0), (3, cols)).into_owned()))
    };
    let raw_b = (rcond(&bxu), rcond(&bqu), rcond(&b_u));
    let (j_p, j_o) = (sub(&j_fk, 0, 0, nq), sub(&j_fk, 3, 0, nq));
    let (c_p, c_o) = (sub(&c, 0, 0, 3), sub(&c, 3, 3, 3));
    let rcond_raw = Rconds {
        b_xu: raw_b.0,
        b_qu: raw_b.1,
        b_u: raw_b.2,
        j_p,
        j_o,
        c_p,
        c_o,
    };
    let (rows, cols_x, cols_q, cols_u) = unit_scales(&model);
    let scale = |a: &DMatrix<f64>, cols: &[f64]| {
        DMatrix::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)] * rows[i] * cols[j])
    };
    let xu: Vec<f64> = cols_x.iter().chain(&cols_u).copied().collect();
    let qu: Vec<f64> = cols_q.iter().chain(&cols_u).copied().collect();
    // J_p, J_o, C_p, C_o are single-unit blocks: their rcond is scale-invariant.
    let rcond_scaled = Rconds {
        b_xu: rcond(&scale(&bxu, &xu)),
        b_qu: rcond(&scale(&bqu, &qu)),
        b_u: rcond(&scale(&b_u, &cols_u)),
        ..rcond_raw
    };
    let singularity = Singularity {
        type_i: rcond_raw.b_qu < settings.type_i_threshold,
        type_ii: rcond_raw.b_xu < settings.type_ii_threshold,
        leg: rcond_raw.b_u < settings.leg_threshold,
    };
    let nu_leg = model.n_leg_unknowns();
    let min_tension = (0..3)
        .flat_map(|i| (0..model.n_tendons()).map(move |k| i * nu_leg + k))
        .map(|i| tension(state.y_u[i]))
        .fold(f64::INFINITY, f64::min);
    Ok(PointMetrics {
        rcond: rcond_raw,
        rcond_scaled,
        singularity,
        min_tension,
    })
}

/// σ_min/σ_max of `a` (0 for a zero or non-finite matrix).
fn rcond(a: &DMatrix<f64>) -> f64 {
    if !a.iter().all(|x| x.is_finite()) {
        return 0.0;
    }
    let s = a.clone().singular_values();
    let (lo, hi) = s.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &x| {
        (lo.min(x), hi.max(x))
    });
    if hi > 0.0 && lo.is_finite() {
        lo / hi
    } else {
        0.0
    }
}

/// Unit scaling that makes the blocks dimensionless: lengths by L, forces by E I / L²,
/// moments by E I / L, tendon unknowns γ by √(E I) / L. Returns (row scales, x_ee column
/// scales, q column scales, y_u column scales).
fn unit_scales(model: &Model) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let len = model.leg.length;
    let ei = model.leg.bending_stiffness();
    let (force, moment) = (ei / (len * len), ei / len);
    let (nu, nt) = (model.n_leg_unknowns(), model.n_tendons());
    let mut rows = vec![1.0 / force; 3];
    rows.extend([1.0 / moment; 3]);
    for _ in 0..3 {
        rows.extend([1.0 / len; 3]);
        rows.extend([1.0 / moment; 3]);
        rows.extend(std::iter::repeat_n(1.0 / len, nt));
    }
    let cols_x = vec![len, len, len, 1.0, 1.0, 1.0];
    let cols_q = vec![len; model.n_actuators()];
    let mut cols_u = Vec::with_capacity(3 * nu);
    for _ in 0..3 {
        cols_u.extend(std::iter::repeat_n(force.sqrt(), nt));
        cols_u.extend([1.0 / len; 3]);
        cols_u.extend([1.0; 3]);
    }
    (rows, cols_x, cols_q, cols_u)
}
