//! The 9-DoF design's least-norm IK where its path takes tendons through their kinks.
//!
//! On circles of the platform in 1 mm steps the least-norm solutions of the reference
//! 9-DoF design reach states where one tendon pair of a leg is slack on both sides or a
//! taut tendon is about to go slack (ζ ≈ 0). A Newton step with the slope of the side a
//! tendon leaves overshoots beyond its kink, and the line search crawled towards the kink
//! until it failed: 4 of the 126 steps of the flat 10 mm circle below, 4 of the tilted
//! one, before 2026-11-28. Such a run is now repeated with one-sided steps across the
//! kinks (`kinetostatics::redundant`, MODEL.md "One-sided columns at the kink"); every
//! step converges, and none jumps (q moves by less than 1.5 mm in a 1 mm step, as the
//! steps away from the kinks do). Gauss–Newton steps (`Solver::least_norm_gauss_newton`,
//! the workspace sweep's) are not retried: they still fail there.

mod common;

use common::design_path;
use nalgebra::{Rotation3, Vector3};
use tdpcr::Tdpcr;
use tdpcr::kinetostatics::Solver;
use tdpcr::model::Pose;
use tdpcr::rod::Wrench;

/// Follows a circle of `radius` \[m\] around home, its plane tilted by `tilt` \[rad\]
/// about x: a spiral out to it over one lap, then one lap on it, in steps of about
/// 1 mm. Returns the failed steps and the largest change of q \[m\] of a step after the
/// first.
fn circle(gauss_newton: bool, radius: f64, tilt: f64) -> (Vec<String>, f64) {
    let design = Tdpcr::from_ron_file(design_path("lilge2022_redundant.ron")).unwrap();
    let mut solver = Solver::new(&design).unwrap();
    solver.least_norm_gauss_newton = gauss_newton;
    let w = Wrench::default();
    let home = solver.solve_ik(&Pose::identity(), &w, None).unwrap().state;
    let tilted = Rotation3::from_axis_angle(&Vector3::x_axis(), tilt).into_inner();
    let steps = (std::f64::consts::TAU * radius / 1e-3).ceil() as usize;
    let mut state = home.clone();
    let (mut failed, mut largest) = (Vec::new(), 0.0_f64);
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
                state = s.state;
            }
            Err(e) => failed.push(format!("step {k}: {e}")),
        }
    }
    (failed, largest)
}

#[test]
fn least_norm_steps_cross_tendon_kinks_on_circles() {
    for (radius, tilt) in [(0.01, 0.0), (0.01, 20f64.to_radians())] {
        let (failed, largest) = circle(false, radius, tilt);
        eprintln!(
            "radius {radius} m, tilt {tilt:.3} rad: {} failed, largest step of q {largest:.3e} m",
            failed.len()
        );
        assert!(failed.is_empty(), "failed steps: {failed:#?}");
        assert!(largest < 1.5e-3, "q jumped by {largest:e} m in a step");
        // Gauss–Newton steps keep the runs of before, failures included.
        let (failed, _) = circle(true, radius, tilt);
        assert!(
            !failed.is_empty(),
            "Gauss–Newton steps no longer fail at the kinks"
        );
    }
}
