//! Parallel robot: boundary residual, exact vs finite-difference Jacobian, the dense
//! Newton solve, cold FK over 30 seeded reachable actuation vectors, warm IK steps (one
//! step of 1 mm; a step along the peer-style path of issue 17) and the paper's motion
//! sequences.

use std::hint::black_box;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use nalgebra::{DMatrix, DVector, Vector3};
use tdpcr::Tdpcr;
use tdpcr::boundary::{
    BoundaryJacobians, BoundaryScratch, FiniteDifference, boundary_derivatives,
    boundary_derivatives_fd, boundary_residual,
};
use tdpcr::kinetostatics::{RobotState, Solver};
use tdpcr::linalg::DenseLu;
use tdpcr::model::{Model, Pose};
use tdpcr::rod::Wrench;
use tdpcr::sampling::{
    fk_motion_sequence, ik_fine_path, ik_motion_sequence, seeded_reachable_actuations,
};
use tdpcr::trajectory::{Targets, run_trajectory};

fn design(file: &str) -> Tdpcr {
    Tdpcr::from_ron_file(format!("{}/designs/{file}", env!("CARGO_MANIFEST_DIR"))).unwrap()
}

/// A solved configuration of the reference design (q bent and translated).
fn solved_state(solver: &mut Solver, q: &[f64]) -> RobotState {
    solver.solve_fk(q, &Wrench::default(), None).unwrap().state
}

fn bench_jacobians(c: &mut Criterion) {
    let mut group = c.benchmark_group("boundary");
    for (name, file, q) in [
        (
            "6dof",
            "lilge2022.ron",
            vec![0.004, 0.02, -0.003, -0.01, 0.002, 0.03],
        ),
        ("9dof", "lilge2022_redundant.ron", vec![0.0; 9]),
    ] {
        let d = design(file);
        let model = Model::new(&d);
        let mut solver = Solver::new(&d).unwrap();
        let state = solved_state(&mut solver, &q);
        let pose: Pose = state.pose();
        let wrench = solver.total_wrench(&Wrench::default());
        let p = state.boundary_point(&pose, &wrench);
        let mut sc = BoundaryScratch::new(&model);
        let mut jac = BoundaryJacobians::new(&model);
        let mut r = DVector::zeros(model.n_residuals());
        // Each evaluation integrates: the buffers forget the last integration first (an
        // evaluation at its leg starts would reuse it).
        group.bench_function(format!("{name}/residual"), |b| {
            b.iter(|| {
                sc.forget_integration();
                boundary_residual(&model, &mut sc, black_box(&p), &mut r).unwrap()
            })
        });
        group.bench_function(format!("{name}/jacobian_exact"), |b| {
            b.iter(|| {
                sc.forget_integration();
                boundary_derivatives(&model, &mut sc, black_box(&p), &mut r, &mut jac).unwrap()
            })
        });
        for (label, m) in [
            ("fd_forward", FiniteDifference::Forward),
            ("fd_central", FiniteDifference::Central),
        ] {
            group.bench_function(format!("{name}/jacobian_{label}"), |b| {
                b.iter(|| {
                    boundary_derivatives_fd(&model, &mut sc, black_box(&p), m, &mut r, &mut jac)
                        .unwrap()
                })
            });
        }
        // The dense Newton solve [B_x B_u] δ = −b.
        boundary_derivatives(&model, &mut sc, &p, &mut r, &mut jac).unwrap();
        let n = model.n_residuals();
        let mut a = DMatrix::zeros(n, n);
        a.columns_mut(0, 6).copy_from(&jac.b_x);
        a.columns_mut(6, n - 6).copy_from(&jac.b_u);
        let mut lu = DenseLu::new(n);
        let mut x = r.clone();
        group.bench_function(format!("{name}/newton_solve_own_lu"), |b| {
            b.iter(|| {
                lu.factor(black_box(&a)).unwrap();
                x.copy_from(&r);
                lu.solve_in_place(&mut x);
            })
        });
        group.bench_function(format!("{name}/newton_solve_nalgebra_lu"), |b| {
            b.iter(|| black_box(&a).clone().lu().solve(&r).unwrap())
        });
        group.bench_function(format!("{name}/svd_bx_bu_nalgebra"), |b| {
            b.iter(|| black_box(&a).clone().singular_values())
        });
        // The same two jobs with faer (allocating API, sequential), with the feature
        // `faer-comparison` only: `cargo bench --bench solve --features faer-comparison`.
        #[cfg(feature = "faer-comparison")]
        {
            let fa = faer::Mat::<f64>::from_fn(n, n, |i, j| a[(i, j)]);
            let fr = faer::Mat::<f64>::from_fn(n, 1, |i, _| r[i]);
            group.bench_function(format!("{name}/newton_solve_faer_lu"), |b| {
                b.iter(|| {
                    use faer::linalg::solvers::Solve;
                    black_box(&fa).partial_piv_lu().solve(&fr)
                })
            });
            group.bench_function(format!("{name}/svd_bx_bu_faer"), |b| {
                b.iter(|| black_box(&fa).singular_values().unwrap())
            });
        }
    }
    group.finish();
}

