//! [`LegModel`]: the quantities of one leg derived once from a validated [`Leg`].

use nalgebra::{Matrix3, Vector3};

use crate::design::{Leg, MAX_TENDONS};
use crate::rod::tableau::{Tableau, tableau};

/// A piece of the leg between two consecutive breakpoints (tendon ends, L).
#[derive(Debug, Clone, PartialEq)]
pub struct Interval {
    /// Arc length at the start \[m\].
    pub start: f64,
    /// Arc length at the end \[m\].
    pub end: f64,
    /// Fixed Runge–Kutta steps on this interval.
    pub steps: usize,
    /// Bit k set: tendon k runs through this interval.
    pub active: u32,
    /// Bit k set: tendon k is attached at `end` (its force/moment jump is applied there).
    pub terminating: u32,
}

/// One leg's stiffness, tendon routing and integration grid (MODEL.md §2), SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct LegModel {
    /// Rod length L \[m\].
    pub length: f64,
    /// Diagonal of K_se = diag(G A, G A, E A) \[N\].
    pub k_se: Vector3<f64>,
    /// Diagonal of K_bt = diag(E I, E I, G J) \[N·m²\].
    pub k_bt: Vector3<f64>,
    /// Number of tendons n_t.
    pub n_tendons: usize,
    /// Tendon offsets r_k in the body frame \[m\] (z = 0); entries beyond n_t are zero.
    pub tendon_offsets: [Vector3<f64>; MAX_TENDONS],
    /// r̂_k, the skew matrices of the offsets.
    pub tendon_hats: [Matrix3<f64>; MAX_TENDONS],
    /// r̂_k r̂_kᵀ = |r_k|² I − r_k r_kᵀ.
    pub tendon_hat_squares: [Matrix3<f64>; MAX_TENDONS],
    /// Arc length where each tendon ends \[m\].
    pub tendon_ends: [f64; MAX_TENDONS],
    /// Tendon axial stiffness (EA)_t \[N\].
    pub tendon_stiffness: f64,
    /// Distributed weight f (world frame) \[N/m\].
    pub weight_per_length: Vector3<f64>,
    /// Integration grid.
    pub intervals: Vec<Interval>,
    /// The Runge–Kutta method of every step.
    pub tableau: &'static Tableau,
    /// Number of disks.
    pub n_disks: usize,
    /// Disk radius \[m\].
    pub disk_radius: f64,
}

impl LegModel {
    /// Derives the model from a leg that passed [`Leg::check`], under gravity `g` \[m/s²\].
    pub fn new(leg: &Leg, gravity: Vector3<f64>) -> Self {
        let e = leg.youngs_modulus;
        let g_mod = e / (2.0 * (1.0 + leg.poisson_ratio));
        let r = leg.backbone_radius;
        let area = std::f64::consts::PI * r * r;
        let inertia = area * r * r / 4.0;
        let mut tendon_offsets = [Vector3::zeros(); MAX_TENDONS];
        let mut tendon_ends = [0.0; MAX_TENDONS];
        for (k, t) in leg.tendons.iter().enumerate() {
            tendon_offsets[k] =
                Vector3::new(t.offset * t.angle.cos(), t.offset * t.angle.sin(), 0.0);
            tendon_ends[k] = t.end;
        }
        let tendon_hats = tendon_offsets.map(|r| crate::rod::rhs::hat(&r));
        let tendon_hat_squares = tendon_hats.map(|h| h * h.transpose());
        let total_mass = leg.backbone_mass + leg.disks.count as f64 * leg.disks.mass;
        Self {
            length: leg.length,
            k_se: Vector3::new(g_mod * area, g_mod * area, e * area),
            k_bt: Vector3::new(e * inertia, e * inertia, g_mod * 2.0 * inertia),
            n_tendons: leg.tendons.len(),
            tendon_offsets,
            tendon_hats,
            tendon_hat_squares,
            tendon_ends,
            tendon_stiffness: leg.tendon_stiffness,
            weight_per_length: gravity * (total_mass / leg.length),
            intervals: build_intervals(leg),
            tableau: tableau(leg.integrator),
            n_disks: leg.disks.count,
            disk_radius: leg.disks.radius,
        }
    }

    /// Bending stiffness E I \[N·m²\].
    pub fn bending_stiffness(&self) -> f64 {
        self.k_bt.x
    }

    /// Axial stiffness E A of the backbone \[N\].
    pub fn axial_stiffness(&self) -> f64 {
        self.k_se.z
    }

    /// Arc length of disk `j` (1-based: disk n_disks is at L) \[m\].
    pub fn disk_arc(&self, j: usize) -> f64 {
        self.length * j as f64 / self.n_disks as f64
    }

    /// Arc lengths \[m\] of the integration's knots: 0, then every step's end, as the
    /// integrator computes them (the arcs of [`LegShape::knots`](super::LegShape)).
    pub fn knot_arcs(&self) -> impl Iterator<Item = f64> + '_ {
        std::iter::once(0.0).chain(self.intervals.iter().flat_map(|iv| {
            let h = (iv.end - iv.start) / iv.steps as f64;
            (1..=iv.steps).map(move |k| {
                if k == iv.steps {
                    iv.end
                } else {
                    iv.start + k as f64 * h
                }
            })
        }))
    }

    /// Largest tendon offset \[m\] (0 without tendons).
    pub fn max_offset(&self) -> f64 {
        self.tendon_offsets[..self.n_tendons]
            .iter()
            .map(|r| r.norm())
            .fold(0.0, f64::max)
    }
}

/// Breakpoints are the tendon ends (where the strains jump) and L; steps are spread in
/// proportion to length, at least one per interval. Disks are not breakpoints: their
/// frames come from partial steps ([`LegModel::disk_arc`]).
fn build_intervals(leg: &Leg) -> Vec<Interval> {
    let len = leg.length;
    let tol = 1e-12 * len;
    let mut points = vec![len];
    for t in &leg.tendons {
        if points.iter().all(|s| (s - t.end).abs() > tol) {
            points.push(t.end);
        }
    }
    points.sort_by(f64::total_cmp);
    let mut intervals = Vec::with_capacity(points.len());
    let mut start = 0.0;
    for end in points {
        let mut active = 0u32;
        let mut terminating = 0u32;
        for (k, t) in leg.tendons.iter().enumerate() {
            if t.end > end - tol {
                active |= 1 << k;
            }
            if (t.end - end).abs() <= tol {
                terminating |= 1 << k;
            }
        }
        let steps = ((leg.integration_steps as f64 * (end - start) / len) - 1e-9)
            .ceil()
            .max(1.0) as usize;
        intervals.push(Interval {
            start,
            end,
            steps,
            active,
            terminating,
        });
        start = end;
    }
    intervals
}
