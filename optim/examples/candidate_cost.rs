//! The wall time of the design search's candidate evaluation (issue 17) with the default
//! config `optim/default.ron`: the reference design and `COUNT` candidates drawn as the
//! search's first generation draws them (the reference's box point plus the initial step
//! times standard normal numbers, clamped into the box; seed 1), each evaluated as the
//! search does ([`evaluate_point`] with the [`WorkspaceEvaluator`]) on one thread (the
//! search runs one candidate per thread). Prints each time and the median and maximum.
//! Usage: `cargo run --release -p tdpcr-optim --example candidate_cost [COUNT]`.
use std::path::Path;

use tdpcr_optim::Overrides;
use tdpcr_optim::evaluate::evaluate_point;
use tdpcr_optim::objectives::Outcome;
use tdpcr_optim::rng::Rng;
use tdpcr_optim::search::Setup;
use tdpcr_optim::workspace_eval::WorkspaceEvaluator;

fn main() {
    let count: usize = std::env::args()
        .nth(1)
        .map_or(20, |a| a.parse().expect("COUNT: a non-negative integer"));
    let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("default.ron");
    let setup = Setup::load(&config, &Overrides::default()).expect("the default config");
    let space = &setup.space;
    let evaluator = WorkspaceEvaluator::new(&setup.config.evaluation);
    let reference: Vec<f64> = space.normalize(
        &space
            .bounds()
            .iter()
            .map(|b| b.parameter.get(space.base()))
            .collect::<Vec<_>>(),
    );
    let mut rng = Rng::new(1);
    let sigma = setup.config.initial_step;
    let candidates = std::iter::once(reference.clone()).chain((0..count).map(|_| {
        reference
            .iter()
            .map(|&m| (m + sigma * rng.normal()).clamp(0.0, 1.0))
            .collect::<Vec<_>>()
    }));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool");
    let mut times = Vec::new();
    for (k, x) in candidates.enumerate() {
        let (outcome, seconds) = pool.install(|| evaluate_point(space, &evaluator, &x));
        let what = match outcome {
            Outcome::Feasible(m) => format!("feasible, {} reachable cells", m.reachable_cells),
            Outcome::Infeasible { reason } => format!("infeasible: {reason}"),
        };
        let label = if k == 0 { "reference" } else { "candidate" };
        println!("{label} {k}: {seconds:.3} s ({what})");
        times.push(seconds);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "{} evaluations on one thread: median {:.3} s, max {:.3} s",
        times.len(),
        times[times.len() / 2],
        times[times.len() - 1]
    );
}
