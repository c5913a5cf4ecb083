//! What a controller does each cycle: a warm-started IK to the next pose of a path, then
//! the Jacobian and the compliance at the solution (for a velocity or stiffness law), with
//! the time each cycle takes.
//!
//! `cargo run --release --example controller_loop` (run by `tests/examples.rs`).

use std::time::Instant;

use nalgebra::Vector3;
use tdpcr::Tdpcr;
use tdpcr::analysis::AnalysisSettings;
use tdpcr::error::Error;
use tdpcr::kinetostatics::Solver;
use tdpcr::model::Pose;
use tdpcr::rod::Wrench;

pub fn main() -> Result<(), Error> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/designs/lilge2022.ron");
    let mut solver = Solver::new(&Tdpcr::from_ron_file(path)?)?;
    let (w, settings) = (Wrench::default(), AnalysisSettings::default());
    let mut state = solver.solve_ik(&Pose::identity(), &w, None)?.state;
    // A 20 mm circle in the plane z = 0, 100 poses (1.3 mm apart).
    for k in 1..=100 {
        let t = k as f64 / 100.0 * std::f64::consts::TAU;
        let target = Pose {
            position: Vector3::new(0.02 * (t.cos() - 1.0), 0.02 * t.sin(), 0.0),
            ..Pose::identity()
        };
        let start = Instant::now();
        state = solver.solve_ik(&target, &w, Some(&state))?.state;
        let a = solver.analyze(&state, &w, &settings)?;
        let cycle_us = start.elapsed().as_secs_f64() * 1e6;
        if k % 25 == 0 {
            let dq_dx = a.j_ik.column(0); // δq for 1 m along x [m/m]
            println!(
                "pose {k}: q = {:.2?} mm, |dq/dx| {:.3}, C_p[z,z] {:.1} mm/N, cycle {cycle_us:.0} µs",
                state.q.iter().map(|x| x * 1e3).collect::<Vec<_>>(),
                dq_dx.norm(),
                a.compliance[(2, 2)] * 1e3
            );
        }
    }
    Ok(())
}
