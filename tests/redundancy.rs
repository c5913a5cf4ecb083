//! IK of the redundant (9-DoF) design within the actuation limits: QP steps (clarabel)
//! against the least-norm steps.

mod common;

use common::design_path;
use tdpcr::error::Error;
use tdpcr::kinetostatics::{RobotState, Solver};
use tdpcr::redundancy::{Objective, Redundancy};
use tdpcr::rod::Wrench;
use tdpcr::{StopReason, Tdpcr};

/// The ψ = 0 twin of the redundant reference design: the configurations below (pair 2
/// near its limit) were chosen on it.
fn design() -> Tdpcr {
    Tdpcr::from_ron_file(design_path("lilge2022_redundant_psi0.ron")).unwrap()
}

/// Largest |q_j| / limit_j (per leg [bend_x, bend_y, translation]).
fn limit_ratio(d: &Tdpcr, q: &[f64]) -> f64 {
    let l = &d.actuation_limits;
    q.iter()
        .enumerate()
        .map(|(j, x)| {
            x.abs()
                / if j % 3 == 2 {
                    l.base_translation
                } else {
                    l.tendon_displacement
                }
        })
        .fold(0.0, f64::max)
}

/// max_j |a_j − b_j|.
fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// A start with leg 1's y-bending at −9.8 mm (limit 10 mm) and a pose reached from it by
/// 2 mm more x-bending of leg 1 (so a solution within the limits exists).
fn start_and_target(s: &mut Solver) -> (RobotState, RobotState) {
    let w = Wrench::default();
    let home = s.solve_fk(&[0.0; 9], &w, None).unwrap().state;
    let mut q = vec![0.0; 9];
    q[1] = -0.0098;
    let start = s.solve_fk(&q, &w, Some(&home)).unwrap().state;
    q[0] = 0.002;
    let target = s.solve_fk(&q, &w, Some(&start)).unwrap().state;
    (start, target)
}

#[test]
fn least_norm_steps_leave_the_limits_where_qp_steps_stay_within_and_converge() {
    let d = design();
    let w = Wrench::default();
    let mut least_norm = Solver::new(&d).unwrap();
    let (start, target) = start_and_target(&mut least_norm);
    let pose = target.pose();
    let ln = least_norm.solve_ik(&pose, &w, Some(&start)).unwrap();
    let ratio_ln = limit_ratio(&d, &ln.state.q);
    assert!(
        ratio_ln > 1.05,
        "least-norm q within the limits: {:?}",
        ln.state.q
    );

    let mut strict = Solver::new(&d).unwrap();
    strict.redundancy = Redundancy::WithinLimits(Objective::LeastChange);
    let qp = strict.solve_ik(&pose, &w, Some(&start)).unwrap();
    let ratio_qp = limit_ratio(&d, &qp.state.q);
    assert!(
        ratio_qp <= 1.0 + 1e-12,
        "QP q outside the limits: {:?}",
        qp.state.q
    );
    assert!(qp.report.residual_norm <= 1e-10, "{:?}", qp.report);
    assert!(qp.report.iterations <= 10, "{:?}", qp.report);
    eprintln!(
        "least-norm: max |q|/limit {ratio_ln:.4}; QP: {ratio_qp:.4}, {} iterations, residual {:.1e}",
        qp.report.iterations, qp.report.residual_norm
    );
    // The QP's actuation really holds the pose: FK of it, from the start, returns it.
    let back = strict
        .solve_fk(&qp.state.q, &w, Some(&start))
        .unwrap()
        .state
        .pose();
    assert!((back.position - pose.position).norm() < 1e-9);
    // A different solution than the least-norm one, not the same one clipped.
    assert!((qp.state.q[1] - ln.state.q[1]).abs() > 1e-3);
}

#[test]
fn closest_to_a_reference_on_the_solution_set_returns_it() {
    let d = design();
    let w = Wrench::default();
    let mut s = Solver::new(&d).unwrap();
    let (start, target) = start_and_target(&mut s);
    s.redundancy = Redundancy::WithinLimits(Objective::ClosestTo(target.q.clone()));
    let sol = s.solve_ik(&target.pose(), &w, Some(&start)).unwrap();
    let dist = max_difference(&sol.state.q, &target.q);
    assert!(
        dist < 1e-9,
        "q {:?} vs reference {:?}",
        sol.state.q,
        target.q
    );
    // Least change from the start ends elsewhere (the reference mattered).
    s.redundancy = Redundancy::WithinLimits(Objective::LeastChange);
    let other = s.solve_ik(&target.pose(), &w, Some(&start)).unwrap();
    let moved = max_difference(&other.state.q, &target.q);
    assert!(moved > 1e-4, "{moved:.1e}");
}

/// A run towards a reference across a tendon's kink retries with one-sided steps, as
/// the least-change runs do, and a cold run from the reference that fails is tried again
/// from the least-change solution: the references below (leg 1's and leg 0's second
/// pair 2 mm from the least-change solution, on the reference design) were given up for
/// the least-change solution before, and now pull q by 1.6 mm towards them.
#[test]
fn a_reference_is_followed_not_given_up() {
    let d = Tdpcr::from_ron_file(design_path("lilge2022_redundant.ron")).unwrap();
    let w = Wrench::default();
    let mut s = Solver::new(&d).unwrap();
    let pose = tdpcr::Pose {
        position: nalgebra::Vector3::new(0.005, 0.0, -0.01),
        rotation: nalgebra::Matrix3::identity(),
    };
    s.redundancy = Redundancy::WithinLimits(Objective::LeastChange);
    let free = s.solve_ik(&pose, &w, None).unwrap().state.q;
    let mut reference = free.clone();
    reference[4] -= 0.002;
    s.redundancy = Redundancy::WithinLimits(Objective::ClosestTo(reference));
    let pulled = s.solve_ik(&pose, &w, None).unwrap().state.q;
    assert!(
        pulled[4] - free[4] < -1e-3,
        "q[4] {:.3e} against {:.3e} without the reference",
        pulled[4],
        free[4]
    );
    // Leg 0's second pair 2 mm off: the cold run from the reference failed at its first
    // QP step (the straight guess's leg unknowns), and the least-change solution came
    // back; the run from that solution's leg unknowns follows the reference.
    let mut reference = free.clone();
    reference[1] += 0.002;
    s.redundancy = Redundancy::WithinLimits(Objective::ClosestTo(reference));
    let pulled = s.solve_ik(&pose, &w, None).unwrap().state.q;
    assert!(
        pulled[1] - free[1] > 1e-3,
        "q[1] {:.3e} against {:.3e} without the reference",
        pulled[1],
        free[1]
    );
}

