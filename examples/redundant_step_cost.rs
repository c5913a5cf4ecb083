//! Runs warm 1 mm IK steps of the 9-DoF design, each from the same solved state (the
//! `ik_9dof_warm_step_1mm/{least_norm,within_limits}` benches' step) or back and forth
//! between two poses from the solver's last solution (`..._back_and_forth`), for
//! instruction counting under callgrind; prints the median `solve_time_us` and the last
//! step's evaluations:
//! `redundant_step_cost {least_norm|least_norm_gauss_newton|within_limits} [repetitions,
//! default 200] [fixed|back_and_forth, default fixed]`.
use nalgebra::Vector3;
use tdpcr::Tdpcr;
use tdpcr::kinetostatics::{Objective, Redundancy, Solver};
use tdpcr::model::Pose;
use tdpcr::rod::Wrench;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let design = Tdpcr::from_ron_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/designs/lilge2022_redundant.ron"
    ))
    .unwrap();
    let mut solver = Solver::new(&design).expect("valid design");
    solver.redundancy = match args.get(1).map(String::as_str) {
        Some("within_limits") => Redundancy::WithinLimits(Objective::LeastChange),
        _ => Redundancy::LeastNorm,
    };
    solver.least_norm_gauss_newton =
        args.get(1).map(String::as_str) == Some("least_norm_gauss_newton");
    let repetitions: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(200);
    let back_and_forth = args.get(3).map(String::as_str) == Some("back_and_forth");
    let w = Wrench::default();
    let home = solver.solve_ik(&Pose::identity(), &w, None).unwrap().state;
    let poses = [1e-3, 0.0].map(|x| Pose {
        position: Vector3::new(x, 0.0, 0.0),
        rotation: home.pose().rotation,
    });
    let mut last = home.clone();
    let mut report = None;
    let mut times: Vec<f64> = (0..repetitions)
        .map(|k| {
            let (pose, start) = if back_and_forth {
                (&poses[k % 2], &last)
            } else {
                (&poses[0], &home)
            };
            let s = solver.solve_ik(pose, &w, Some(start)).unwrap();
            report = Some(s.report);
            last = s.state;
            s.solve_time_us
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let r = report.expect("at least one repetition");
    println!(
        "median solve_time_us {:.1} (last step: {} residuals, {} Jacobians)",
        times[times.len() / 2],
        r.residual_evaluations,
        r.jacobian_evaluations
    );
}
