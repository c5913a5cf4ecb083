//! Warm IK along the peer-style path of issue 17 (`sampling::ik_fine_path`: 200 poses,
//! ≤ 0.63 mm and ≤ 0.32° per step, ε_b = 1e-10) on the reference design: each step
//! warm-started from the previous solution, the closed path run for `LAPS` laps after
//! one lap of warm-up. Prints the per-step median, mean, 99th percentile and max solve
//! time and the mean work per step (the criterion bench `solve/ik_fine_path_step` times
//! the same steps). Usage: `cargo run --release --example warm_ik_path [LAPS]`.
use std::time::Instant;

use tdpcr::Tdpcr;
use tdpcr::kinetostatics::Solver;
use tdpcr::rod::Wrench;
use tdpcr::sampling::{ik_fine_path, largest_step};

fn main() {
    let laps: usize = std::env::args()
        .nth(1)
        .map_or(5, |a| a.parse().expect("LAPS: a positive integer"));
    let design = Tdpcr::from_ron_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/designs/lilge2022.ron"
    ))
    .expect("the reference design");
    let mut solver = Solver::new(&design).expect("valid design");
    let w = Wrench::default();
    let home = solver.solve_fk(&[0.0; 6], &w, None).unwrap().state;
    let path = ik_fine_path(&home.pose(), 200);
    let (dp, dr) = largest_step(&path);
    let mut last = home;
    let mut times_us = Vec::new();
    let (mut residuals, mut jacobians, mut iterations) = (0, 0, 0);
    // The step with the most evaluations (residuals, Jacobians): a load-independent max.
    let mut most = (0, 0);
    for lap in 0..=laps {
        for pose in &path {
            let start = Instant::now();
            let sol = solver
                .solve_ik(pose, &w, Some(&last))
                .expect("every step of the path converges");
            let us = start.elapsed().as_secs_f64() * 1e6;
            if lap > 0 {
                times_us.push(us);
                residuals += sol.report.residual_evaluations;
                jacobians += sol.report.jacobian_evaluations;
                iterations += sol.report.iterations;
                most = most.max((
                    sol.report.residual_evaluations,
                    sol.report.jacobian_evaluations,
                ));
            }
            last = sol.state;
        }
    }
    times_us.sort_by(f64::total_cmp);
    let n = times_us.len();
    let per_step = |x: usize| x as f64 / n as f64;
    println!(
        "warm IK, 200-pose path (steps ≤ {:.3} mm, ≤ {:.3}°), {laps} laps, {n} steps: \
         median {:.1} µs, mean {:.1} µs, p99 {:.1} µs, max {:.1} µs per step; \
         per step {:.2} iterations, {:.2} residuals, {:.2} Jacobians; \
         the most work in one step {} residuals ({} with a Jacobian)",
        dp * 1e3,
        dr.to_degrees(),
        times_us[n / 2],
        times_us.iter().sum::<f64>() / n as f64,
        times_us[(n * 99) / 100],
        times_us[n - 1],
        per_step(iterations),
        per_step(residuals),
        per_step(jacobians),
        most.0,
        most.1,
    );
}
