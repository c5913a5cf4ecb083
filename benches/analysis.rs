//! Kinetostatic analysis (issue 4): everything of `Analysis` from a solved state, with the
//! blocks given (`analyze_blocks`) and with their evaluation (`Solver::analyze`); the
//! dense-SVD rcond it replaces; IK steps of the 9-DoF design with and without limits.

use std::hint::black_box;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use nalgebra::{DMatrix, Vector3};
use tdpcr::Tdpcr;
use tdpcr::analysis::{AnalysisSettings, analyze_blocks, rcond::rcond};
use tdpcr::kinetostatics::Solver;
use tdpcr::model::Pose;
use tdpcr::redundancy::{Objective, Redundancy};
use tdpcr::rod::Wrench;

fn design(file: &str) -> Tdpcr {
    Tdpcr::from_ron_file(format!("{}/designs/{file}", env!("CARGO_MANIFEST_DIR"))).unwrap()
}

fn bench_analysis(c: &mut Criterion) {
    let mut group = c.benchmark_group("analysis");
    let settings = AnalysisSettings::default();
    for (name, file, q) in [
        (
            "6dof",
            "lilge2022.ron",
            vec![0.004, 0.02, -0.003, -0.01, 0.002, 0.03],
        ),
        ("9dof", "lilge2022_redundant.ron", vec![0.0; 9]),
    ] {
        let d = design(file);
        let mut solver = Solver::new(&d).unwrap();
        let state = solver.solve_fk(&q, &Wrench::default(), None).unwrap().state;
        let (_r, blocks) = solver.blocks_at(&state, &Wrench::default()).unwrap();
        let blocks = blocks.clone();
        let model = solver.model().clone();
        group.bench_function(format!("{name}/analyze_blocks"), |b| {
            b.iter(|| analyze_blocks(&model, black_box(&blocks), &state.y_u, &settings).unwrap())
        });
        // With the legs' integration: the solver forgets the last one first (an analysis
        // of the same state would reuse it).
        group.bench_function(format!("{name}/analyze_with_blocks"), |b| {
            b.iter(|| {
                solver.forget_jacobian();
                solver
                    .analyze(black_box(&state), &Wrench::default(), &settings)
                    .unwrap()
            })
        });
        // The baseline the structured QR + Lanczos replace: dense SVDs of the three raw
        // matrices (the scaled ones would double it).
        let (n, nq, ny) = (blocks.b_x.nrows(), blocks.b_q.ncols(), blocks.b_u.ncols());
        let mut m_x = DMatrix::zeros(n, n);
        m_x.columns_mut(0, 6).copy_from(&blocks.b_x);
        m_x.columns_mut(6, ny).copy_from(&blocks.b_u);
        let mut m_q = DMatrix::zeros(n, nq + ny);
        m_q.columns_mut(0, nq).copy_from(&blocks.b_q);
        m_q.columns_mut(nq, ny).copy_from(&blocks.b_u);
        group.bench_function(format!("{name}/dense_svd_rcond_raw_x3"), |b| {
            b.iter(|| {
                (
                    rcond(black_box(&m_x)),
                    rcond(black_box(&m_q)),
                    rcond(black_box(&blocks.b_u)),
                )
            })
        });
    }
    group.finish();
}

fn bench_ik_within_limits(c: &mut Criterion) {
    let mut group = c.benchmark_group("ik_9dof_warm_step_1mm");
    group.sample_size(10);
    let d = design("lilge2022_redundant.ron");
    for (name, redundancy) in [
        ("least_norm", Redundancy::LeastNorm),
        (
            "within_limits",
            Redundancy::WithinLimits(Objective::LeastChange),
        ),
    ] {
        let mut solver = Solver::new(&d).unwrap();
        solver.redundancy = redundancy;
        let home = solver
            .solve_ik(&Pose::identity(), &Wrench::default(), None)
            .unwrap()
            .state;
        let target = Pose {
            position: Vector3::new(0.001, 0.0, 0.0),
            rotation: home.pose().rotation,
        };
        group.bench_function(name, |b| {
            b.iter_batched(
                || home.clone(),
                |start| {
                    solver
                        .solve_ik(black_box(&target), &Wrench::default(), Some(&start))
                        .unwrap()
                },
                BatchSize::SmallInput,
            )
        });
    }
    // Steps of 1 mm back and forth between two poses, each from the solver's own last
    // solution (a controller's loop): least-norm with fresh Jacobians (the default) and
    // starting from the last factorization (`Solver::reuse_least_norm_factorization`),
    // and within the limits.
    for (name, reuse, redundancy) in [
        ("least_norm_back_and_forth", false, Redundancy::LeastNorm),
        (
            "least_norm_back_and_forth_reused",
            true,
            Redundancy::LeastNorm,
        ),
        (
            "within_limits_back_and_forth",
            false,
            Redundancy::WithinLimits(Objective::LeastChange),
        ),
    ] {
        let mut solver = Solver::new(&d).unwrap();
        solver.reuse_least_norm_factorization = reuse;
        solver.redundancy = redundancy;
        let w = Wrench::default();
        let mut last = solver.solve_ik(&Pose::identity(), &w, None).unwrap().state;
        let poses = [1e-3, 0.0].map(|x| Pose {
            position: Vector3::new(x, 0.0, 0.0),
            rotation: last.pose().rotation,
        });
        let mut k = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                k += 1;
                last = solver
                    .solve_ik(black_box(&poses[k % 2]), &w, Some(&last))
                    .unwrap()
                    .state;
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).measurement_time(std::time::Duration::from_secs(3));
    targets = bench_analysis, bench_ik_within_limits
}
criterion_main!(benches);
