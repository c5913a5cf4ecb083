//! The single-TDCR solver against closed forms and symmetry (MODEL.md §2, §8, §9).

mod common;

use common::{bare_leg, leg_with, reference_tdcr};
use nalgebra::Vector3;
use tdpcr::Tdcr;
use tdpcr::design::Tendon;
use tdpcr::tdcr::{TdcrSolver, TendonControl, TipWrench};

const NO_GRAVITY: (f64, f64, f64) = (0.0, 0.0, 0.0);

fn one_tendon(end: f64) -> Tdcr {
    leg_with(
        vec![Tendon {
            angle: 0.0,
            offset: 0.005,
            end,
        }],
        NO_GRAVITY,
    )
}

#[test]
fn one_tendon_bends_the_rod_at_constant_curvature() {
    let robot = one_tendon(0.145);
    let mut solver = TdcrSolver::new(&robot);
    let ei = solver.model().bending_stiffness();
    let ea = solver.model().axial_stiffness();
    let len = robot.leg.length;
    for tau in [0.5, 3.0, 6.0] {
        let sol = solver
            .solve(
                &TendonControl::Tension(vec![tau]),
                &TipWrench::default(),
                None,
            )
            .unwrap();
        let u_y = tau * 0.005 / ei;
        let v3 = 1.0 - tau / ea;
        let expected = Vector3::new(1.0 - (u_y * len).cos(), 0.0, (u_y * len).sin()) * (v3 / u_y);
        let err = (sol.tip.position - expected).norm();
        assert!(err <= 1e-6, "tau = {tau} N: tip error {err:.3e} m");
        assert!(
            (sol.state.u0[1] - u_y).abs() <= 1e-6 * u_y,
            "u_y {} vs {u_y}",
            sol.state.u0[1]
        );
        assert!(
            (sol.state.v0[2] - v3).abs() <= 1e-12,
            "v3 {} vs {v3}",
            sol.state.v0[2]
        );
        // Towards the tendon: +x.
        assert!(sol.tip.position.x > 0.0);
    }
}

#[test]
fn a_small_tip_force_deflects_like_a_cantilever() {
    let robot = Tdcr {
        gravity: NO_GRAVITY,
        leg: bare_leg(),
    };
    let mut solver = TdcrSolver::new(&robot);
    let ei = solver.model().bending_stiffness();
    let len = robot.leg.length;
    let force = 1e-3;
    let wrench = TipWrench {
        force: Vector3::new(force, 0.0, 0.0),
        moment: Vector3::zeros(),
    };
    let sol = solver
        .solve(&TendonControl::Tension(vec![]), &wrench, None)
        .unwrap();
    let expected = force * len.powi(3) / (3.0 * ei);
    let deflection = sol.tip.position.x;
    assert!(
        (deflection - expected).abs() <= 0.01 * expected,
        "deflection {deflection:.4e} m vs F L^3/(3 E I) = {expected:.4e} m"
    );
}

#[test]
fn the_rod_beyond_a_tendon_end_stays_straight() {
    let len = 0.145;
    let robot = one_tendon(len / 2.0);
    let mut solver = TdcrSolver::new(&robot);
    let sol = solver
        .solve(
            &TendonControl::Tension(vec![3.0]),
            &TipWrench::default(),
            None,
        )
        .unwrap();
    let shape = &sol.shape;
    let beyond: Vec<usize> = (0..shape.arcs.len())
        .filter(|&i| shape.arcs[i] > len / 2.0)
        .collect();
    assert!(beyond.len() >= 6);
    let first = beyond[0];
    let tangent = shape.rotations[first] * Vector3::z();
    for &i in &beyond {
        assert!(
            (shape.rotations[i] - shape.rotations[first]).norm() < 1e-9,
            "rotation changes at s = {}",
            shape.arcs[i]
        );
        let expected = shape.positions[first] + tangent * (shape.arcs[i] - shape.arcs[first]);
        assert!(
            (shape.positions[i] - expected).norm() < 1e-9,
            "not on a line at s = {}",
            shape.arcs[i]
        );
    }
    // ... while the first half is bent.
    let bend = (shape.rotations[first] * Vector3::z()).angle(&Vector3::z());
    assert!(bend > 0.3, "first half bent by only {bend} rad");
}

