//! Leg integration with and without exact sensitivities, and single-TDCR solves.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;
use tdpcr::Tdcr;
use tdpcr::design::{MAX_TENDONS, Tendon};
use tdpcr::rod::{
    Frame, LegEnd, LegModel, LegScratch, LegSensitivities, LegStart, integrate_leg,
    integrate_leg_with_sensitivities,
};
use tdpcr::tdcr::{TdcrSolver, TendonControl, TipWrench};

fn reference() -> Tdcr {
    Tdcr::from_ron_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/designs/tdcr_one_segment.ron"
    ))
    .unwrap()
}

/// The reference leg with two antagonistic pairs (as in the 9-DoF design).
fn four_tendons() -> Tdcr {
    let mut r = reference();
    r.leg.tendons.extend([
        Tendon {
            angle: std::f64::consts::FRAC_PI_2,
            offset: 0.005,
            end: 0.145,
        },
        Tendon {
            angle: 3.0 * std::f64::consts::FRAC_PI_2,
            offset: 0.005,
            end: 0.145,
        },
    ]);
    r
}

fn bench_integration(c: &mut Criterion) {
    let mut group = c.benchmark_group("leg_integration");
    for (name, robot) in [("2_tendons", reference()), ("4_tendons", four_tendons())] {
        let model = LegModel::new(&robot.leg, Vector3::new(0.0, 0.0, -9.81));
        let nt = model.n_tendons;
        let mut tensions = [0.0; MAX_TENDONS];
        tensions[0] = 3.2;
        tensions[2 % nt] += 0.7;
        let start = LegStart {
            base: Frame::identity(),
            u0: Vector3::new(0.3, 6.0, 0.0),
            v0: Vector3::new(0.0, 0.0, 0.99992),
            tensions,
        };
        let mut scratch = LegScratch::new();
        let mut end = LegEnd::zeros();
        group.bench_function(format!("{name}/primal"), |b| {
            b.iter(|| {
                integrate_leg(&model, black_box(&start), &mut scratch, &mut end, None).unwrap()
            })
        });
        for nd in [6, 6 + nt] {
            let mut sens = LegSensitivities::new(nd);
            group.bench_function(format!("{name}/sensitivities_{nd}"), |b| {
                b.iter(|| {
                    integrate_leg_with_sensitivities(
                        &model,
                        black_box(&start),
                        &mut scratch,
                        &mut end,
                        &mut sens,
                        None,
                    )
                    .unwrap()
                })
            });
        }
    }
    group.finish();
}

fn bench_tdcr_solve(c: &mut Criterion) {
    let mut group = c.benchmark_group("tdcr_solve_cold");
    let robot = reference();
    let mut solver = TdcrSolver::new(&robot);
    let w = TipWrench::default();
    let pull = TendonControl::Displacement(vec![-0.005, 0.005]);
    group.bench_function("displacement_5mm", |b| {
        b.iter(|| solver.solve(black_box(&pull), &w, None).unwrap())
    });
    let tension = TendonControl::Tension(vec![3.2, 0.0]);
    group.bench_function("tension_3.2N", |b| {
        b.iter(|| solver.solve(black_box(&tension), &w, None).unwrap())
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(50).measurement_time(std::time::Duration::from_secs(3));
    targets = bench_integration, bench_tdcr_solve
}
criterion_main!(benches);
