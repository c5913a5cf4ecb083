//! The 9-DoF design's IK where its path takes tendons through their kinks.
//!
//! On circles of the platform in 1 mm steps the solutions of the reference 9-DoF design
//! reach states where one tendon pair of a leg is slack on both sides or a taut tendon
//! is about to go slack (ζ ≈ 0). A Newton step with the slope of the side a tendon
//! leaves overshoots beyond its kink, and the line search crawled towards the kink until
//! it failed: 4 of the 126 least-norm steps of the flat 10 mm circle below and 4 of the
//! tilted one, 3 and 2 within the limits, before 2026-11-28. With one-sided steps across
//! the kinks (`Solver::across_kinks`, MODEL.md "Least-norm steps across tendon kinks":
//! the default least-norm steps from the start, every rule in the retry of a failed
//! run) every step converges, none jumps (q moves by less than 1.5 mm in a 1 mm step, as
//! the steps away from the kinks do), and within the limits q stays within them; the
//! least-norm steps take fewer than 1 000 evaluations a circle (3 609 before, with 4
//! failed steps uncounted). Every solution is analysed: the least-norm steps hold
//! tendons exactly at their kinks (61 and 110 of the 126 solutions of the two circles),
//! which a state reports just taut (γ = 1e-8), so that the analysis exists there.

mod common;

use common::design_path;
use nalgebra::{Rotation3, Vector3};
use tdpcr::Tdpcr;
use tdpcr::analysis::AnalysisSettings;
use tdpcr::kinetostatics::Solver;
use tdpcr::model::Pose;
use tdpcr::redundancy::{Objective, Redundancy};
use tdpcr::rod::Wrench;

/// Follows a circle of `radius` \[m\] around home with `solver`, its plane tilted by
/// `tilt` \[rad\] about x: a spiral out to it over one lap, then one lap on it, in steps
/// of about 1 mm. Returns the failed steps, the largest change of q \[m\] of a step
/// after the first, the largest |q_j| / limit_j of the solutions and the residual
/// evaluations of the converged steps. Every solution is analysed too: the failed
/// analyses are added to the failures, and `at_kink` counts the solutions with a tendon
/// at its kink (|γ| < 1e-6: tension below 1e-12 N, slack below 1e-12 m).
fn circle(
    solver: &mut Solver,
    radius: f64,
    tilt: f64,
    at_kink: &mut usize,
) -> (Vec<String>, f64, f64, usize) {
    let w = Wrench::default();
    let home = solver.solve_ik(&Pose::identity(), &w, None).unwrap().state;
    let tilted = Rotation3::from_axis_angle(&Vector3::x_axis(), tilt).into_inner();
    let steps = (std::f64::consts::TAU * radius / 1e-3).ceil() as usize;
    let mut state = home.clone();
    let (mut failed, mut largest, mut reach) = (Vec::new(), 0.0_f64, 0.0_f64);
    let mut evaluations = 0;
    for k in 1..=2 * steps {
        let t = k as f64 / steps as f64;
        let (r, angle) = (radius * t.min(1.0), std::f64::consts::TAU * t);
        let pose = Pose {
            position: Vector3::new(r * angle.cos(), r * angle.sin(), 0.0),
            rotation: tilted * home.pose().rotation,
        };
        match solver.solve_ik(&pose, &w, Some(&state)) {
            Ok(s) => {
                if k > 1 {
                    let dq = s.state.q.iter().zip(&state.q);
                    largest = dq.fold(largest, |m, (a, b)| m.max((a - b).abs()));
                }
                let model = solver.model();
                reach = (0..s.state.q.len())
                    .map(|j| s.state.q[j].abs() / model.actuation_limit(j))
                    .fold(reach, f64::max);
                evaluations += s.report.residual_evaluations;
                let mut tendons = solver.model().tendon_unknown_indices();
                if tendons.any(|i| s.state.y_u[i].abs() < 1e-6) {
                    *at_kink += 1;
                }
                if let Err(e) = solver.analyze_solution(&s, &AnalysisSettings::default()) {
                    failed.push(format!("analysis of step {k}: {e}"));
                }
                state = s.state;
            }
            Err(e) => failed.push(format!("step {k}: {e}")),
        }
    }
    (failed, largest, reach, evaluations)
}

