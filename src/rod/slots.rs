//! Which tendon each lane runs in each slot of the kernel, and the tendon data in slot
//! order.
//!
//! With the legs in SIMD lanes ([`lanes`](super::lanes)), a tendon's terms are computed
//! for every lane as soon as one lane has it taut. The legs of an antagonistic pair are
//! usually taut on different sides (one leg pulls tendon 1, the next tendon 2), so without
//! reordering every slot is taut somewhere and every lane pays for both tendons. Each lane
//! therefore lists its taut tendons first, within each group of tendons that end at the
//! same arc length (so a slot runs over the same intervals in every lane): a slot slack in
//! every lane is then skipped, as the one-leg kernel skips a slack tendon.
//!
//! The partition is stable (taut tendons keep their order, slack ones theirs), so the
//! strain system sums its taut terms in the same order as without it. Where tendons end
//! together, their jumps are applied in slot order: this changed the small sweep's solved
//! q by at most 2e-9 (relative, 35 of 2866 points; iterate-level) and not its map. Measured
//! (callgrind, reference design): the residual 146.5 k → 120.6 k instructions, the exact
//! Jacobian 861 k → 794 k.

use nalgebra::{Matrix3, Vector3};

use crate::design::MAX_TENDONS;
use crate::rod::lanes::Real;
use crate::rod::leg_model::LegModel;
use crate::rod::rhs::MAX_LEGS;

/// The tendons of every lane in slot order.
#[derive(Debug, Clone, Copy)]
pub struct TendonSlots<T: Real> {
    /// Tendon offset r of each slot (body frame) \[m\].
    pub offsets: [Vector3<T>; MAX_TENDONS],
    /// r̂ of each slot.
    pub hats: [Matrix3<T>; MAX_TENDONS],
    /// r̂ r̂ᵀ of each slot.
    pub hat_squares: [Matrix3<T>; MAX_TENDONS],
    /// Tension τ of each slot \[N\].
    pub tensions: [T; MAX_TENDONS],
    /// `tendon[lane][slot]`: the leg's own index of the tendon in that slot.
    pub tendon: [[usize; MAX_TENDONS]; MAX_LEGS],
}

impl<T: Real> TendonSlots<T> {
    /// Slots in the model's order, all tensions zero.
    pub fn new() -> Self {
        Self {
            offsets: [Vector3::zeros(); MAX_TENDONS],
            hats: [Matrix3::zeros(); MAX_TENDONS],
            hat_squares: [Matrix3::zeros(); MAX_TENDONS],
            tensions: [T::zero(); MAX_TENDONS],
            tendon: [std::array::from_fn(|k| k); MAX_LEGS],
        }
    }

    /// Fills lane `lane` for a leg of `model` with tensions `tau` \[N\]: its taut tendons
    /// (τ ≠ 0) first within each group of tendons with the same end (stable).
    pub fn set_lane(&mut self, lane: usize, model: &LegModel, tau: &[f64; MAX_TENDONS]) {
        let nt = model.n_tendons;
        let order = &mut self.tendon[lane];
        for (k, slot) in order.iter_mut().enumerate() {
            *slot = k;
        }
        // Tendons of one group may trade places only with each other: for each slot, the
        // next unplaced member of its group, taut ones before slack ones.
        let mut placed = [false; MAX_TENDONS];
        for slot in 0..nt {
            let end = model.tendon_ends[slot];
            let pick = (0..nt)
                .filter(|&k| !placed[k] && model.tendon_ends[k] == end)
                .find(|&k| tau[k] != 0.0)
                .or_else(|| (0..nt).find(|&k| !placed[k] && model.tendon_ends[k] == end))
                .unwrap_or(slot);
            placed[pick] = true;
            order[slot] = pick;
        }
        for slot in 0..nt {
            let k = order[slot];
            for i in 0..3 {
                self.offsets[slot][i].set_lane(lane, model.tendon_offsets[k][i]);
            }
            for (e, x) in self.hats[slot].iter_mut().zip(model.tendon_hats[k].iter()) {
                e.set_lane(lane, *x);
            }
            let squares = model.tendon_hat_squares[k].iter();
            for (e, x) in self.hat_squares[slot].iter_mut().zip(squares) {
                e.set_lane(lane, *x);
            }
            self.tensions[slot].set_lane(lane, tau[k]);
        }
    }
}

impl<T: Real> Default for TendonSlots<T> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn taut_tendons_come_first_within_groups_of_equal_ends() {
        let tendons = [(0.0, 0.145), (1.0, 0.08), (2.0, 0.145), (3.0, 0.145)];
        let leg = crate::design::test_leg(&tendons);
        let model = LegModel::new(&leg, Vector3::zeros());
        let mut slots = TendonSlots::<f64>::new();
        let tensions = |t: [f64; 4]| std::array::from_fn(|k| t.get(k).copied().unwrap_or(0.0));
        // Tendon 1 (its own group) stays in slot 1; of the group {0, 2, 3}, the taut 2
        // and 3 come first in their order, then the slack 0.
        slots.set_lane(0, &model, &tensions([0.0, 0.0, 2.0, 1.0]));
        assert_eq!(slots.tendon[0][..4], [2, 1, 3, 0]);
        assert_eq!(slots.tensions[..4], [2.0, 0.0, 1.0, 0.0]);
        assert_eq!(slots.offsets[0], model.tendon_offsets[2]);
        assert_eq!(slots.hats[3], model.tendon_hats[0]);
        // All taut: the model's order.
        slots.set_lane(0, &model, &tensions([1.0, 1.0, 1.0, 1.0]));
        assert_eq!(slots.tendon[0][..4], [0, 1, 2, 3]);
    }
}
