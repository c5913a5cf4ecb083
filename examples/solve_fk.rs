//! Forward kinetostatics of the paper's robot, from the command line's point of view of a
//! library user: load the design, solve FK cold, then analyse the solution.
//!
//! `cargo run --release --example solve_fk` (run by `tests/examples.rs`).

use tdpcr::Tdpcr;
use tdpcr::analysis::AnalysisSettings;
use tdpcr::error::Error;
use tdpcr::kinetostatics::Solver;
use tdpcr::rod::Wrench;

pub fn main() -> Result<(), Error> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/designs/lilge2022.ron");
    let design = Tdpcr::from_ron_file(path)?;
    let mut solver = Solver::new(&design)?;
    // Per leg [q_b, q_t] [m]: bend leg 1 by 3 mm of tendon, raise every base by 10 mm.
    let q = [0.003, 0.01, 0.0, 0.01, 0.0, 0.01];
    let no_load = Wrench::default();
    let sol = solver.solve_fk(&q, &no_load, None)?;
    let p = sol.state.position;
    println!(
        "platform at ({:.2}, {:.2}, {:.2}) mm after {} Newton iterations ({:.0} µs)",
        p[0] * 1e3,
        p[1] * 1e3,
        p[2] * 1e3,
        sol.report.iterations,
        sol.solve_time_us
    );
    let a = solver.analyze_solution(&sol, &AnalysisSettings::default())?;
    println!(
        "rcond(J_p) {:.3}, rcond(C_p) {:.3}",
        a.rcond.j_p, a.rcond.c_p
    );
    println!(
        "stiffest direction: {:.3} N/mm; stable with the actuators held: {}",
        1e-3 / a.ellipsoids.c_p.semi_axes[2],
        a.stability.stable
    );
    Ok(())
}
