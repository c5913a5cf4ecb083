//! Convergence at the round-off floor (MODEL.md "Convergence at the round-off floor"): a
//! solve whose trust region collapses with ‖F‖₂ as small as double precision allows is
//! converged, at both ends of the scale; one that collapses far from a solution is not.

use nalgebra::Vector3;
use tdpcr::Tdcr;
use tdpcr::tdcr::{TdcrSolver, TendonControl, TipWrench};

/// The one-segment reference TDCR with every `(from, to)` text replacement applied.
fn edited_reference(edits: &[(&str, &str)]) -> Tdcr {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/designs/tdcr_one_segment.ron");
    let mut text = std::fs::read_to_string(path).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{from} not in {path}");
        text = text.replace(from, to);
    }
    Tdcr::from_ron_str(&text, "edited tdcr_one_segment.ron").unwrap()
}

/// A 0.5 m rod of 8 mm diameter (EA = 2.7 MN: round-off of its internal force ~ 6e-10 N).
fn half_metre_rod() -> Tdcr {
    edited_reference(&[
        ("0.145", "0.5"),
        ("backbone_radius: 0.0005", "backbone_radius: 0.004"),
    ])
}

/// A 1 mm rod of 20 µm diameter, tendons 40 µm off its axis.
fn millimetre_rod() -> Tdcr {
    edited_reference(&[
        ("0.145", "0.001"),
        ("backbone_radius: 0.0005", "backbone_radius: 0.00001"),
        ("offset: 0.005", "offset: 0.00004"),
        ("radius: 0.006", "radius: 0.00005"),
        ("backbone_mass: 0.0012", "backbone_mass: 1e-9"),
        ("mass: 0.0003", "mass: 1e-10"),
    ])
}

fn sideways(force: f64) -> TipWrench {
    TipWrench {
        force: Vector3::new(0.0, force, 0.0),
        moment: Vector3::zeros(),
    }
}

#[test]
fn a_half_metre_rod_under_a_hundred_newtons_converges_at_its_floor() {
    let robot = half_metre_rod();
    let control = TendonControl::Tension(vec![20.0, 0.0]);
    let mut solver = TdcrSolver::new(&robot);
    // The floor is the round-off of the integration: with 10 fifth-order steps it lies at
    // 9e-11 (below the tolerance) under 50 N, at 1.8e-10 under 100 N.
    let floor = solver.solve(&control, &sideways(100.0), None).unwrap();
    assert!(floor.report.converged_at_floor, "{:?}", floor.report);
    assert!(floor.report.residual_norm > solver.settings.tolerance);
    let mut loose = TdcrSolver::new(&robot);
    loose.settings.tolerance = 1e-9;
    let reference = loose.solve(&control, &sideways(100.0), None).unwrap();
    assert!(!reference.report.converged_at_floor);
    let gap = (floor.tip.position - reference.tip.position).norm();
    assert!(gap <= 1e-9 * robot.leg.length, "tip gap {gap:.2e} m");
}

#[test]
fn a_millimetre_rod_asked_beyond_round_off_converges_at_its_floor() {
    let robot = millimetre_rod();
    let control = TendonControl::Tension(vec![1e-3, 0.0]);
    let mut solver = TdcrSolver::new(&robot);
    // In test units (MODEL.md §9b): its force rows relative to F* = 0.085 N, whose
    // round-off floor ε·EA/F* is 4.4e-14.
    solver.settings.tolerance = 1e-17;
    let floor = solver.solve(&control, &sideways(5e-3), None).unwrap();
    assert!(floor.report.converged_at_floor, "{:?}", floor.report);
    let mut fine = TdcrSolver::new(&robot);
    fine.settings.tolerance = 1e-12;
    let reference = fine.solve(&control, &sideways(5e-3), None).unwrap();
    let gap = (floor.tip.position - reference.tip.position).norm();
    assert!(gap <= 1e-6 * robot.leg.length, "tip gap {gap:.2e} m");
}

#[test]
fn a_collapse_far_from_a_solution_still_fails() {
    let robot = edited_reference(&[
        ("0.145", "0.5"),
        ("backbone_radius: 0.0005", "backbone_radius: 0.002"),
    ]);
    let mut solver = TdcrSolver::new(&robot);
    let control = TendonControl::Tension(vec![20.0, 0.0]);
    let err = solver.solve(&control, &sideways(20.0), None).unwrap_err();
    assert!(err.to_string().contains("trust region collapsed"), "{err}");
}

/// The tip of `robot` under `control` and a sideways tip force, solved with `tolerance`.
fn tip(robot: &Tdcr, control: &TendonControl, force: f64, tolerance: f64) -> Vector3<f64> {
    let mut solver = TdcrSolver::new(robot);
    solver.settings.tolerance = tolerance;
    let sol = solver.solve(control, &sideways(force), None).unwrap();
    eprintln!(
        "tol {tolerance:.0e}: residual {:.2e} after {} iterations, at floor {}",
        sol.report.residual_norm, sol.report.iterations, sol.report.converged_at_floor
    );
    sol.tip.position
}

/// The default tolerance means the same relative accuracy on a millimetre rod under
/// millinewtons as on a metre-scale one: its tip within 1e-8 L of a solve 1e8 times
/// tighter. (The absolute SI test accepted it with the moment rows at 1e-10 N·m, 2e-4 of
/// its moment scale: a tip 1.3e-5 L off; now 1.9e-10 L.)
#[test]
fn a_millimetre_rod_under_millinewtons_is_as_accurate_as_a_large_one() {
    let robot = millimetre_rod();
    let control = TendonControl::Tension(vec![1e-3, 0.0]);
    let reference = tip(&robot, &control, 5e-4, 1e-17);
    let default = tip(&robot, &control, 5e-4, 1e-10);
    let error = (default - reference).norm() / robot.leg.length;
    eprintln!("millimetre rod: tip error {error:.2e} L");
    assert!(error <= 1e-8, "tip error {error:.2e} L");
}

/// A warm start with a non-finite value is refused by name (it ran Newton from a NaN
/// guess); a finite one of the other control mode is still ignored for the cold guess.
#[test]
fn a_non_finite_warm_start_is_refused_by_name() {
    let robot = edited_reference(&[]);
    let mut solver = TdcrSolver::new(&robot);
    let control = TendonControl::Tension(vec![0.5, 0.0]);
    let solved = solver.solve(&control, &TipWrench::default(), None).unwrap();
    let mut bad = solved.state.clone();
    bad.v0[2] = f64::NAN;
    let e = solver
        .solve(&control, &TipWrench::default(), Some(&bad))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("init.v0[2] = NaN: expected a finite number"),
        "{e}"
    );
    let other_mode = TendonControl::Displacement(vec![-1e-4, 1e-4]);
    assert!(
        solver
            .solve(&other_mode, &TipWrench::default(), Some(&solved.state))
            .is_ok()
    );
}