#[test]
fn a_pose_out_of_reach_within_the_limits_is_a_solve_error_not_a_violation() {
    let d = design();
    let w = Wrench::default();
    let mut s = Solver::new(&d).unwrap();
    let home = s.solve_fk(&[0.0; 9], &w, None).unwrap().state;
    // Translations of 104 mm (limit 100 mm): FK does not check limits.
    let beyond = [0.0, 0.0, 0.104, 0.0, 0.0, 0.104, 0.0, 0.0, 0.104];
    let target = s.solve_fk(&beyond, &w, Some(&home)).unwrap().state;
    s.redundancy = Redundancy::WithinLimits(Objective::LeastChange);
    let e = s.solve_ik(&target.pose(), &w, Some(&home)).unwrap_err();
    assert!(matches!(e, Error::Solve(_)), "{e}");
    assert!(e.to_string().contains("solve did not converge"), "{e}");
    // The default (least-norm) solver reaches it, outside the limits.
    let mut free = Solver::new(&d).unwrap();
    let sol = free.solve_ik(&target.pose(), &w, Some(&home)).unwrap();
    assert!(limit_ratio(&d, &sol.state.q) > 1.0);
}

#[test]
fn the_6_dof_design_ignores_the_redundancy_setting() {
    let d = Tdpcr::from_ron_file(design_path("lilge2022.ron")).unwrap();
    let w = Wrench::default();
    let mut a = Solver::new(&d).unwrap();
    let mut b = Solver::new(&d).unwrap();
    b.redundancy = Redundancy::WithinLimits(Objective::LeastChange);
    let pose = tdpcr::model::Pose::identity();
    let qa = a.solve_ik(&pose, &w, None).unwrap().state.q;
    let qb = b.solve_ik(&pose, &w, None).unwrap().state.q;
    assert_eq!(qa, qb);
}

/// Every IK loop (square Newton, least-norm, within limits) stops a run that fails its
/// progress check at the check's iteration.
#[test]
fn every_ik_loop_honours_the_progress_check() {
    use tdpcr::error::SolveError;
    use tdpcr::newton::ProgressCheck;
    let six = Tdpcr::from_ron_file(design_path("lilge2022.ron")).unwrap();
    let nine = design();
    let cases = [
        (&six, Redundancy::LeastNorm),
        (&nine, Redundancy::LeastNorm),
        (&nine, Redundancy::WithinLimits(Objective::LeastChange)),
    ];
    let w = Wrench::default();
    for (d, redundancy) in cases {
        let mut s = Solver::new(d).unwrap();
        let home = s
            .solve_fk(&vec![0.0; d.n_actuators()], &w, None)
            .unwrap()
            .state;
        let mut pose = home.pose();
        pose.position.z += 0.04;
        s.redundancy = redundancy.clone();
        // A reduction by 1e12 in one iteration is what a 4 cm step from home never makes.
        s.settings.progress_check = Some(ProgressCheck {
            iterations: 1,
            factor: 1e12,
        });
        match s.solve_ik_newton(&pose, &w, &home) {
            Err(Error::Solve(SolveError::NotConverged {
                iterations, reason, ..
            })) => {
                assert_eq!(iterations, 1, "{redundancy:?}");
                assert_eq!(reason, StopReason::TooLittleProgress, "{redundancy:?}");
            }
            other => panic!("{redundancy:?}: {other:?}"),
        }
        // Without the check the same step converges.
        s.settings.progress_check = None;
        assert!(
            s.solve_ik_newton(&pose, &w, &home).is_ok(),
            "{redundancy:?}"
        );
    }
}

/// A within-limits IK overwrites the solver's Jacobian blocks, so the warm FK after it
/// must not predict from the FK solution before it: it takes exactly the steps of a fresh
/// solver from the same start (before the fix it predicted with the IK's B_q).
#[test]
fn a_within_limits_ik_leaves_no_stale_prediction_for_the_next_warm_fk() {
    let d = design();
    let w = Wrench::default();
    let mut s = Solver::new(&d).unwrap();
    s.redundancy = Redundancy::WithinLimits(Objective::LeastChange);
    let (start, target) = start_and_target(&mut s);
    // The last solve is the FK at `target`; an IK at another pose comes between.
    s.solve_ik(&start.pose(), &w, Some(&target)).unwrap();
    let mut q = target.q.clone();
    q[0] += 0.001;
    let after_ik = s.solve_fk(&q, &w, Some(&target)).unwrap();
    let fresh = Solver::new(&d)
        .unwrap()
        .solve_fk(&q, &w, Some(&target))
        .unwrap();
    assert_eq!(after_ik.state, fresh.state);
    assert_eq!(
        after_ik.report.jacobian_evaluations,
        fresh.report.jacobian_evaluations
    );
}
