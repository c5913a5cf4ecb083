//! Each bundled parallel design's own discretization (`DEFAULT_INTEGRATION_STEPS` = 10
//! fixed steps of Butcher's fifth-order method per leg; the optimizer's results keep
//! their RK4 at 26 steps) against a converged fine one (16× the steps), at the test
//! configurations of the benches (home, and strongly bent legs): the platform pose and every leg's tip frame must be within 1 µm (position, and rotation
//! times the leg length), issue 17's accuracy bound. Issue 17 allows fewer steps only
//! where this holds; BENCHMARKS.md ("Fewer integration steps", "A fifth-order
//! integrator", "Fewer steps against the legs' tip frames") has the measurements.

mod common;

use common::design_path;
use nalgebra::{Matrix3, Vector3};
use tdpcr::Tdpcr;
use tdpcr::kinetostatics::{RobotState, Solver};
use tdpcr::rod::Wrench;

/// A solved state with its legs' tip frames (position \[m\], orientation).
struct Solved {
    state: RobotState,
    tips: Vec<(Vector3<f64>, Matrix3<f64>)>,
}

/// The FK of `q` on `design` with `steps` integration steps per leg, from `start` if given
/// (else from home, then a warm step to q): the solved state and its legs' tip frames.
fn fk(design: &Tdpcr, steps: usize, q: &[f64], start: Option<&RobotState>) -> Solved {
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
    let state = solver.solve_fk(q, &w, Some(start)).unwrap().state;
    // The legs' frames at their disks, the last one at the tip.
    solver.record_shapes(true);
    solver.blocks_at(&state, &w).unwrap();
    let tips = solver
        .shapes()
        .unwrap()
        .iter()
        .map(|shape| {
            let position = shape.positions.last().expect("a leg shape has its tip");
            let rotation = shape.rotations.last().expect("a leg shape has its tip");
            (*position, *rotation)
        })
        .collect();
    Solved { state, tips }
}

/// The rotation angle \[rad\] between two orientations.
fn angle(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let dr = a.transpose() * b;
    let skew = Vector3::new(
        dr[(2, 1)] - dr[(1, 2)],
        dr[(0, 2)] - dr[(2, 0)],
        dr[(1, 0)] - dr[(0, 1)],
    );
    (0.5 * skew.norm()).asin()
}

/// Largest position error \[m\] and rotation error times the leg length \[m\] of the
/// default discretization at `q`, over the platform and the legs' tips.
fn errors(file: &str, q: &[f64]) -> (f64, f64) {
    let design = Tdpcr::from_ron_file(design_path(file)).unwrap();
    let steps = design.leg.integration_steps;
    let coarse = fk(&design, steps, q, None);
    // The fine solve starts from the coarse one: the same equilibrium branch.
    let fine = fk(&design, 16 * steps, q, Some(&coarse.state));
    let (a, b) = (coarse.state.pose(), fine.state.pose());
    let frames = [(a.position, a.rotation, b.position, b.rotation)]
        .into_iter()
        .chain(
            coarse
                .tips
                .iter()
                .zip(&fine.tips)
                .map(|(c, f)| (c.0, c.1, f.0, f.1)),
        );
    frames.fold((0.0f64, 0.0f64), |(dp, dr), (pa, ra, pb, rb)| {
        (
            dp.max((pa - pb).norm()),
            dr.max(angle(&ra, &rb) * design.leg.length),
        )
    })
}

#[test]
fn the_default_steps_put_the_platform_and_tips_within_a_micrometre_of_a_fine_discretization() {
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
        // The optimizer's bundled results (RK4 at 26 steps, their own geometry);
        // `pareto_max_margin` is the same candidate as `best_composite`.
        ("optimized/best_composite.ron", &six[..]),
        ("optimized/best_composite.ron", &six_bent[..]),
        ("optimized/pareto_max_isotropy.ron", &six[..]),
        ("optimized/pareto_max_isotropy.ron", &six_bent[..]),
        ("optimized/pareto_max_volume.ron", &six[..]),
        ("optimized/pareto_max_volume.ron", &six_bent[..]),
    ] {
        let (position, rotation) = errors(file, q);
        println!("{file} q = {q:?}: position {position:.2e} m, rotation × L {rotation:.2e} m");
        assert!(
            position < 1e-6 && rotation < 1e-6,
            "{file} at q = {q:?}: the default steps put the platform or a leg's tip \
             {position:.2e} m (position) and {rotation:.2e} m (rotation × L) from the fine \
             discretization"
        );
    }
}
