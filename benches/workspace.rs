//! The workspace sweep of the reference design at R_ee = I (MODEL.md §6).
//!
//! - criterion: a coarse sweep (Δ = 10 mm, φ = 0.1 rad: rays at most Δ apart out to
//!   0.1 m; the default z-range) on 1 and on 2 threads (the design optimizer's kind of
//!   call; 10 samples each).
//! - `TDPCR_BENCH_FULL=1 cargo bench --bench workspace`: additionally the paper's sweep
//!   (Δ = 3 mm, φ = 0.035 rad) once on all cores, printing wall time, solves per second
//!   and cell counts (criterion needs at least 10 samples, too long for a sweep of minutes).

use std::hint::black_box;

use criterion::Criterion;
use tdpcr::Tdpcr;
use tdpcr::workspace::{WorkspaceSettings, sweep_workspace};

fn design() -> Tdpcr {
    Tdpcr::from_ron_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/designs/lilge2022.ron"
    ))
    .unwrap()
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

fn bench_coarse(c: &mut Criterion) {
    let d = design();
    let settings = WorkspaceSettings {
        step: 0.01,
        angle_step: 0.1,
        ..Default::default()
    };
    let mut group = c.benchmark_group("workspace");
    group.sample_size(10);
    for threads in [1, 2] {
        let pool = pool(threads);
        group.bench_function(format!("coarse_10mm/{threads}_threads"), |b| {
            b.iter(|| pool.install(|| sweep_workspace(black_box(&d), &settings).unwrap()))
        });
    }
    group.finish();
    let map = sweep_workspace(&d, &settings).unwrap();
    let s = &map.summary;
    println!(
        "coarse sweep: {} reachable cells, {} solves, planes z {:.3}..{:.3} m",
        s.counts.reachable, s.solves, s.z_reached[0], s.z_reached[1]
    );
}

fn full_sweep_once() {
    let d = design();
    let settings = WorkspaceSettings::default();
    let map = sweep_workspace(&d, &settings).unwrap();
    let s = &map.summary;
    println!(
        "workspace/paper_3mm: {:.1} s wall on {} threads, {} solves ({:.0} solves/s), \
         {} Newton iterations; {} reachable cells ({:.4e} m³), {} near Type II, \
         {} collision; planes z {:.3}..{:.3} m ({} of {})",
        s.wall_time_s,
        s.threads,
        s.solves,
        s.solves_per_second,
        s.newton_iterations,
        s.counts.reachable,
        s.volume.reachable,
        s.counts.near_type_ii,
        s.counts.collision,
        s.z_reached[0],
        s.z_reached[1],
        s.planes_reached,
        s.planes
    );
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    bench_coarse(&mut c);
    if std::env::var_os("TDPCR_BENCH_FULL").is_some() {
        full_sweep_once();
    }
    c.final_summary();
}
