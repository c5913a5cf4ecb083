//! The predictor of warm starts (MODEL.md §4): a solve whose guess is the last solution
//! with only its target changed starts from a prediction made with the Jacobian the last
//! Newton run factorized: the first-order (tangent) prediction from the last solution,
//! or, on a smooth path of targets, the extrapolation of the last solutions (up to
//! [`PREDICTOR_POINTS`]) corrected to first order for where the new target leaves the
//! extrapolated path ([`extrapolated_start`]).

use std::borrow::Cow;

use nalgebra::{DVector, Rotation3, Vector3};

use super::Solver;
use super::shooting::{Problem, retract};
use super::state::RobotState;
use crate::model::Model;
use crate::rod::Wrench;

/// Solutions a path keeps for the predictor: the last five give a quartic extrapolation
/// (at least three are needed). Measured on the peer-style path, per step (median, then
/// iterations and residual evaluations), quadratic from three: 51–54 µs, 3.14, 4.26;
/// cubic from four: 48 µs, 2.70, 3.80; quartic from five: 37–39 µs, 2.20, 3.34; from six:
/// 37 µs, 1.91, 3.06 (the tangent prediction alone: 70 µs, 4.23, 5.34).
pub(super) const PREDICTOR_POINTS: usize = 5;
/// Length \[m\] that one radian of platform rotation counts for in distances between IK
/// targets (about the platform's coupling radius).
const ROTATION_LENGTH: f64 = 0.1;
/// Steps along a path of targets differ by at most this factor from each other for the
/// extrapolation (about equal steps, as a controller's or a planner's).
const STEP_RATIO: f64 = 2.0;
/// The new target lies within this fraction of its step from the target path
/// extrapolated from the last solutions' targets (a smooth path; a reversal or a corner
/// is not).
const PATH_DEVIATION: f64 = 0.25;

/// One solution on a path: its target (FK: q \[m\]; IK: position \[m\] and rotation vector
/// \[rad\]) and its unknowns in the solver's form.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct PathPoint {
    pub(super) target: Vec<f64>,
    pub(super) x: DVector<f64>,
}

/// What the Newton scratch's factorized Jacobian linearizes.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct LastSolve {
    /// The solution.
    pub(super) state: RobotState,
    /// The total wrench it was solved under.
    pub(super) wrench: Wrench,
    /// FK (true) or square IK (false).
    pub(super) forward: bool,
    /// This solution and up to [`PREDICTOR_POINTS`] − 1 before it on one path of warm
    /// solves (oldest first).
    pub(super) path: Vec<PathPoint>,
}

/// Whether `guess` is the last solution with only the target of `problem` changed
/// (FK: q; IK: the pose), under the same wrench.
pub(super) fn is_last_solution(
    solver: &Solver,
    problem: Problem,
    wrench: &Wrench,
    guess: &RobotState,
) -> bool {
    let Some(last) = solver.last.as_ref() else {
        return false;
    };
    let same_legs = last.wrench == *wrench && last.state.y_u == guess.y_u;
    match problem {
        Problem::Forward { .. } => {
            last.forward
                && same_legs
                && last.state.position == guess.position
                && last.state.rotvec == guess.rotvec
        }
        Problem::Inverse { .. } => !last.forward && same_legs && last.state.q == guess.q,
    }
}

/// The target of `problem` as a vector (FK: q; IK: position, rotation vector).
pub(super) fn target_vector(problem: Problem) -> Vec<f64> {
    match problem {
        Problem::Forward { q } => q.to_vec(),
        Problem::Inverse { pose } => {
            let r = Rotation3::from_matrix_unchecked(pose.rotation).scaled_axis();
            pose.position.iter().chain(r.iter()).copied().collect()
        }
    }
}