#[test]
fn zero_displacement_and_no_pretension_give_the_straight_rod() {
    let robot = reference_tdcr();
    let mut solver = TdcrSolver::new(&robot);
    let sol = solver
        .solve(
            &TendonControl::Displacement(vec![0.0, 0.0]),
            &TipWrench::default(),
            None,
        )
        .unwrap();
    assert!(
        sol.tip.position.xy().norm() < 1e-12,
        "tip {}",
        sol.tip.position
    );
    assert!((sol.tip.position.z - 0.145).abs() < 1e-5);
    assert_eq!(sol.tensions, vec![0.0, 0.0]);
}

#[test]
fn an_antagonistic_pair_gives_mirror_images_and_the_released_tendon_goes_slack() {
    let robot = reference_tdcr();
    let mut solver = TdcrSolver::new(&robot);
    let d = 0.004;
    let w = TipWrench::default();
    let a = solver
        .solve(&TendonControl::Displacement(vec![-d, d]), &w, None)
        .unwrap();
    let b = solver
        .solve(&TendonControl::Displacement(vec![d, -d]), &w, None)
        .unwrap();
    assert!(a.tip.position.x > 0.03);
    assert!((a.tip.position.x + b.tip.position.x).abs() < 1e-9);
    assert!((a.tip.position.z - b.tip.position.z).abs() < 1e-9);
    assert!(a.tip.position.y.abs() < 1e-12 && b.tip.position.y.abs() < 1e-12);
    assert!((a.tensions[0] - b.tensions[1]).abs() < 1e-7);
    for (p, q) in a.shape.positions.iter().zip(&b.shape.positions) {
        assert!((p.x + q.x).abs() < 1e-9 && (p.z - q.z).abs() < 1e-9);
    }
    assert_eq!(
        a.tensions[1], 0.0,
        "the released tendon must report zero tension"
    );
    assert!(a.slacks[1] > 1e-4, "slack {}", a.slacks[1]);
    assert_eq!(a.slacks[0], 0.0);
}

#[test]
fn the_reference_pull_converges_cold_in_few_iterations_to_the_model_md_answer() {
    // MODEL.md §9: Δℓ = (−5 mm, +5 mm), gravity along −z, no pretension:
    // τ ≈ (3.20 N, 0), released tendon slack by ≈ 0.49 mm, tip ≈ (0.062, 0, 0.126) m.
    let robot = reference_tdcr();
    let mut solver = TdcrSolver::new(&robot);
    let sol = solver
        .solve(
            &TendonControl::Displacement(vec![-0.005, 0.005]),
            &TipWrench::default(),
            None,
        )
        .unwrap();
    assert!(
        sol.report.iterations <= 8,
        "{} iterations",
        sol.report.iterations
    );
    assert!(sol.report.residual_norm <= 1e-10);
    assert!(
        (sol.tensions[0] - 3.20).abs() < 0.01,
        "tension {}",
        sol.tensions[0]
    );
    assert!(
        (sol.slacks[1] - 0.49e-3).abs() < 0.01e-3,
        "slack {}",
        sol.slacks[1]
    );
    assert!(
        (sol.tip.position - Vector3::new(0.062, 0.0, 0.126)).norm() < 1e-3,
        "tip {}",
        sol.tip.position
    );
    eprintln!("residual history: {:?}", sol.residual_history);
}

#[test]
fn full_newton_steps_with_the_exact_jacobian_converge_quadratically() {
    // From the solution x*, perturb by e0 and take one plain Newton step: the new error
    // must be O(e0²). With an inexact Jacobian it would only shrink linearly.
    let robot = reference_tdcr();
    let mut solver = TdcrSolver::new(&robot);
    let control = TendonControl::Displacement(vec![-0.005, 0.005]);
    let w = TipWrench::default();
    let sol = solver.solve(&control, &w, None).unwrap();
    let x_star = pack(&sol.state);
    // Scale: γ ~ 1, u ~ 1/L, v ~ 1e-4.
    let scale = nalgebra::DVector::from_vec(vec![1.0, 1.0, 6.9, 6.9, 6.9, 1e-4, 1e-4, 1e-4]);
    let direction = nalgebra::DVector::from_vec(vec![0.3, -0.2, 0.5, -0.4, 0.2, 0.6, -0.3, 0.1]);
    let mut constants = vec![];
    for e0 in [1e-2, 3e-3, 1e-3] {
        let x0 = &x_star + direction.component_mul(&scale) * e0;
        let (r, j) = solver
            .residual_and_jacobian(&control, &w, &unpack(&x0))
            .unwrap();
        let x1 = &x0 - j.lu().solve(&r).unwrap();
        let e1 = (&x1 - &x_star).component_div(&scale).norm();
        let e0n = direction.norm() * e0;
        constants.push(e1 / (e0n * e0n));
    }
    eprintln!("e1 / e0^2 = {constants:?}");
    // Quadratic: the constant stays bounded (a linear rate would make it grow 10x per row).
    assert!(constants[2] < 3.0 * constants[0], "{constants:?}");
}

