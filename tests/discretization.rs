//! The default discretization (`DEFAULT_INTEGRATION_STEPS` = 10 fixed steps of Butcher's
//! fifth-order method per leg) against a converged fine one (16× the steps): on every
//! bundled parallel design, at home and at the test configurations of the benches, the
//! platform pose must be within 1 µm (position, and rotation times the leg length).
//! Issue 17 allows fewer steps only where this holds; BENCHMARKS.md ("Fewer integration
//! steps", "A fifth-order integrator") has the measurements.

mod common;

use common::design_path;
use tdpcr::Tdpcr;
use tdpcr::kinetostatics::{RobotState, Solver};
use tdpcr::rod::Wrench;

/// The FK of `q` on `design` with `steps` integration steps per leg, from `start` if given
/// (else from home, then a warm step to q): the solved state.
fn fk(design: &Tdpcr, steps: usize, q: &[f64], start: Option<&RobotState>) -> RobotState {
    let mut d = design.clone();
    d.leg.integration_steps = steps;
    let mut solver = Solver::new(&d).unwrap();
    let w = Wrench::default();
    let home;
    let start = match start {
        Some(s) => s,
        None => {
            home = solver
                .solve_fk(&vec![0.0; q.len()], &w, None)
                .unwrap()
                .state;
            &home
        }
    };
    solver.solve_fk(q, &w, Some(start)).unwrap().state
}

/// Largest position error \[m\] and rotation error times the leg length \[m\] of the
/// default discretization at `q`.
fn errors(file: &str, q: &[f64]) -> (f64, f64) {
    let design = Tdpcr::from_ron_file(design_path(file)).unwrap();
    let steps = design.leg.integration_steps;
    let coarse = fk(&design, steps, q, None);
    // The fine solve starts from the coarse one: the same equilibrium branch.
    let fine = fk(&design, 16 * steps, q, Some(&coarse));
    let (a, b) = (coarse.pose(), fine.pose());
    let dr = a.rotation.transpose() * b.rotation;
    let skew = 0.5
        * nalgebra::Vector3::new(
            dr[(2, 1)] - dr[(1, 2)],
            dr[(0, 2)] - dr[(2, 0)],
            dr[(1, 0)] - dr[(0, 1)],
        )
        .norm();
    ((a.position - b.position).norm(), skew * design.leg.length)
}

#[test]
fn the_default_steps_are_within_a_micrometre_of_a_fine_discretization() {
    let six = [0.004, 0.02, -0.003, -0.01, 0.002, 0.03];
    let nine = [0.004, -0.002, 0.02, -0.003, 0.003, -0.01, 0.002, 0.0, 0.03];
    // Strongly bent legs (9 of the 10 mm tendon displacements), bases 5 cm apart: here
    // 13 RK4 steps would miss by 2.4 µm (rotation × L, measured).
    let six_bent = [-0.009, 0.05, 0.009, -0.05, 0.0, 0.0];
    let nine_bent = [-0.009, 0.004, 0.05, 0.009, -0.004, -0.05, 0.0, 0.006, 0.0];
    for (file, q) in [
        ("lilge2022.ron", &[0.0; 6][..]),
        ("lilge2022.ron", &six[..]),
        ("lilge2022.ron", &six_bent[..]),
        ("lilge2022_psi0.ron", &six[..]),
        ("lilge2022_psi0.ron", &six_bent[..]),
        ("lilge2022_redundant.ron", &[0.0; 9][..]),
        ("lilge2022_redundant.ron", &nine[..]),
        ("lilge2022_redundant.ron", &nine_bent[..]),
        ("lilge2022_redundant_psi0.ron", &nine[..]),
        ("lilge2022_redundant_psi0.ron", &nine_bent[..]),
    ] {
        let (position, rotation) = errors(file, q);
        println!("{file} q = {q:?}: position {position:.2e} m, rotation × L {rotation:.2e} m");
        assert!(
            position < 1e-6 && rotation < 1e-6,
            "{file} at q = {q:?}: the default steps are {position:.2e} m (position) and \
             {rotation:.2e} m (rotation × L) from the fine discretization"
        );
    }
}