fn bench_solves(c: &mut Criterion) {
    let mut group = c.benchmark_group("solve");
    group.sample_size(10);
    let d = design("lilge2022.ron");
    let mut solver = Solver::new(&d).unwrap();
    let w = Wrench::default();
    let set = seeded_reachable_actuations(&d, 30, 42).unwrap().actuations;
    group.bench_function("fk_cold_30_vectors", |b| {
        b.iter(|| {
            let mut converged = 0;
            for q in &set {
                converged += usize::from(solver.solve_fk(black_box(q), &w, None).is_ok());
            }
            converged
        })
    });
    // Warm IK steps of 1 mm, alternating between two poses, each from the solver's own
    // last solution (what a controller or trajectory does: tangent prediction applies).
    let home = solved_state(&mut solver, &[0.0; 6]);
    let poses = [
        home.pose(),
        Pose {
            position: home.pose().position + Vector3::new(0.001, 0.0, 0.0),
            rotation: home.pose().rotation,
        },
    ];
    let mut last = solver.solve_ik(&poses[0], &w, Some(&home)).unwrap().state;
    let mut k = 0;
    group.bench_function("ik_warm_step_1mm", |b| {
        b.iter(|| {
            k += 1;
            let sol = solver
                .solve_ik(black_box(&poses[k % 2]), &w, Some(&last))
                .unwrap();
            last = sol.state;
        })
    });
    // Warm IK along the peer-style path of issue 17 (200 poses, ≤ 0.63 mm and ≤ 0.32° per
    // step, ε_b = 1e-10; closed, so it is run round and round): one iteration is one
    // step, so criterion's figure is the time per step (median and max per step: the
    // example warm_ik_path).
    // "_own_jacobians": the same path without reusing the last step's Jacobian (each
    // step evaluates its own, as before issue 17's reuse): the ratio within one run.
    let path = ik_fine_path(&home.pose(), 200);
    for (name, reuse) in [
        ("ik_fine_path_step", true),
        ("ik_fine_path_step_own_jacobians", false),
    ] {
        let mut walker = Solver::new(&d).unwrap();
        walker.reuse_jacobian = reuse;
        let mut on_path = walker.solve_ik(&path[0], &w, Some(&home)).unwrap().state;
        let mut k = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                k = (k + 1) % path.len();
                let sol = walker
                    .solve_ik(black_box(&path[k]), &w, Some(&on_path))
                    .unwrap();
                on_path = sol.state;
            })
        });
    }
    // The same step from a state this solver did not produce (no prediction).
    group.bench_function("ik_warm_step_1mm_unpredicted", |b| {
        b.iter_batched(
            || (Solver::new(&d).unwrap(), home.clone()),
            |(mut fresh, start)| {
                fresh
                    .solve_ik(black_box(&poses[1]), &w, Some(&start))
                    .unwrap()
            },
            BatchSize::LargeInput,
        )
    });
    // The paper's Tab. VII sequences, whole (per-step statistics: the example
    // motion_sequences).
    let ik = ik_motion_sequence(&home.pose(), 1300);
    group.bench_function("ik_motion_1300_poses", |b| {
        b.iter(|| run_trajectory(&mut solver, black_box(&Targets::Poses(ik.clone())), &w).1)
    });
    // The ψ = 0 twin: the same robot as the reference 9-DoF design (with four tendons at
    // 90° a roll of 90° only renames the pairs, MODEL.md §1), whose pair labels the
    // sequence is written for.
    let d9 = design("lilge2022_redundant_psi0.ron");
    let mut solver9 = Solver::new(&d9).unwrap();
    let fk = fk_motion_sequence(solver9.model().pairs, 1000);
    for (name, reuse) in [
        ("fk_motion_1000_steps_9dof", true),
        ("fk_motion_1000_steps_9dof_own_jacobians", false),
    ] {
        solver9.reuse_jacobian = reuse;
        group.bench_function(name, |b| {
            b.iter(|| {
                run_trajectory(
                    &mut solver9,
                    black_box(&Targets::Actuations(fk.clone())),
                    &w,
                )
                .1
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).measurement_time(std::time::Duration::from_secs(3));
    targets = bench_jacobians, bench_solves
}
criterion_main!(benches);
