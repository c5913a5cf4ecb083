//! Cold FK over the 30 seeded actuation vectors of the benchmark: converged count,
//! median iterations and solve time (the figures of BENCHMARKS.md).
use tdpcr::Tdpcr;
use tdpcr::kinetostatics::Solver;
use tdpcr::rod::Wrench;
use tdpcr::sampling::seeded_actuations;

fn main() {
    let design = Tdpcr::from_ron_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/designs/lilge2022.ron"
    ))
    .unwrap();
    let mut solver = Solver::new(&design);
    let set = seeded_actuations(solver.model(), 30, 42);
    let (mut iterations, mut times, mut failed) = (vec![], vec![], 0);
    for q in &set {
        match solver.solve_fk(q, &Wrench::default(), None) {
            Ok(s) => {
                iterations.push(s.report.iterations);
                times.push(s.solve_time_us);
            }
            Err(e) => {
                failed += 1;
                println!("q = {q:.4?}: {e}");
            }
        }
    }
    iterations.sort_unstable();
    times.sort_by(f64::total_cmp);
    let median = |v: &[f64]| {
        if v.is_empty() {
            f64::NAN
        } else {
            v[v.len() / 2]
        }
    };
    let its: Vec<f64> = iterations.iter().map(|&i| i as f64).collect();
    println!(
        "converged {}/{}, median iterations {}, median time {:.0} µs, mean time {:.0} µs",
        set.len() - failed,
        set.len(),
        median(&its),
        median(&times),
        times.iter().sum::<f64>() / times.len().max(1) as f64
    );
}
