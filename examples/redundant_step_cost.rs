//! Runs warm 1 mm IK steps of the 9-DoF design, each from the same solved state (the
//! `ik_9dof_warm_step_1mm/{least_norm,within_limits}` benches' step), for instruction
//! counting under callgrind; prints the median `solve_time_us`:
//! `redundant_step_cost {least_norm|within_limits} [repetitions, default 200]`.
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
    let repetitions: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(200);
    let w = Wrench::default();
    let home = solver.solve_ik(&Pose::identity(), &w, None).unwrap().state;
    let target = Pose {
        position: Vector3::new(0.001, 0.0, 0.0),
        rotation: home.pose().rotation,
    };
    let mut times: Vec<f64> = (0..repetitions)
        .map(|_| {
            solver
                .solve_ik(&target, &w, Some(&home))
                .unwrap()
                .solve_time_us
        })
        .collect();
    times.sort_by(f64::total_cmp);
    println!("median solve_time_us {:.1}", times[times.len() / 2]);
}
