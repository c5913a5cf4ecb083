//! The straight home guess of a cold start (MODEL.md §9): legs straight, tensions from
//! the constant-curvature estimate of each leg ([`crate::rod::cold_guess`]), and the
//! straight-leg pose or base translations that fit a given actuation or pose.

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::state::RobotState;
use crate::model::{Model, Pose};
use crate::rod::Wrench;
use crate::rod::cold_guess::{TendonControl, cold_guess_at};

/// The straight home guess (MODEL.md §9) for platform `pose` and actuation `q` under the
/// loads of `m`: legs straight, each carrying a third of `wrench`, tensions from the
/// constant-curvature estimate, base strains consistent with them.
pub fn home_guess(m: &Model, pose: &Pose, q: &[f64], wrench: &Wrench) -> RobotState {
    let share = Wrench {
        force: wrench.force / 3.0,
        moment: Vector3::zeros(),
    };
    let mut y_u = Vec::with_capacity(3 * m.n_leg_unknowns());
    for i in 0..3 {
        let d = m.tendon_displacements(i, q);
        let control = TendonControl::Displacement(d[..m.n_tendons()].to_vec());
        let g = cold_guess_at(&m.leg, &m.bases[i].rotation, &control, &share);
        y_u.extend(g.gammas);
        y_u.extend(g.u0);
        y_u.extend(g.v0);
    }
    RobotState {
        position: pose.position.into(),
        rotvec: Rotation3::from_matrix_unchecked(pose.rotation)
            .scaled_axis()
            .into(),
        q: q.to_vec(),
        y_u,
    }
}

/// Base translations that put straight legs' joints closest to the coupling points of
/// `pose`: q_t,i = t_i · (joint_i − home joint_i); bending zero.
pub fn straight_leg_translations(model: &Model, pose: &Pose) -> Vec<f64> {
    let mut q = vec![0.0; model.n_actuators()];
    for i in 0..3 {
        let joint = pose.position + pose.rotation * model.coupling_points[i];
        q[i * (model.pairs + 1) + model.pairs] =
            model.tangents[i].dot(&(joint - model.coupling_points[i]));
    }
    q
}

/// The platform pose that best fits straight legs on bases translated by q (Kabsch).
pub fn straight_leg_pose(model: &Model, q: &[f64]) -> Pose {
    let joints: Vec<Vector3<f64>> = (0..3)
        .map(|i| model.coupling_points[i] + model.tangents[i] * model.translation(i, q))
        .collect();
    let centroid = (joints[0] + joints[1] + joints[2]) / 3.0;
    let body_centroid =
        (model.coupling_points[0] + model.coupling_points[1] + model.coupling_points[2]) / 3.0;
    let mut h = Matrix3::zeros();
    for i in 0..3 {
        h += (model.coupling_points[i] - body_centroid) * (joints[i] - centroid).transpose();
    }
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u.expect("requested"), svd.v_t.expect("requested"));
    let mut d = Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let rotation = vt.transpose() * d * u.transpose();
    Pose {
        position: centroid - rotation * body_centroid,
        rotation,
    }
}
