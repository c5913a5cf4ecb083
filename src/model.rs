//! [`Model`]: the parallel robot's quantities derived once from a validated [`Tdpcr`]
//! design (MODEL.md §1): base frames, coupling points, tendon displacement offsets.

use nalgebra::{Matrix3, Vector3};

use crate::design::{ActuationLimits, MAX_TENDONS, Tdpcr};
use crate::rod::{Frame, LegModel};

/// Most actuators of a valid design: 3 (1 + pairs) with at most [`MAX_TENDONS`] tendons
/// (MAX_TENDONS / 2 pairs) per leg ([`Model::n_actuators`]).
pub const MAX_ACTUATORS: usize = 3 * (1 + MAX_TENDONS / 2);

/// The parallel robot (three identical legs and a platform), SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// The leg, used three times.
    pub leg: LegModel,
    /// Antagonistic tendon pairs per leg (1: 6-DoF, 2: 9-DoF).
    pub pairs: usize,
    /// Base frame of each leg at zero translation (p_i(0) at q_t = 0, R_i(0)).
    pub bases: [Frame; 3],
    /// Unit leg tangent t_i (base z-axis, from base towards platform).
    pub tangents: [Vector3<f64>; 3],
    /// Coupling points ᵇp_ci in the platform frame \[m\].
    pub coupling_points: [Vector3<f64>; 3],
    /// L_c \[m\].
    pub coupling_offset: f64,
    /// Tendon displacement offset of the pretension, δ_pre \[m\].
    pub pretension_offset: f64,
    /// Pretension τ_pre \[N\].
    pub pretension: f64,
    /// Platform weight m_p g (world frame) \[N\].
    pub platform_weight: Vector3<f64>,
    /// Actuation limits.
    pub limits: ActuationLimits,
}

pub use crate::spatial::Pose;

impl Model {
    /// Derives the model from a design that passed [`Tdpcr::validate`].
    pub fn new(design: &Tdpcr) -> Self {
        let (gx, gy, gz) = design.gravity;
        let gravity = Vector3::new(gx, gy, gz);
        let leg = LegModel::new(&design.leg, gravity);
        let (a0, a1, a2) = design.coupling_angles;
        let radius = design.platform.side_length / 3f64.sqrt();
        let length = design.leg.length + design.coupling_offset;
        let (ca, sa) = (design.alpha.cos(), design.alpha.sin());
        let rz = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), design.beta);
        let mut bases = [Frame::identity(); 3];
        let mut tangents = [Vector3::zeros(); 3];
        let mut coupling_points = [Vector3::zeros(); 3];
        for (i, theta) in [a0, a1, a2].into_iter().enumerate() {
            let c = Vector3::new(theta.cos(), theta.sin(), 0.0) * radius;
            let t = (rz * Vector3::new(-theta.cos(), -theta.sin(), 0.0)) * ca - Vector3::z() * sa;
            let x0 = t.cross(&Vector3::z()).normalize();
            let x = x0 * design.psi.cos() + t.cross(&x0) * design.psi.sin();
            let y = t.cross(&x);
            bases[i] = Frame {
                position: c - t * length,
                rotation: Matrix3::from_columns(&[x, y, t]),
            };
            tangents[i] = t;
            coupling_points[i] = c;
        }
        let n_t = design.leg.tendons.len() as f64;
        let backbone_area = std::f64::consts::PI * design.leg.backbone_radius.powi(2);
        let pretension_offset = design.pretension
            * design.leg.length
            * (1.0 / design.leg.tendon_stiffness
                + n_t / (design.leg.youngs_modulus * backbone_area));
        Self {
            leg,
            pairs: design.leg.tendons.len() / 2,
            bases,
            tangents,
            coupling_points,
            coupling_offset: design.coupling_offset,
            pretension_offset,
            pretension: design.pretension,
            platform_weight: gravity * design.platform.mass,
            limits: design.actuation_limits.clone(),
        }
    }

    /// A copy with every gravity load (legs and platform) scaled by `scale` and the tendon
    /// pretension set to `pretension` \[N\] (for continuation).
    pub fn with_homotopy(&self, scale: f64, pretension: f64) -> Self {
        let mut m = self.clone();
        m.leg.weight_per_length *= scale;
        m.platform_weight *= scale;
        m.pretension_offset = pretension_offset(&m.leg, pretension);
        m.pretension = pretension;
        m
    }

    /// Tendons per leg n_t.
    pub fn n_tendons(&self) -> usize {
        self.leg.n_tendons
    }

    /// Length of the actuation vector q: per leg \[q_b (per pair), q_t\].
    pub fn n_actuators(&self) -> usize {
        3 * (self.pairs + 1)
    }

    /// Unknowns y_u per leg: γ (n_t), u(0) (3), v(0) (3).
    pub fn n_leg_unknowns(&self) -> usize {
        self.leg.n_tendons + 6
    }

    /// Indices of the tendon unknowns (γ or ζ) in the stacked y_u of the three legs, leg by
    /// leg.
    pub fn tendon_unknown_indices(&self) -> impl Iterator<Item = usize> + use<> {
        let (nu, nt) = (self.n_leg_unknowns(), self.n_tendons());
        (0..3).flat_map(move |leg| (0..nt).map(move |k| leg * nu + k))
    }

    /// Rows of the boundary residual b: 6 platform rows + per leg 6 + n_t (30 or 36).
    pub fn n_residuals(&self) -> usize {
        6 + 3 * self.n_leg_unknowns()
    }

    /// Base frame of leg i translated by q_t along its tangent.
    pub fn base_frame(&self, leg: usize, translation: f64) -> Frame {
        Frame {
            position: self.bases[leg].position + self.tangents[leg] * translation,
            rotation: self.bases[leg].rotation,
        }
    }

    /// Tendon length changes Δℓ_k of leg i for actuation q (MODEL.md §1):
    /// tendon 2j: −q_b,j − δ_pre; tendon 2j+1: +q_b,j − δ_pre.
    pub fn tendon_displacements(&self, leg: usize, q: &[f64]) -> [f64; MAX_TENDONS] {
        let mut d = [0.0; MAX_TENDONS];
        let base = leg * (self.pairs + 1);
        for j in 0..self.pairs {
            d[2 * j] = -q[base + j] - self.pretension_offset;
            d[2 * j + 1] = q[base + j] - self.pretension_offset;
        }
        d
    }

    /// Every |q_b| and |q_t| within its actuation limit (MODEL.md §1).
    pub fn within_limits(&self, q: &[f64]) -> bool {
        q.iter()
            .enumerate()
            .all(|(i, x)| x.abs() <= self.actuation_limit(i))
    }

    /// The limit of |q_i| \[m\]: the base translation's for each leg's last actuator,
    /// the tendon displacement's for its pairs.
    pub fn actuation_limit(&self, i: usize) -> f64 {
        if i % (self.pairs + 1) == self.pairs {
            self.limits.base_translation
        } else {
            self.limits.tendon_displacement
        }
    }

    /// Base translation q_t of leg i.
    pub fn translation(&self, leg: usize, q: &[f64]) -> f64 {
        q[leg * (self.pairs + 1) + self.pairs]
    }
}

/// δ_pre = τ_pre L (1/(EA)_t + n_t/(E A_b)) (MODEL.md §1).
fn pretension_offset(leg: &LegModel, pretension: f64) -> f64 {
    pretension
        * leg.length
        * (1.0 / leg.tendon_stiffness + leg.n_tendons as f64 / leg.axial_stiffness())
}