/// The prediction of the solution of `problem` from the last solve (see the module
/// documentation): FK \[δx; δy\] = −\[B_x B_u\]⁻¹ B_q δq, IK \[δq; δy\] = −\[B_q B_u\]⁻¹ B_x δx
/// (MODEL.md §4), with the exact Jacobian factorized in the last Newton iteration (near
/// the solution). `x` is the last solution in the solver's unknowns with the new target;
/// the prediction is returned in the same form.
pub(super) fn predict(solver: &Solver, problem: Problem, x: &DVector<f64>) -> Option<DVector<f64>> {
    let last = solver.last.as_ref()?;
    let extrapolated = solver
        .extrapolate_starts
        .then(|| extrapolated_start(&solver.model, problem, &last.path))
        .flatten();
    let (from, dq, dp, dtheta) = match extrapolated {
        Some((from, dq, dp, dtheta)) => (Cow::Owned(from), dq, dp, dtheta),
        None => {
            let (dq, dp, dtheta) = match problem {
                Problem::Forward { q } => {
                    let dq: Vec<f64> = q.iter().zip(&last.state.q).map(|(a, b)| a - b).collect();
                    (dq, Vector3::zeros(), Vector3::zeros())
                }
                Problem::Inverse { pose } => {
                    let from = last.state.pose();
                    let dtheta =
                        Rotation3::from_matrix_unchecked(pose.rotation * from.rotation.transpose())
                            .scaled_axis();
                    (Vec::new(), pose.position - from.position, dtheta)
                }
            };
            (Cow::Borrowed(x), dq, dp, dtheta)
        }
    };
    let mut rhs = DVector::zeros(solver.model.n_residuals());
    for (j, d) in dq.iter().enumerate() {
        rhs.axpy(-d, &solver.blocks.b_q.column(j), 1.0);
    }
    if let Problem::Inverse { .. } = problem {
        for c in 0..3 {
            rhs.axpy(-dp[c], &solver.blocks.b_x.column(c), 1.0);
            rhs.axpy(-dtheta[c], &solver.blocks.b_x.column(3 + c), 1.0);
        }
    }
    solver.newton.solve_with_last_jacobian(&mut rhs)?;
    let mut out = DVector::zeros(x.len());
    retract(problem, &from, &rhs, &mut out);
    Some(out)
}

