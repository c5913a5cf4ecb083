//! Forward and inverse kinetostatics of the parallel robot.

mod common;

use common::design_path;
use nalgebra::{Matrix3, Rotation3, Vector3};
use tdpcr::Tdpcr;
use tdpcr::error::Error;
use tdpcr::kinetostatics::{RobotState, Solver};
use tdpcr::model::{Model, Pose};
use tdpcr::rod::tendon::tension;
use tdpcr::rod::{LegEnd, LegScratch, LegStart, Wrench, integrate_leg};

fn solver(file: &str) -> Solver {
    Solver::new(&Tdpcr::from_ron_file(design_path(file)).unwrap()).unwrap()
}

/// max |q_a − q_b| \[m\].
fn max_q_difference(a: &RobotState, b: &RobotState) -> f64 {
    a.q.iter()
        .zip(&b.q)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// The angle \[rad\] between two orientations, resolved down to round-off: |sin θ| from
/// the skew part of a bᵀ. (`Rotation3::angle` takes acos of the trace, which cannot
/// resolve angles below √(2ε) ≈ 2.1e-8 rad: one ulp of the trace reads as 2.1e-8.)
fn rotation_error(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let d = a * b.transpose();
    Vector3::new(
        d[(2, 1)] - d[(1, 2)],
        d[(0, 2)] - d[(2, 0)],
        d[(1, 0)] - d[(0, 1)],
    )
    .norm()
        / 2.0
}

/// Platform equilibrium and joint conditions recomputed from fresh leg integrations,
/// independently of the boundary residual code. Returns the worst violation in SI units.
fn independent_check(model: &Model, state: &RobotState, wrench: &Wrench) -> f64 {
    let pose = state.pose();
    let nu = model.n_leg_unknowns();
    let nt = model.n_tendons();
    let mut force = Vector3::zeros();
    let mut moment = Vector3::zeros();
    let mut worst: f64 = 0.0;
    for i in 0..3 {
        let y = &state.y_u[i * nu..(i + 1) * nu];
        let mut tensions = [0.0; tdpcr::design::MAX_TENDONS];
        for k in 0..nt {
            tensions[k] = tension(y[k]);
        }
        let q_t = state.q[i * (model.pairs + 1) + model.pairs];
        let start = LegStart {
            base: tdpcr::rod::Frame {
                position: model.bases[i].position + model.tangents[i] * q_t,
                rotation: model.bases[i].rotation,
            },
            u0: Vector3::new(y[nt], y[nt + 1], y[nt + 2]),
            v0: Vector3::new(y[nt + 3], y[nt + 4], y[nt + 5]),
            tensions,
        };
        let mut end = LegEnd::zeros();
        integrate_leg(&model.leg, &start, &mut LegScratch::new(), &mut end, None).unwrap();
        let link = end.r * Vector3::z() * model.coupling_offset;
        let joint = end.p + link;
        let expected_joint = pose.position + pose.rotation * model.coupling_points[i];
        worst = worst.max((joint - expected_joint).norm());
        // No moment in the spherical joint.
        worst = worst.max((end.m + (-link).cross(&end.n)).norm());
        force += end.n;
        moment += (pose.rotation * model.coupling_points[i]).cross(&end.n);
    }
    worst = worst.max((force - wrench.force).norm());
    worst.max((moment - wrench.moment).norm())
}

#[test]
fn fk_at_home_converges_and_the_platform_is_in_equilibrium() {
    let mut s = solver("lilge2022.ron");
    let sol = s.solve_fk(&[0.0; 6], &Wrench::default(), None).unwrap();
    assert!(sol.report.residual_norm <= 1e-10);
    let total = s.total_wrench(&Wrench::default());
    let err = independent_check(s.model(), &sol.state, &total);
    assert!(err < 1e-9, "independent equilibrium check: {err:.2e}");
    // The platform sags under its weight.
    assert!(
        sol.state.position[2] < -0.005,
        "z = {}",
        sol.state.position[2]
    );
    for t in sol.tensions(s.model()).iter().flatten() {
        assert!(t.is_finite() && *t >= 0.0);
    }
}

#[test]
fn fk_with_an_external_wrench_balances_it() {
    let mut s = solver("lilge2022.ron");
    let home = s.solve_fk(&[0.0; 6], &Wrench::default(), None).unwrap();
    let extra = Wrench {
        force: Vector3::new(0.05, -0.02, 0.1),
        moment: Vector3::new(0.0, 0.0, 0.002),
    };
    let sol = s.solve_fk(&[0.0; 6], &extra, Some(&home.state)).unwrap();
    let err = independent_check(s.model(), &sol.state, &s.total_wrench(&extra));
    assert!(err < 1e-9, "independent equilibrium check: {err:.2e}");
}

#[test]
fn ik_of_an_fk_pose_returns_its_actuation_and_fk_of_that_returns_the_pose() {
    let mut s = solver("lilge2022.ron");
    let w = Wrench::default();
    let q = [0.004, 0.02, -0.003, -0.01, 0.002, 0.03];
    let fk = s.solve_fk(&q, &w, None).unwrap();
    let pose = fk.state.pose();
    // IK from a start away from the answer: actuation off by 2 mm / 5 mm.
    let mut start = fk.state.clone();
    for (k, x) in start.q.iter_mut().enumerate() {
        *x += if k % 2 == 0 { 0.002 } else { -0.005 };
    }
    let ik = s.solve_ik(&pose, &w, Some(&start)).unwrap();
    assert!(ik.report.iterations > 0);
    for (a, b) in ik.state.q.iter().zip(&q) {
        assert!((a - b).abs() < 1e-8, "IK q {:?} vs {q:?}", ik.state.q);
    }
    // FK of the IK actuation, from a perturbed pose, lands on the pose.
    let mut start = ik.state.clone();
    start.position[0] += 0.003;
    start.rotvec[2] += 0.02;
    let again = s.solve_fk(&ik.state.q, &w, Some(&start)).unwrap();
    let back = again.state.pose();
    assert!(
        (back.position - pose.position).norm() < 1e-9,
        "position error {:.2e}",
        (back.position - pose.position).norm()
    );
    let angle = rotation_error(&back.rotation, &pose.rotation);
    assert!(angle < 1e-9, "rotation error {angle:.2e} rad");
}

#[test]
fn permuting_the_legs_actuation_rotates_the_pose_by_120_degrees() {
    let mut s = solver("lilge2022.ron");
    let w = Wrench::default();
    let q = [0.003, 0.01, -0.002, -0.02, 0.001, 0.015];
    // Leg i+1 takes the actuation of leg i.
    let permuted = [q[4], q[5], q[0], q[1], q[2], q[3]];
    let a = s.solve_fk(&q, &w, None).unwrap();
    let b = s.solve_fk(&permuted, &w, None).unwrap();
    let rz = Rotation3::from_axis_angle(&Vector3::z_axis(), 2.0 * std::f64::consts::PI / 3.0);
    let pa = a.state.pose();
    let pb = b.state.pose();
    assert!(
        (rz * pa.position - pb.position).norm() < 1e-9,
        "{} vs {}",
        rz * pa.position,
        pb.position
    );
    // The platform's body frame is symmetric too: leg i+1's coupling point is Rz ᵇp_ci,
    // so the orientation is conjugated, R_b = Rz R_a Rzᵀ.
    assert!((rz.matrix() * pa.rotation * rz.matrix().transpose() - pb.rotation).norm() < 1e-9);
}

#[test]
fn warm_newton_converges_quadratically() {
    let mut s = solver("lilge2022.ron");
    let w = Wrench::default();
    let home = s.solve_fk(&[0.0; 6], &w, None).unwrap();
    // A 0.1 mm translation and 0.05 mm tendon step from the home solution, by plain
    // Newton (a Jacobian at every iterate) from the unpredicted start (a second solver,
    // which has not solved home itself).
    let q = [0.0002, 0.0004, 0.0, 0.0, 0.0, 0.0];
    let mut s = solver("lilge2022.ron");
    s.settings.chord_contraction = 0.0;
    let sol = s.solve_fk(&q, &w, Some(&home.state)).unwrap();
    let h = s.residual_history().to_vec();
    // A Jacobian at every iterate (the start and each accepted step but the last, whose
    // trial may carry one too).
    assert!(
        sol.report.jacobian_evaluations >= sol.report.iterations,
        "{:?}",
        sol.report
    );
    eprintln!("residual history {h:?}");
    assert!(
        sol.report.iterations >= 2 && sol.report.iterations <= 6,
        "{h:?}"
    );
    // Once the residual is small, each step at least squares it (relative to the start),
    // until the round-off floor (~1e-11 in these units) is reached.
    let r0 = h[0];
    let mut checked = 0;
    for k in 0..h.len() - 1 {
        let (e0, e1) = (h[k] / r0, h[k + 1] / r0);
        if e0 < 0.5 && h[k + 1] > 1e-10 {
            assert!(e1 <= 10.0 * e0 * e0, "not quadratic at step {k}: {h:?}");
            checked += 1;
        }
    }
    assert!(checked >= 1, "no step to check in {h:?}");
}

/// A warm step from the solver's own last solution starts from the tangent prediction
/// and finishes with chord steps: one Jacobian evaluation, and the same solution as
/// plain Newton from the unpredicted start. Where the Jacobian of the step before is
/// reused ([`Solver::reuse_jacobian`]) the steps need fewer Jacobian evaluations in all
/// and give the same solutions.
#[test]
fn warm_steps_from_the_last_solution_are_predicted() {
    let mut jacobians = [0, 0];
    for reuse in [false, true] {
        let w = Wrench::default();
        let mut s = solver("lilge2022.ron");
        s.reuse_jacobian = reuse;
        let mut state = s.solve_fk(&[0.0; 6], &w, None).unwrap().state;
        let mut plain = solver("lilge2022.ron");
        plain.settings.chord_contraction = 0.0;
        plain.reuse_jacobian = false;
        for k in 1..=4 {
            let mut pose = state.pose();
            pose.position += Vector3::new(0.001, -0.0005, 0.0002 * k as f64);
            pose.rotation = *Rotation3::new(Vector3::new(0.0, 0.01, 0.0)).matrix() * pose.rotation;
            let predicted = s.solve_ik(&pose, &w, Some(&state)).unwrap();
            let reference = plain.solve_ik(&pose, &w, Some(&state)).unwrap();
            if k > 1 {
                // (The first IK step follows an FK solve: no IK linearization to predict
                // from, no IK Jacobian to reuse.)
                jacobians[usize::from(reuse)] += predicted.report.jacobian_evaluations;
                if !reuse {
                    assert_eq!(
                        predicted.report.jacobian_evaluations, 1,
                        "{:?}",
                        predicted.report
                    );
                }
                assert!(
                    predicted.report.residual_evaluations < reference.report.residual_evaluations
                        || predicted.report.jacobian_evaluations
                            < reference.report.jacobian_evaluations,
                    "{:?} vs {:?}",
                    predicted.report,
                    reference.report
                );
            }
            let dq = max_q_difference(&predicted.state, &reference.state);
            assert!(
                dq < 1e-10,
                "reuse {reuse}, step {k}: q differs by {dq:.2e} m"
            );
            state = predicted.state;
        }
    }
    assert!(jacobians[1] < jacobians[0], "{jacobians:?}");
}

/// On a smooth path of equal steps (the peer-style path of issue 17), a warm step from the
/// last solution starts from the extrapolation of the last five solutions (MODEL.md
/// "Notes of the implementation"): its median start residual is 3.3e-8 (test units; the
/// tangent prediction alone: 2.7e-5), and each solution matches a plain Newton solve
/// from the last one.
#[test]
fn warm_steps_on_a_smooth_path_start_from_the_extrapolated_solutions() {
    let w = Wrench::default();
    let mut s = solver("lilge2022.ron");
    let mut plain = solver("lilge2022.ron");
    plain.settings.chord_contraction = 0.0;
    plain.reuse_jacobian = false;
    let mut state = s.solve_fk(&[0.0; 6], &w, None).unwrap().state;
    let path = tdpcr::sampling::ik_fine_path(&state.pose(), 200);
    let mut starts = Vec::new();
    for (k, pose) in path.iter().enumerate().take(40) {
        let sol = s.solve_ik(pose, &w, Some(&state)).unwrap();
        if k >= 4 {
            starts.push(s.residual_history()[0]);
            let reference = plain.solve_ik(pose, &w, Some(&state)).unwrap();
            let dq = max_q_difference(&sol.state, &reference.state);
            assert!(dq < 1e-10, "step {k}: q differs by {dq:.2e} m");
        }
        state = sol.state;
    }
    starts.sort_by(f64::total_cmp);
    let median = starts[starts.len() / 2];
    assert!(median < 1e-6, "median start residual {median:.2e}");
}

/// A warm step from the solver's last solution reuses its Jacobian (no evaluation of its
/// own, the solution within the tolerance); after [`Solver::forget_jacobian`] the same
/// step depends only on its guess and target: bit for bit what a fresh solver gives
/// (what keeps the workspace map independent of the thread schedule). Cold solves never
/// depend on the solve before.
#[test]
fn a_solve_after_forget_jacobian_does_not_depend_on_the_solve_before() {
    let w = Wrench::default();
    let fresh = || solver("lilge2022.ron");
    let home = fresh().solve_fk(&[0.0; 6], &w, None).unwrap().state;
    let target = |dx: f64| {
        let mut pose = home.pose();
        pose.position += Vector3::new(dx, 0.002, -0.001);
        pose
    };
    let (mut reusing, mut forgetting) = (fresh(), fresh());
    let mut first = None;
    for s in [&mut reusing, &mut forgetting] {
        first = Some(s.solve_ik(&target(0.002), &w, Some(&home)).unwrap().state);
    }
    let first = first.unwrap();
    forgetting.forget_jacobian();
    let step = |s: &mut Solver| s.solve_ik(&target(0.003), &w, Some(&first)).unwrap();
    let (reused, forgot, new) = (
        step(&mut reusing),
        step(&mut forgetting),
        step(&mut fresh()),
    );
    assert_eq!((&forgot.state, forgot.report), (&new.state, new.report));
    assert_eq!(reused.report.jacobian_evaluations, 0, "{:?}", reused.report);
    assert!(new.report.jacobian_evaluations >= 1, "{:?}", new.report);
    let dq = max_q_difference(&reused.state, &new.state);
    assert!(dq < 1e-10, "q differs by {dq:.2e} m");
    // A cold solve after a history is a fresh solver's cold solve.
    let cold = |s: &mut Solver| {
        s.solve_fk(&[0.001, 0.0, -0.001, 0.0, 0.0, 0.0], &w, None)
            .unwrap()
    };
    let (after, first_cold) = (cold(&mut reusing), cold(&mut fresh()));
    assert_eq!(
        (&after.state, after.report),
        (&first_cold.state, first_cold.report)
    );
}

#[test]
fn the_redundant_design_solves_fk_and_least_norm_ik() {
    let mut s = solver("lilge2022_redundant.ron");
    let sol = s.solve_fk(&[0.0; 9], &Wrench::default(), None).unwrap();
    let err = independent_check(s.model(), &sol.state, &s.total_wrench(&Wrench::default()));
    assert!(err < 1e-9, "{err:.2e}");
    // Least-norm IK of a displaced pose, warm and cold; FK of its q returns the pose.
    let w = Wrench::default();
    let mut pose = sol.state.pose();
    pose.position += Vector3::new(0.005, 0.0, 0.003);
    let warm = s.solve_ik(&pose, &w, Some(&sol.state)).unwrap();
    let cold = s.solve_ik(&pose, &w, None).unwrap();
    assert!(warm.report.iterations <= 8, "{:?}", warm.report);
    for ik in [&warm, &cold] {
        let err = independent_check(s.model(), &ik.state, &s.total_wrench(&w));
        assert!(err < 1e-9, "{err:.2e}");
        let mut start = ik.state.clone();
        start.position[0] += 0.002;
        let back = s
            .solve_fk(&ik.state.q, &w, Some(&start))
            .unwrap()
            .state
            .pose();
        assert!((back.position - pose.position).norm() < 1e-9);
        let angle = rotation_error(&back.rotation, &pose.rotation);
        assert!(angle < 1e-9, "{angle:.2e}");
    }
    // From the FK state, the least-norm change of q is small: 9 actuators share the motion.
    let dq: f64 = warm
        .state
        .q
        .iter()
        .zip(&sol.state.q)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(dq < 0.02, "|dq| = {dq}");
}

#[test]
fn least_norm_steps_from_the_last_factorization_repeat_going_back_and_forth() {
    let mut s = solver("lilge2022_redundant.ron");
    s.reuse_least_norm_factorization = true;
    let w = Wrench::default();
    let home = s.solve_ik(&Pose::identity(), &w, None).unwrap().state;
    let poses = [1e-3, 0.0].map(|x| Pose {
        position: Vector3::new(x, 0.0, 0.0),
        rotation: home.pose().rotation,
    });
    let (mut last, mut jacobians) = (home, 0);
    let mut at_home: Vec<Vec<f64>> = Vec::new();
    for cycle in 0..6 {
        for pose in &poses {
            let ik = s.solve_ik(pose, &w, Some(&last)).unwrap();
            let err = independent_check(s.model(), &ik.state, &s.total_wrench(&w));
            assert!(err < 1e-9, "cycle {cycle}: equilibrium {err:.2e}");
            if cycle > 0 {
                jacobians += ik.report.jacobian_evaluations;
            }
            last = ik.state;
        }
        at_home.push(last.q.clone());
    }
    // After the first cycle, steps are chord steps on the factorization of the first.
    assert_eq!(jacobians, 0, "Jacobians after the first cycle");
    // One linear map there and back: q at home repeats (fresh Jacobians creep by ≈ 4e-8 m
    // a cycle on this path), up to where each run stops under its tolerance (1e-10 on the
    // weighted residual): a run that stops at 9e-11 instead of 1e-11 lands 1.2e-11 m away.
    for q in &at_home[1..] {
        for (a, b) in q.iter().zip(&at_home[0]) {
            assert!(
                (a - b).abs() < 1e-10,
                "q at home {q:?} after {:?}",
                at_home[0]
            );
        }
    }
}

/// `Solver::stop_beyond_limits` ends a warm IK whose solution lies beyond the actuation
/// limits once an iteration has contracted tenfold, with that reason and less work than
/// the run that finishes, and changes nothing where the solution is within the limits:
/// rays out from the plane z = −30 mm in 6 mm steps, each step warm-started from the last
/// solution, solved with and without the stop until the solution leaves the limits.
#[test]
fn a_warm_ik_heading_beyond_the_limits_stops_early_and_no_other_changes() {
    use tdpcr::error::{SolveError, StopReason};
    let w = Wrench::default();
    let mut stopped = 0;
    for angle in [0.0_f64, 1.0, 2.0, 3.0, 4.0, 5.0] {
        let mut finishing = solver("lilge2022.ron");
        let mut stopping = solver("lilge2022.ron");
        stopping.stop_beyond_limits = true;
        let model = finishing.model().clone();
        let at = |r: f64| Pose {
            position: Vector3::new(r * angle.cos(), r * angle.sin(), -0.03),
            rotation: Matrix3::identity(),
        };
        let mut last = finishing.solve_ik(&at(0.0), &w, None).unwrap().state;
        stopping.solve_ik(&at(0.0), &w, None).unwrap();
        for step in 1..40 {
            let target = at(0.006 * step as f64);
            let Ok(finished) = finishing.solve_ik(&target, &w, Some(&last)) else {
                break;
            };
            let stop = stopping.solve_ik(&target, &w, Some(&last));
            if model.within_limits(&finished.state.q) {
                let same = stop.expect("a solution within the limits is found");
                let bits = |s: &RobotState| s.q.iter().map(|q| q.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&same.state),
                    bits(&finished.state),
                    "angle {angle}, step {step}"
                );
                last = finished.state;
                continue;
            }
            match stop {
                Err(Error::Solve(SolveError::NotConverged {
                    reason, iterations, ..
                })) => {
                    assert_eq!(reason, StopReason::BeyondActuationLimits);
                    assert!(iterations < finished.report.iterations, "angle {angle}");
                    stopped += 1;
                }
                // Converged before any iteration could stop it: the same solution.
                Ok(same) => assert_eq!(same.state.q, finished.state.q, "angle {angle}"),
                Err(e) => panic!("angle {angle}, step {step}: {e}"),
            }
            break;
        }
    }
    assert!(stopped > 0, "no run stopped early");
}

