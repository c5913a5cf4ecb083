//! The paper's motion-sequence experiment (Tab. VII) on deterministic sequences
//! (`sampling::ik_motion_sequence`, `sampling::fk_motion_sequence`): 1300 IK poses of
//! the 6-DoF design mixing translations and rotations, and 1000 FK actuations of the
//! 9-DoF design, each warm-started from the previous step. Prints per-step statistics.
use tdpcr::Tdpcr;
use tdpcr::kinetostatics::Solver;
use tdpcr::rod::Wrench;
use tdpcr::sampling::{fk_motion_sequence, ik_motion_sequence, largest_step};
use tdpcr::trajectory::{Targets, run_trajectory};

fn design(file: &str) -> Tdpcr {
    Tdpcr::from_ron_file(format!("{}/designs/{file}", env!("CARGO_MANIFEST_DIR"))).unwrap()
}

fn main() {
    let w = Wrench::default();
    let mut solver = Solver::new(&design("lilge2022.ron")).expect("valid design");
    let home = solver.solve_fk(&[0.0; 6], &w, None).unwrap().state;
    let poses = ik_motion_sequence(&home.pose(), 1300);
    let (max_dp, max_dr) = largest_step(&poses);
    let (steps_ik, stats) = run_trajectory(&mut solver, &Targets::Poses(poses), &w);
    let mut slowest: Vec<(f64, usize, usize)> = steps_ik
        .iter()
        .map(|s| (s.solve_time_us, s.step, s.iterations))
        .collect();
    slowest.sort_by(|a, b| b.0.total_cmp(&a.0));
    println!(
        "slowest IK steps (µs, step, iterations): {:.0?}",
        &slowest[..5]
    );
    println!(
        "IK, 6-DoF, 1300 poses (steps ≤ {:.2} mm, ≤ {:.2}°): {stats:?}",
        max_dp * 1e3,
        max_dr.to_degrees()
    );
    // The ψ = 0 twin: the same robot as the reference 9-DoF design (with four tendons at
    // 90° a roll of 90° only renames the pairs, MODEL.md §1), whose pair labels the
    // sequence is written for.
    let d = design("lilge2022_redundant_psi0.ron");
    let mut solver = Solver::new(&d).expect("valid design");
    let qs = fk_motion_sequence(solver.model().pairs, 1000);
    let (steps, stats) = run_trajectory(&mut solver, &Targets::Actuations(qs), &w);
    println!("FK, 9-DoF, 1000 steps: {stats:?}");
    let mut slowest: Vec<(f64, usize, usize)> = steps
        .iter()
        .map(|s| (s.solve_time_us, s.step, s.iterations))
        .collect();
    slowest.sort_by(|a, b| b.0.total_cmp(&a.0));
    println!(
        "slowest FK steps (µs, step, iterations): {:.0?}",
        &slowest[..5]
    );
    let failed: Vec<usize> = steps
        .iter()
        .filter(|s| !s.converged)
        .map(|s| s.step)
        .collect();
    println!("failed steps: {failed:?}");
}
