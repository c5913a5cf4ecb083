//! Cold FK over 30 seeded actuation vectors that have an equilibrium on the home branch
//! (`sampling::seeded_reachable_actuations`, seed 42): converged count, whether each
//! solution is the certified one (and, if not, whether the equilibrium it found is
//! stable), median and mean iterations (every Newton run of each solve) and solve time
//! (BENCHMARKS.md).
//! `cold_fk_stats [DESIGN.ron] [--one-sided]` (default: the reference design;
//! `--one-sided` turns on [`Solver::one_sided_kinks`]).
use tdpcr::Tdpcr;
use tdpcr::analysis::AnalysisSettings;
use tdpcr::kinetostatics::Solver;
use tdpcr::rod::Wrench;
use tdpcr::sampling::seeded_reachable_actuations;

fn main() {
    let one_sided = std::env::args().any(|a| a == "--one-sided");
    let file = std::env::args()
        .skip(1)
        .find(|a| a != "--one-sided")
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/designs/lilge2022.ron").into());
    let design = Tdpcr::from_ron_file(&file).unwrap();
    let sample = seeded_reachable_actuations(&design, 30, 42).unwrap();
    println!(
        "{} draws rejected (path from q = 0 ends in a fold first):",
        sample.rejected.len()
    );
    for q in &sample.rejected {
        println!("  rejected q = {q:.4?}");
    }
    let mut solver = Solver::new(&design).expect("valid design");
    solver.one_sided_kinks = one_sided;
    let (mut iterations, mut jacobians, mut times, mut failed, mut other_branch) =
        (vec![], vec![], vec![], 0, 0);
    for (q, pose) in sample.actuations.iter().zip(&sample.poses) {
        match solver.solve_fk(q, &Wrench::default(), None) {
            Ok(s) => {
                if (s.state.pose().position - pose.position).norm() > 1e-6 {
                    other_branch += 1;
                    let stable = solver
                        .analyze(&s.state, &Wrench::default(), &AnalysisSettings::default())
                        .map_or("stability unknown", |a| {
                            if a.stability.stable {
                                "stable"
                            } else {
                                "unstable"
                            }
                        });
                    println!(
                        "q = {q:.4?}: converged to another equilibrium, {stable} (platform at {:.4?} m, the home branch's at {:.4?} m)",
                        s.state.position,
                        pose.position.as_slice()
                    );
                }
                iterations.push(s.report.iterations as f64);
                jacobians.push(s.report.jacobian_evaluations as f64);
                times.push(s.solve_time_us);
            }
            Err(e) => {
                failed += 1;
                println!("q = {q:.4?}: {e}");
            }
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        if v.is_empty() {
            f64::NAN
        } else {
            v[v.len() / 2]
        }
    };
    let mean = times.iter().sum::<f64>() / times.len().max(1) as f64;
    let mean_iterations = iterations.iter().sum::<f64>() / iterations.len().max(1) as f64;
    println!(
        "converged {}/{} ({} to another equilibrium), median iterations {} (mean {:.1}), median Jacobians {}, median time {:.0} µs, mean time {:.0} µs, max {:.0} µs",
        sample.actuations.len() - failed,
        sample.actuations.len(),
        other_branch,
        median(&mut iterations),
        mean_iterations,
        median(&mut jacobians),
        median(&mut times),
        mean,
        times.last().copied().unwrap_or(f64::NAN),
    );
}