#[test]
fn bad_input_and_unreachable_poses_are_errors_not_panics() {
    let mut s = solver("lilge2022.ron");
    let w = Wrench::default();
    match s.solve_fk(&[0.0; 5], &w, None) {
        Err(Error::Input(v)) => assert!(
            v.to_string().contains("q = 5 values: expected 6 values"),
            "{v}"
        ),
        other => panic!("{other:?}"),
    }
    match s.solve_fk(&[0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0], &w, None) {
        Err(Error::Input(v)) => assert!(v.to_string().contains("q[1]"), "{v}"),
        other => panic!("{other:?}"),
    }
    let far = tdpcr::model::Pose {
        position: Vector3::new(0.0, 0.0, 0.6),
        rotation: nalgebra::Matrix3::identity(),
    };
    s.settings.max_iterations = 15;
    match s.solve_ik(&far, &w, None) {
        Err(Error::Solve(e)) => assert!(e.to_string().contains("did not converge"), "{e}"),
        Ok(sol) => panic!("an unreachable pose solved: {:?}", sol.state),
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn every_solve_checks_its_newton_settings_and_names_each_bad_one() {
    let mut s = solver("lilge2022.ron");
    s.settings.tolerance = -1.0;
    s.settings.max_iterations = 0;
    s.settings.chord_contraction = 1.5;
    s.settings.progress_check = Some(tdpcr::newton::ProgressCheck {
        iterations: 0,
        factor: 0.5,
    });
    let w = Wrench::default();
    let msg = s.solve_fk(&[0.0; 6], &w, None).unwrap_err().to_string();
    for part in [
        "settings.tolerance = -1: expected finite and > 0",
        "settings.max_iterations = 0: expected >= 1",
        "settings.chord_contraction = 1.5: expected in [0, 1)",
        "settings.progress_check.iterations = 0: expected >= 1",
        "settings.progress_check.factor = 0.5: expected finite and >= 1",
    ] {
        assert!(msg.contains(part), "{part:?} not in {msg}");
    }
    assert!(
        s.solve_ik(&tdpcr::model::Pose::identity(), &w, None)
            .is_err()
    );
}

#[test]
fn a_solver_is_made_only_for_a_valid_design_and_names_every_bad_value() {
    let mut d = Tdpcr::from_ron_file(design_path("lilge2022.ron")).unwrap();
    d.pretension = -1.0;
    d.gravity = (0.0, f64::NAN, 0.0);
    match Solver::new(&d) {
        Err(Error::Design(e)) => {
            let msg = e.to_string();
            assert!(msg.contains("pretension = -1"), "{msg}");
            assert!(msg.contains("gravity"), "{msg}");
        }
        Err(e) => panic!("unexpected {e}"),
        Ok(_) => panic!("an invalid design made a solver"),
    }
}

#[test]
fn per_call_settings_match_the_same_solver_settings_and_leave_them_alone() {
    let w = Wrench::default();
    let q = [0.002, 0.01, -0.001, 0.0, 0.0, 0.005];
    let per_call = tdpcr::newton::NewtonSettings {
        tolerance: 1e-8,
        chord_contraction: 0.0,
        ..Default::default()
    };
    let mut a = solver("lilge2022.ron");
    let defaults = a.settings;
    let by_call = a.solve_fk_with(&q, &w, None, &per_call).unwrap();
    assert_eq!(a.settings, defaults);
    let mut b = solver("lilge2022.ron");
    b.settings = per_call;
    let by_field = b.solve_fk(&q, &w, None).unwrap();
    assert_eq!(by_call.state, by_field.state);
    assert_eq!(by_call.report, by_field.report);
    let pose = by_field.state.pose();
    let ik_call = a
        .solve_ik_newton_with(&pose, &w, &by_call.state, &per_call)
        .unwrap();
    let ik_field = b.solve_ik_newton(&pose, &w, &by_field.state).unwrap();
    assert_eq!(ik_call.state, ik_field.state);
    assert_eq!(a.settings, defaults);
    let bad = tdpcr::newton::NewtonSettings {
        max_iterations: 0,
        ..per_call
    };
    match a.solve_ik_with(&pose, &w, None, &bad) {
        Err(Error::Input(v)) => {
            assert!(v.to_string().contains("settings.max_iterations = 0"), "{v}")
        }
        other => panic!("{other:?}"),
    }
}

/// The exact blocks of an analysis at a solution seed the next IK step's chord steps
/// ([`Solver::reuse_blocks_for_ik`]): no Jacobian evaluation of its own, and the
/// solution of a fresh solve.
#[test]
fn the_blocks_of_an_analysis_start_the_next_ik_step() {
    let w = Wrench::default();
    let mut s = solver("lilge2022.ron");
    let home = s.solve_fk(&[0.0; 6], &w, None).unwrap().state;
    let step = |state: &RobotState, dx: f64| {
        let mut pose = state.pose();
        pose.position += Vector3::new(dx, 0.0, 0.0);
        pose
    };
    let first = s
        .solve_ik(&step(&home, 0.001), &w, Some(&home))
        .unwrap()
        .state;
    let settings = tdpcr::analysis::AnalysisSettings::default();
    s.condition(&first, &w, &settings).unwrap();
    s.reuse_blocks_for_ik(&first);
    let target = step(&first, 0.001);
    let seeded = s.solve_ik(&target, &w, Some(&first)).unwrap();
    assert_eq!(seeded.report.jacobian_evaluations, 0, "{:?}", seeded.report);
    let fresh = solver("lilge2022.ron")
        .solve_ik(&target, &w, Some(&first))
        .unwrap();
    let dq = max_q_difference(&seeded.state, &fresh.state);
    assert!(dq < 1e-10, "q differs by {dq:.2e} m");
}

#[test]
fn cold_fk_ends_at_a_stable_equilibrium_where_newton_from_straight_legs_finds_an_unstable_one() {
    // Three seeded reachable draws of the ψ = 0 design (`sampling::seeded_reachable_actuations`,
    // seed 42: draws 3, 8 and 21) where Newton from the straight guess converges to an
    // unstable equilibrium (before 2026-11-26 the cold FK returned it for draws 3 and 21);
    // the platform position of each on the branch from q = 0, where the ramp goes.
    let draws = [
        (
            [
                0.0038835514864212217,
                0.08230470277809979,
                0.0068103296417505385,
            ],
            [
                0.07659215708826289,
                0.005643125782877083,
                0.0762095386442079,
            ],
            [
                0.016369885187249814,
                0.0028491101993725165,
                -0.08633694754424935,
            ],
        ),
        (
            [
                0.0034580410553494835,
                0.05006483322237755,
                0.006703903791703263,
            ],
            [
                0.0754254668128517,
                0.0063361017251020255,
                0.04746855261174367,
            ],
            [
                0.013552202718101487,
                0.014764184481939566,
                -0.06849795556522668,
            ],
        ),
        (
            [
                0.0026623531173862094,
                0.050433039053946825,
                0.00539647535149985,
            ],
            [
                0.0466203082162972,
                0.009158787341173476,
                0.04649312987141559,
            ],
            [
                0.010831222046573467,
                0.03155739398934482,
                -0.04871230778243334,
            ],
        ),
    ];
    let mut s = solver("lilge2022_psi0.ron");
    let w = Wrench::default();
    for (head, tail, branch) in draws {
        let q: Vec<f64> = head.iter().chain(&tail).copied().collect();
        let solution = s.solve_fk(&q, &w, None).unwrap();
        let analysis = s.analyze(&solution.state, &w, &Default::default()).unwrap();
        assert!(
            analysis.stability.stable,
            "q = {q:?}: eigenvalues {:?}",
            analysis.stability.eigenvalues
        );
        let position = Vector3::from(solution.state.position);
        assert!(
            (position - Vector3::from(branch)).norm() < 1e-6,
            "q = {q:?}: at {position:?}"
        );
    }
}