#[test]
fn steps_cross_tendon_kinks_on_circles() {
    let design = Tdpcr::from_ron_file(design_path("lilge2022_redundant.ron")).unwrap();
    let rules = [
        ("least-norm", Redundancy::LeastNorm, false),
        ("least-norm, Gauss–Newton", Redundancy::LeastNorm, true),
        (
            "within the limits",
            Redundancy::WithinLimits(Objective::LeastChange),
            false,
        ),
    ];
    for (radius, tilt) in [(0.01, 0.0), (0.01, 20f64.to_radians())] {
        for (name, redundancy, gauss_newton) in &rules {
            let mut solver = Solver::new(&design).unwrap();
            solver.redundancy = redundancy.clone();
            solver.least_norm_gauss_newton = *gauss_newton;
            let mut at_kink = 0;
            let (failed, largest, reach, evaluations) =
                circle(&mut solver, radius, tilt, &mut at_kink);
            eprintln!(
                "radius {radius} m, tilt {tilt:.3} rad, {name}: {} failed, largest step of q {largest:.3e} m, |q|/limit ≤ {reach:.3}, {evaluations} evaluations, {at_kink} solutions with a tendon at its kink",
                failed.len()
            );
            assert!(failed.is_empty(), "{name}: failed steps: {failed:#?}");
            assert!(
                largest < 1.5e-3,
                "{name}: q jumped by {largest:e} m in a step"
            );
            if matches!(redundancy, Redundancy::WithinLimits(_)) {
                assert!(
                    reach <= 1.0 + 1e-12,
                    "{name}: q beyond its limits ({reach})"
                );
            }
            if name == &"least-norm" {
                assert!(evaluations < 1000, "{name}: {evaluations} evaluations");
            }
            // Without the one-sided steps these circles fail at the kinks.
            solver.across_kinks = false;
            let (failed, _, _, _) = circle(&mut solver, radius, tilt, &mut 0);
            assert!(
                !failed.is_empty(),
                "{name}: no step fails without the retry"
            );
        }
    }
}

/// A least-norm solution with a tendon held at its kink (ζ = 0: no tension, no slack)
/// reports that tendon just taut (γ = 1e-8, τ = 1e-16 N), where the analysis' γ
/// columns do not vanish: J_FK and the compliance are the taut side's, the same within
/// 1e-6 as with the tendon taut at 1e-10 N (γ = 1e-5), and the paper's rconds flag the
/// zero tension (near Type II and leg singular). With γ = 0 the analysis found
/// \[B_x B_u\] exactly singular (every solution at a kink of the circle above).
#[test]
fn a_tendon_held_at_its_kink_is_analysed_as_just_taut() {
    let design = Tdpcr::from_ron_file(design_path("lilge2022_redundant.ron")).unwrap();
    let mut solver = Solver::new(&design).unwrap();
    let w = Wrench::default();
    let home = solver.solve_ik(&Pose::identity(), &w, None).unwrap().state;
    let mut state = home.clone();
    let kink = (1..=63)
        .find_map(|k| {
            let angle = std::f64::consts::TAU * k as f64 / 63.0;
            let r = 0.01 * k as f64 / 63.0;
            let pose = Pose {
                position: Vector3::new(r * angle.cos(), r * angle.sin(), 0.0),
                rotation: home.pose().rotation,
            };
            let s = solver.solve_ik(&pose, &w, Some(&state)).unwrap();
            state = s.state.clone();
            let held: Vec<usize> = solver
                .model()
                .tendon_unknown_indices()
                .filter(|&i| s.state.y_u[i].abs() < 1e-6)
                .collect();
            (!held.is_empty()).then_some((s.state, held))
        })
        .expect("a solution with a tendon at its kink on the spiral");
    let (at_kink, held) = kink;
    for &i in &held {
        assert_eq!(at_kink.y_u[i], 1e-8, "γ of a tendon at its kink");
    }
    let settings = AnalysisSettings::default();
    let a = solver.analyze(&at_kink, &w, &settings).unwrap();
    let mut taut = at_kink.clone();
    held.iter().for_each(|&i| taut.y_u[i] = 1e-5);
    let b = solver.analyze(&taut, &w, &settings).unwrap();
    let relative =
        |x: &nalgebra::DMatrix<f64>, y: &nalgebra::DMatrix<f64>| (x - y).norm() / y.norm();
    eprintln!(
        "{} tendon(s) at the kink; C {:e}, J_FK {:e} apart; rcond [B_x B_u] {:e} (taut at 1e-10 N: {:e}), B_u {:e}",
        held.len(),
        relative(&a.compliance, &b.compliance),
        relative(&a.j_fk, &b.j_fk),
        a.rcond.b_xu,
        b.rcond.b_xu,
        a.rcond.b_u
    );
    assert!(
        relative(&a.compliance, &b.compliance) < 1e-6,
        "C moved by {:e}",
        relative(&a.compliance, &b.compliance)
    );
    assert!(
        relative(&a.j_fk, &b.j_fk) < 1e-6,
        "J_FK moved by {:e}",
        relative(&a.j_fk, &b.j_fk)
    );
    assert!(a.rcond.b_xu < 1e-12, "rcond([B_x B_u]) {:e}", a.rcond.b_xu);
    assert!(
        a.singularity.type_ii && a.singularity.leg,
        "{:?}",
        a.singularity
    );
}
