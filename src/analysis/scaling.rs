//! The unit scaling of the analysis: every residual row and every unknown divided by a
//! characteristic size of the design, so that rcond compares like with like (design
//! scoring, MODEL.md §7). The raw SI matrices stay what the paper reports.
//!
//! Characteristic sizes (L leg length, EI bending stiffness, D largest tendon offset):
//!
//! | quantity | size |
//! |---|---|
//! | force rows, f_ext, tension τ | F = EI/L² \[N\] |
//! | moment and joint-moment rows, l_ext | M = EI/L \[N·m\] |
//! | coupling-position rows, platform position, base translation q_t | L \[m\] |
//! | tendon-length rows, bending actuation q_b | D \[m\] |
//! | platform rotation | 1 \[rad\] |
//! | γ | √F \[√N\] (so (γ/√F)² is the tension in units of F) |
//! | u(0) | 1/L \[1/m\] |
//! | v(0) | F/(GA) across, F/(EA) along the rod \[–\] |
//!
//! A scaled matrix is diag(1/row size) · M · diag(column size). The same division is
//! the merit weighting of the Newton solver (`row_weights` in `kinetostatics`).

use crate::model::Model;

/// Characteristic sizes of one design (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitScaling {
    /// Leg length L \[m\].
    pub length: f64,
    /// Force F = EI/L² \[N\].
    pub force: f64,
    /// Moment M = EI/L \[N·m\].
    pub moment: f64,
    /// Tendon offset D \[m\] (largest over the leg's tendons).
    pub tendon_offset: f64,
    /// Shear strain F/(GA) \[–\].
    pub shear_strain: f64,
    /// Axial strain F/(EA) \[–\].
    pub axial_strain: f64,
    /// Tendons per leg n_t.
    n_tendons: usize,
    /// Antagonistic pairs per leg.
    pairs: usize,
}

impl UnitScaling {
    /// The sizes of `model`'s design.
    pub fn new(model: &Model) -> Self {
        let leg = &model.leg;
        let length = leg.length;
        let ei = leg.bending_stiffness();
        let force = ei / (length * length);
        Self {
            length,
            force,
            moment: ei / length,
            tendon_offset: leg.max_offset().max(1e-6),
            shear_strain: force / leg.k_se.x,
            axial_strain: force / leg.k_se.z,
            n_tendons: model.n_tendons(),
            pairs: model.pairs,
        }
    }

    /// Size of residual row `i` (MODEL.md §3 order as in `boundary`).
    pub fn row(&self, i: usize) -> f64 {
        if i < 3 {
            self.force
        } else if i < 6 {
            self.moment
        } else {
            match (i - 6) % (6 + self.n_tendons) {
                0..3 => self.length,
                3..6 => self.moment,
                _ => self.tendon_offset,
            }
        }
    }

    /// Size of pose column `c` (δp then δθ).
    pub fn pose(&self, c: usize) -> f64 {
        if c < 3 { self.length } else { 1.0 }
    }

    /// Size of actuation column `j` (per leg \[q_b per pair, q_t\]).
    pub fn actuation(&self, j: usize) -> f64 {
        if j % (self.pairs + 1) < self.pairs {
            self.tendon_offset
        } else {
            self.length
        }
    }

    /// Size of wrench column `c` (f_ext then l_ext).
    pub fn wrench(&self, c: usize) -> f64 {
        if c < 3 { self.force } else { self.moment }
    }

    /// Size of leg-unknown column `j` (per leg \[γ (n_t), u(0) (3), v(0) (3)\]).
    pub fn leg_unknown(&self, j: usize) -> f64 {
        let k = j % (6 + self.n_tendons);
        let nt = self.n_tendons;
        if k < nt {
            self.force.sqrt()
        } else if k < nt + 3 {
            1.0 / self.length
        } else if k < nt + 5 {
            self.shear_strain
        } else {
            self.axial_strain
        }
    }
}