/// The start of the higher-order prediction on a smooth path: the unknowns extrapolated
/// from the last solutions of `path` (three to [`PREDICTOR_POINTS`]; Lagrange, in the
/// distance travelled along the targets) and the new target's deviation from the
/// targets extrapolated alike (FK: δq; IK: δp, δθ), for the first-order correction.
/// `None` (the tangent prediction from the last solution then) unless there are at least
/// three points, every step (the new one included) is within [`STEP_RATIO`] of every
/// other, the new target lies near the extrapolated path ([`PATH_DEVIATION`]), and no
/// tendon switches between taut and slack along the points or in the extrapolation (the
/// solution is smooth in the target only between switches).
#[allow(clippy::type_complexity)]
fn extrapolated_start(
    model: &Model,
    problem: Problem,
    path: &[PathPoint],
) -> Option<(DVector<f64>, Vec<f64>, Vector3<f64>, Vector3<f64>)> {
    if path.len() < 3 {
        return None;
    }
    let target = target_vector(problem);
    let distance = |u: &[f64], v: &[f64]| -> f64 {
        let scale = |i: usize| match problem {
            Problem::Inverse { .. } if i >= 3 => ROTATION_LENGTH,
            _ => 1.0,
        };
        u.iter()
            .zip(v)
            .enumerate()
            .map(|(i, (p, q))| ((p - q) * scale(i)).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    // Distances travelled: s_0 = 0 at the oldest point, s at the new target.
    let steps: Vec<f64> = path
        .windows(2)
        .map(|w| distance(&w[0].target, &w[1].target))
        .chain(std::iter::once(distance(
            &path[path.len() - 1].target,
            &target,
        )))
        .collect();
    let (shortest, longest) = steps.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &s| {
        (lo.min(s), hi.max(s))
    });
    if !(steps.iter().all(|s| s.is_finite()) && shortest > 0.0 && longest <= STEP_RATIO * shortest)
    {
        return None;
    }
    let nodes: Vec<f64> = std::iter::once(0.0)
        .chain(steps.iter().scan(0.0, |s, d| {
            *s += d;
            Some(*s)
        }))
        .collect();
    let (nodes, s) = (&nodes[..path.len()], nodes[path.len()]);
    let weights: Vec<f64> = (0..nodes.len())
        .map(|i| {
            (0..nodes.len())
                .filter(|&j| j != i)
                .map(|j| (s - nodes[j]) / (nodes[i] - nodes[j]))
                .product()
        })
        .collect();
    // Σ_k w_k x_k entry by entry, the points in order (as an iterator's sum, which starts
    // from −0.0: −0.0 + a = a bit for bit), one point's slice at a time: entry by entry
    // through `of` it cost 7 k instructions per warm 9-DoF FK step (1.4 %).
    let combine = |of: fn(&PathPoint) -> &[f64]| -> Vec<f64> {
        let mut out: Vec<f64> = of(&path[0]).iter().map(|x| weights[0] * x).collect();
        for (p, w) in path.iter().zip(&weights).skip(1) {
            for (o, x) in out.iter_mut().zip(of(p)) {
                *o += w * x;
            }
        }
        out
    };
    let extrapolated_target = combine(|p| &p.target);
    let last_step = steps[steps.len() - 1];
    if distance(&target, &extrapolated_target) > PATH_DEVIATION * last_step {
        return None;
    }
    let x = DVector::from_vec(combine(|p| p.x.as_slice()));
    let head = x.len() - 3 * model.n_leg_unknowns();
    let taut = |v: &DVector<f64>, i: usize| v[head + i] > 0.0;
    let last = &path[path.len() - 1];
    let smooth = model.tendon_unknown_indices().all(|i| {
        let side = taut(&last.x, i);
        taut(&x, i) == side && path.iter().all(|p| taut(&p.x, i) == side)
    });
    if !smooth {
        return None;
    }
    let deviation: Vec<f64> = target
        .iter()
        .zip(&extrapolated_target)
        .map(|(t, e)| t - e)
        .collect();
    Some(match problem {
        Problem::Forward { .. } => (x, deviation, Vector3::zeros(), Vector3::zeros()),
        Problem::Inverse { pose } => {
            let r = Vector3::new(
                extrapolated_target[3],
                extrapolated_target[4],
                extrapolated_target[5],
            );
            let dtheta = Rotation3::from_matrix_unchecked(
                pose.rotation * Rotation3::new(r).matrix().transpose(),
            )
            .scaled_axis();
            let dp = Vector3::new(deviation[0], deviation[1], deviation[2]);
            (x, Vec::new(), dp, dtheta)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::Tdpcr;
    use crate::model::Pose;

    fn model() -> Model {
        let path = format!("{}/designs/lilge2022.ron", env!("CARGO_MANIFEST_DIR"));
        Model::new(&Tdpcr::from_ron_file(path).unwrap())
    }

    /// The direction of the FK test paths in q.
    const DIRECTION: [f64; 6] = [0.6, -0.8, 0.0, 0.0, 0.0, 0.0];

    fn along(t: f64) -> Vec<f64> {
        DIRECTION.iter().map(|d| d * t).collect()
    }

    /// Unknowns of the FK test paths: a polynomial of `degree` in the distance t along
    /// the path, every tendon taut.
    fn x_of(m: &Model, degree: i32, t: f64) -> DVector<f64> {
        let n = 6 + 3 * m.n_leg_unknowns();
        DVector::from_fn(n, |i, _| {
            1.0 + 0.1 * i as f64 + (0.5 - 0.01 * i as f64) * t + 3.0 * t.powi(degree)
        })
    }

    /// FK targets on a straight line at distances `s` \[m\] along it, unknowns
    /// [`x_of`]; with `switch`, tendon 0 of leg 0 slack at the oldest point.
    fn fk_path(m: &Model, s: &[f64], degree: i32, switch: bool) -> Vec<PathPoint> {
        s.iter()
            .enumerate()
            .map(|(k, &t)| {
                let mut x = x_of(m, degree, t);
                if switch && k == 0 {
                    x[6] = -1.0;
                }
                PathPoint {
                    target: along(t),
                    x,
                }
            })
            .collect()
    }

    #[test]
    fn the_extrapolated_start_is_exact_for_solutions_polynomial_along_a_straight_path() {
        let m = model();
        // Unequal steps (within STEP_RATIO): quadratic from three points, quartic from
        // five.
        for (s, degree) in [
            (&[0.0, 0.002, 0.005][..], 2),
            (&[0.0, 0.002, 0.005, 0.007, 0.0095][..], 4),
        ] {
            let path = fk_path(&m, s, degree, false);
            let t = s[s.len() - 1] + 0.0025;
            let q = along(t);
            let (x, dq, _, _) =
                extrapolated_start(&m, Problem::Forward { q: &q }, &path).expect("smooth");
            assert!((x - x_of(&m, degree, t)).amax() < 1e-12, "degree {degree}");
            assert!(dq.iter().all(|d| d.abs() < 1e-15), "{dq:?}");
        }
    }

    #[test]
    fn the_extrapolated_start_is_declined_off_a_smooth_path() {
        let m = model();
        let path = fk_path(&m, &[0.0, 0.002, 0.004], 2, false);
        let forward = |q: &Vec<f64>| extrapolated_start(&m, Problem::Forward { q }, &path);
        assert!(forward(&along(0.006)).is_some());
        // Back along the path (a reversal), a step 3× the others, a corner.
        assert!(forward(&along(0.002)).is_none());
        assert!(forward(&along(0.010)).is_none());
        assert!(forward(&vec![0.004 * 0.6, -0.004 * 0.8, 0.002, 0.0, 0.0, 0.0]).is_none());
        // Fewer than three points.
        let q = along(0.006);
        assert!(extrapolated_start(&m, Problem::Forward { q: &q }, &path[1..]).is_none());
        // A tendon that switched between taut and slack along the path.
        let switched = fk_path(&m, &[0.0, 0.002, 0.004], 2, true);
        assert!(extrapolated_start(&m, Problem::Forward { q: &q }, &switched).is_none());
    }

    #[test]
    fn the_ik_deviation_is_the_rotation_from_the_extrapolated_pose() {
        let m = model();
        let n = m.n_actuators() + 3 * m.n_leg_unknowns();
        // Poses along x with a rotation about z growing linearly: equal steps.
        let pose_at = |k: f64| Pose {
            position: Vector3::new(0.001 * k, 0.0, 0.0),
            rotation: *Rotation3::new(Vector3::new(0.0, 0.0, 0.002 * k)).matrix(),
        };
        let path: Vec<PathPoint> = (0..3)
            .map(|k| PathPoint {
                target: target_vector(Problem::Inverse {
                    pose: &pose_at(k as f64),
                }),
                x: DVector::from_element(n, 1.0 + k as f64),
            })
            .collect();
        let on_path = pose_at(3.0);
        let (x, _, dp, dtheta) =
            extrapolated_start(&m, Problem::Inverse { pose: &on_path }, &path).expect("smooth");
        assert!((x - DVector::from_element(n, 4.0)).amax() < 1e-12);
        assert!(dp.norm() < 1e-15 && dtheta.norm() < 1e-15, "{dp} {dtheta}");
        // Off the path by a rotation of 1e-5 rad about x (world frame).
        let mut off = on_path;
        off.rotation = *Rotation3::new(Vector3::new(1e-5, 0.0, 0.0)).matrix() * off.rotation;
        let (_, _, dp, dtheta) =
            extrapolated_start(&m, Problem::Inverse { pose: &off }, &path).expect("smooth");
        // (The step's length grows by ≈ (1e-6 m)²/(2 · 1 mm): the weights move the
        // extrapolated position along x by ≈ 5e-10 m.)
        assert!(dp.norm() < 1e-9, "{dp}");
        assert!(
            (dtheta - Vector3::new(1e-5, 0.0, 0.0)).norm() < 1e-9,
            "{dtheta}"
        );
    }
}