fn pack(s: &tdpcr::tdcr::TdcrState) -> nalgebra::DVector<f64> {
    nalgebra::DVector::from_iterator(8, s.gammas.iter().chain(&s.u0).chain(&s.v0).copied())
}

fn unpack(x: &nalgebra::DVector<f64>) -> tdpcr::tdcr::TdcrState {
    tdpcr::tdcr::TdcrState {
        gammas: vec![x[0], x[1]],
        u0: [x[2], x[3], x[4]],
        v0: [x[5], x[6], x[7]],
    }
}

#[test]
fn a_two_segment_robot_solves_cold_in_displacement_mode() {
    let robot = Tdcr::from_ron_file(common::design_path("tdcr_two_segment.ron")).unwrap();
    let mut solver = TdcrSolver::new(&robot);
    let control = TendonControl::Displacement(vec![-0.003, 0.001, 0.001, -0.004, 0.0, 0.002]);
    let sol = solver.solve(&control, &TipWrench::default(), None).unwrap();
    assert!(sol.report.residual_norm <= 1e-10);
    // A warm start from the solution converges immediately.
    let again = solver
        .solve(&control, &TipWrench::default(), Some(&sol.state))
        .unwrap();
    assert_eq!(again.report.iterations, 0);
}

#[test]
fn the_default_step_count_is_accurate_to_a_millionth_of_the_length() {
    let robot = reference_tdcr();
    let mut fine = robot.clone();
    fine.leg.integration_steps = robot.leg.integration_steps * 8;
    let control = TendonControl::Displacement(vec![-0.01, 0.01]);
    let w = TipWrench {
        force: Vector3::new(0.1, 0.05, 0.0),
        moment: Vector3::zeros(),
    };
    let coarse = TdcrSolver::new(&robot).solve(&control, &w, None).unwrap();
    let reference = TdcrSolver::new(&fine).solve(&control, &w, None).unwrap();
    let err = (coarse.tip.position - reference.tip.position).norm();
    assert!(
        err <= 1e-6 * robot.leg.length,
        "tip error {err:.2e} m at {} steps",
        robot.leg.integration_steps
    );
}

/// A leg bent or twisted further than its integration steps can follow is an error
/// (`SolveError::UnderResolved`), not a converged solution with a tip frame that is no
/// rotation; with enough steps the same solve converges to a proper frame.
#[test]
fn a_leg_the_steps_cannot_follow_is_an_under_resolved_error() {
    use tdpcr::error::{Error, MAX_FRAME_DRIFT, SolveError, frame_drift};
    let robot = reference_tdcr();
    let pulls = [
        (
            TendonControl::Tension(vec![40.0, 0.0]),
            TipWrench::default(),
        ),
        (
            TendonControl::Tension(vec![0.0, 0.0]),
            TipWrench {
                force: Vector3::zeros(),
                moment: Vector3::new(0.0, 0.0, 0.3),
            },
        ),
    ];
    for (control, w) in &pulls {
        match TdcrSolver::new(&robot).solve(control, w, None) {
            Err(Error::Solve(SolveError::UnderResolved { drift, steps })) => {
                assert!(drift > MAX_FRAME_DRIFT, "{drift}");
                assert_eq!(steps, robot.leg.integration_steps);
            }
            other => panic!("{control:?}: expected UnderResolved, got {other:?}"),
        }
    }
    let mut fine = robot.clone();
    fine.leg.integration_steps = 200;
    let sol = TdcrSolver::new(&fine)
        .solve(&pulls[0].0, &pulls[0].1, None)
        .unwrap();
    assert!(frame_drift(&sol.tip.rotation) < 1e-6);
    // A strong but resolved pull (10 N) stays a solution at the default steps.
    let sol = TdcrSolver::new(&robot)
        .solve(
            &TendonControl::Tension(vec![10.0, 0.0]),
            &TipWrench::default(),
            None,
        )
        .unwrap();
    assert!(frame_drift(&sol.tip.rotation) <= MAX_FRAME_DRIFT);
}
