#![allow(clippy::needless_range_loop)]
//! Exact sensitivities against central finite differences (MODEL.md §5).
//!
//! Error measure, stated once: the Jacobian is split into output blocks (tip position, tip
//! rotation, tip force, tip moment, tendon lengths; for the TDCR residual: force rows,
//! moment rows, length rows). Each column is scaled by a characteristic size of its
//! unknown (u(0): 1/L = 6.9 1/m; v(0): 1e-4; τ: 1 N; γ: 1 √N), so that entries of one
//! block share a unit. The relative error of a block is max|exact − FD| / max|FD| over
//! all its (scaled) entries, i.e. the max-entry matrix norm. Central differences are
//! Richardson-extrapolated (O(h⁴)), with steps 1e-3·max(1, |x|) in u(0) and τ,
//! 1e-3·max(0.1, |γ|) in γ (never crossing γ = 0 at the states used), and 1e-7 in v(0)
//! (the rod is ~1e4 times stiffer in shear and extension than in bending).

mod common;

use common::{Rng, central_difference, design_path};
use nalgebra::{DMatrix, DVector, Rotation3, Vector3};
use tdpcr::Tdcr;
use tdpcr::design::{Integrator, MAX_TENDONS, Tendon};
use tdpcr::rod::{
    Frame, LegEnd, LegModel, LegScratch, LegSensitivities, LegStart, integrate_leg,
    integrate_leg_with_sensitivities,
};
use tdpcr::tdcr::{TdcrSolver, TdcrState, TendonControl, TipWrench};

const TOLERANCE: f64 = 1e-6;

fn blocks(e: &LegEnd, nt: usize) -> [Vec<f64>; 5] {
    [
        e.p.iter().copied().collect(),
        e.r.iter().copied().collect(),
        e.n.iter().copied().collect(),
        e.m.iter().copied().collect(),
        e.lengths[..nt].to_vec(),
    ]
}

fn model_of(robot: &Tdcr) -> LegModel {
    let (gx, gy, gz) = robot.gravity;
    LegModel::new(&robot.leg, Vector3::new(gx, gy, gz))
}

/// A robot with `n` random tendons, ends at disks or anywhere along the rod.
fn random_robot(rng: &mut Rng, n: usize) -> Tdcr {
    let mut robot = Tdcr::from_ron_file(design_path("tdcr_one_segment.ron")).unwrap();
    robot.leg.tendons = (0..n)
        .map(|_| {
            let end = if rng.uniform(0.0, 1.0) < 0.5 {
                robot.leg.length
            } else {
                rng.uniform(0.2, 1.0) * robot.leg.length
            };
            Tendon {
                angle: rng.uniform(0.0, std::f64::consts::TAU),
                offset: rng.uniform(0.001, 0.006),
                end,
            }
        })
        .collect();
    robot.gravity = (rng.uniform(-9.81, 9.81), rng.uniform(-9.81, 9.81), -9.81);
    robot
}

fn random_start(rng: &mut Rng, nt: usize) -> LegStart {
    let axis = Vector3::new(
        rng.uniform(-1.0, 1.0),
        rng.uniform(-1.0, 1.0),
        rng.uniform(-1.0, 1.0),
    );
    let mut tensions = [0.0; MAX_TENDONS];
    for t in tensions.iter_mut().take(nt) {
        // About a third of the tendons slack (zero tension).
        *t = if rng.uniform(0.0, 1.0) < 0.35 {
            0.0
        } else {
            rng.uniform(0.2, 6.0)
        };
    }
    LegStart {
        base: Frame {
            position: Vector3::new(
                rng.uniform(-0.1, 0.1),
                rng.uniform(-0.1, 0.1),
                rng.uniform(-0.1, 0.1),
            ),
            rotation: *Rotation3::new(axis * rng.uniform(0.0, 2.0)).matrix(),
        },
        u0: Vector3::new(
            rng.uniform(-8.0, 8.0),
            rng.uniform(-8.0, 8.0),
            rng.uniform(-1.0, 1.0),
        ),
        v0: Vector3::new(
            rng.uniform(-1e-4, 1e-4),
            rng.uniform(-1e-4, 1e-4),
            1.0 + rng.uniform(-2e-4, 1e-4),
        ),
        tensions,
    }
}

/// Characteristic size of each unknown kind (see the module doc).
const SCALE_U: f64 = 1.0 / 0.145;
const SCALE_V: f64 = 1e-4;
const SCALE_TENSION: f64 = 1.0;
const SCALE_GAMMA: f64 = 1.0;

/// Max-entry relative error per row block of column-scaled Jacobians; the worst block.
fn block_error(
    jac: &DMatrix<f64>,
    fd: &DMatrix<f64>,
    col_scale: &[f64],
    row_block: &[usize],
) -> (f64, String) {
    let n_blocks = row_block.iter().max().map_or(0, |b| b + 1);
    let mut worst = (0.0, String::new());
    for b in 0..n_blocks {
        let mut num: f64 = 0.0;
        let mut den: f64 = 0.0;
        let mut at = (0, 0);
        for i in (0..jac.nrows()).filter(|&i| row_block[i] == b) {
            for j in 0..jac.ncols() {
                let e = (jac[(i, j)] - fd[(i, j)]).abs() * col_scale[j];
                if e > num || e.is_nan() {
                    num = e;
                    at = (i, j);
                }
                den = den.max(fd[(i, j)].abs() * col_scale[j]);
            }
        }
        let rel = num / den;
        if rel > worst.0 || rel.is_nan() {
            let (i, j) = at;
            worst = (
                rel,
                format!(
                    "block {b}, row {i}, column {j}: exact {:e} vs fd {:e}",
                    jac[(i, j)],
                    fd[(i, j)]
                ),
            );
        }
    }
    worst
}

fn leg_end_vector(e: &LegEnd, nt: usize) -> DVector<f64> {
    let b = blocks(e, nt);
    DVector::from_iterator(18 + nt, b.into_iter().flatten())
}

/// Worst block error of the leg sensitivities, exact vs central differences.
fn worst_leg_error(model: &LegModel, start: &LegStart) -> (f64, String) {
    let nt = model.n_tendons;
    let nd = 6 + nt;
    let mut scratch = LegScratch::new();
    let mut end = LegEnd::zeros();
    let mut sens = LegSensitivities::new(nd);
    integrate_leg_with_sensitivities(model, start, &mut scratch, &mut end, &mut sens, None)
        .unwrap();
    let mut fd_scratch = LegScratch::new();
    let mut eval = |s: &LegStart| {
        let mut e = LegEnd::zeros();
        integrate_leg(model, s, &mut fd_scratch, &mut e, None).unwrap();
        leg_end_vector(&e, nt)
    };
    let rows = 18 + nt;
    let mut jac = DMatrix::zeros(rows, nd);
    let mut fd = DMatrix::zeros(rows, nd);
    let mut col_scale = vec![0.0; nd];
    for j in 0..nd {
        jac.set_column(j, &leg_end_vector(&sens.d[j], nt));
        col_scale[j] = match j {
            0..3 => SCALE_U,
            3..6 => SCALE_V,
            _ => SCALE_TENSION,
        };
        let h = match j {
            0..3 => 1e-3 * start.u0[j].abs().max(1.0),
            3..6 => 1e-7,
            _ => 1e-3 * start.tensions[j - 6].abs().max(1.0),
        };
        let column = central_difference(
            |d| {
                let mut s = *start;
                match j {
                    0..3 => s.u0[j] += d,
                    3..6 => s.v0[j - 3] += d,
                    _ => s.tensions[j - 6] += d,
                }
                eval(&s)
            },
            h,
        );
        fd.set_column(j, &column);
    }
    let row_block: Vec<usize> = (0..rows)
        .map(|i| match i {
            0..3 => 0,
            3..12 => 1,
            12..15 => 2,
            15..18 => 3,
            _ => 4,
        })
        .collect();
    block_error(&jac, &fd, &col_scale, &row_block)
}

#[test]
fn leg_sensitivities_match_central_differences_at_random_states() {
    let mut rng = Rng::new(7);
    let mut robots = vec![
        Tdcr::from_ron_file(design_path("tdcr_one_segment.ron")).unwrap(),
        Tdcr::from_ron_file(design_path("tdcr_two_segment.ron")).unwrap(),
    ];
    for n in [1, 3, 5] {
        robots.push(random_robot(&mut rng, n));
    }
    let mut overall: f64 = 0.0;
    // Each design with both integration methods (the tangents go through each method's
    // stage sums).
    let both = robots.iter().flat_map(|robot| {
        [Integrator::Rk5, Integrator::Rk4].map(|integrator| {
            let mut robot = robot.clone();
            robot.leg.integrator = integrator;
            robot
        })
    });
    for robot in both {
        let model = model_of(&robot);
        for _ in 0..6 {
            let start = random_start(&mut rng, model.n_tendons);
            let (err, at) = worst_leg_error(&model, &start);
            assert!(
                err <= TOLERANCE,
                "relative error {err:.2e} > {TOLERANCE:.0e} at {at}"
            );
            overall = overall.max(err);
        }
    }
    eprintln!("worst relative error of leg sensitivities: {overall:.2e}");
}

/// Worst block error of the TDCR residual Jacobian at `state`.
fn worst_residual_error(
    solver: &mut TdcrSolver,
    control: &TendonControl,
    wrench: &TipWrench,
    state: &TdcrState,
) -> f64 {
    let (_, jac) = solver
        .residual_and_jacobian(control, wrench, state)
        .unwrap();
    let jac_fd = fd_jacobian(solver, control, wrench, state);
    jacobian_error(&jac, &jac_fd, state.gammas.len())
}

fn fd_jacobian(
    solver: &mut TdcrSolver,
    control: &TendonControl,
    wrench: &TipWrench,
    state: &TdcrState,
) -> DMatrix<f64> {
    let ng = state.gammas.len();
    let n = ng + 6;
    let mut jac = DMatrix::zeros(n, n);
    for j in 0..n {
        let h = if j < ng {
            1e-3 * state.gammas[j].abs().max(0.1)
        } else if j < ng + 3 {
            1e-3 * state.u0[j - ng].abs().max(1.0)
        } else {
            1e-7
        };
        let column = central_difference(
            |d| {
                let mut s = state.clone();
                if j < ng {
                    s.gammas[j] += d;
                } else if j < ng + 3 {
                    s.u0[j - ng] += d;
                } else {
                    s.v0[j - ng - 3] += d;
                }
                solver.residual(control, wrench, &s).unwrap()
            },
            h,
        );
        jac.set_column(j, &column);
    }
    jac
}

/// Residual rows: force (0), moment (1), tendon lengths (2); columns γ, u(0), v(0).
fn jacobian_error(jac: &DMatrix<f64>, fd: &DMatrix<f64>, ng: usize) -> f64 {
    let col_scale: Vec<f64> = (0..jac.ncols())
        .map(|j| {
            if j < ng {
                SCALE_GAMMA
            } else if j < ng + 3 {
                SCALE_U
            } else {
                SCALE_V
            }
        })
        .collect();
    let row_block: Vec<usize> = (0..jac.nrows()).map(|i| (i / 3).min(2)).collect();
    let (e, at) = block_error(jac, fd, &col_scale, &row_block);
    if e > TOLERANCE {
        eprintln!("worst: {e:.2e} at {at}");
    }
    e
}

fn random_state(rng: &mut Rng, nt: usize, displacement: bool) -> TdcrState {
    let gammas = if displacement {
        // Off the C¹ kink at γ = 0 on both sides: slack (γ < 0) and taut tendons.
        (0..nt)
            .map(|_| {
                let g = rng.uniform(0.1, 2.4);
                if rng.uniform(0.0, 1.0) < 0.4 {
                    -0.05 * g
                } else {
                    g
                }
            })
            .collect()
    } else {
        vec![]
    };
    TdcrState {
        u0: [
            rng.uniform(-8.0, 8.0),
            rng.uniform(-8.0, 8.0),
            rng.uniform(-1.0, 1.0),
        ],
        v0: [
            rng.uniform(-1e-4, 1e-4),
            rng.uniform(-1e-4, 1e-4),
            1.0 + rng.uniform(-2e-4, 1e-4),
        ],
        gammas,
    }
}

#[test]
fn tdcr_residual_jacobian_matches_central_differences_in_both_tendon_modes() {
    let mut rng = Rng::new(11);
    let robots = [
        Tdcr::from_ron_file(design_path("tdcr_one_segment.ron")).unwrap(),
        Tdcr::from_ron_file(design_path("tdcr_two_segment.ron")).unwrap(),
    ];
    let wrench = TipWrench {
        force: Vector3::new(0.05, -0.02, 0.1),
        moment: Vector3::new(0.001, 0.0, -0.002),
    };
    let mut worst: f64 = 0.0;
    for robot in &robots {
        let mut solver = TdcrSolver::new(robot);
        let nt = robot.leg.tendons.len();
        for _ in 0..5 {
            let d =
                TendonControl::Displacement((0..nt).map(|_| rng.uniform(-0.005, 0.005)).collect());
            let state = random_state(&mut rng, nt, true);
            let err = worst_residual_error(&mut solver, &d, &wrench, &state);
            assert!(
                err <= TOLERANCE,
                "displacement mode: relative error {err:.2e}"
            );
            worst = worst.max(err);
            let t = TendonControl::Tension((0..nt).map(|_| rng.uniform(0.0, 4.0)).collect());
            let state = random_state(&mut rng, nt, false);
            let err = worst_residual_error(&mut solver, &t, &wrench, &state);
            assert!(err <= TOLERANCE, "tension mode: relative error {err:.2e}");
            worst = worst.max(err);
        }
    }
    eprintln!("worst relative error of the TDCR residual Jacobian: {worst:.2e}");
}

#[test]
fn the_checker_rejects_a_jacobian_with_one_column_sign_flipped() {
    let robot = Tdcr::from_ron_file(design_path("tdcr_one_segment.ron")).unwrap();
    let mut solver = TdcrSolver::new(&robot);
    let control = TendonControl::Displacement(vec![-0.004, 0.004]);
    let state = TdcrState {
        u0: [0.5, 5.0, 0.0],
        v0: [0.0, 0.0, 0.9999],
        gammas: vec![1.7, -0.02],
    };
    let (_, mut jac) = solver
        .residual_and_jacobian(&control, &TipWrench::default(), &state)
        .unwrap();
    let fd = fd_jacobian(&mut solver, &control, &TipWrench::default(), &state);
    assert!(jacobian_error(&jac, &fd, 2) <= TOLERANCE);
    for j in 0..jac.ncols() {
        let mut flipped = jac.clone();
        flipped.column_mut(j).neg_mut();
        assert!(
            jacobian_error(&flipped, &fd, 2) > 1e-3,
            "flipping column {j} went unnoticed"
        );
    }
    // The largest entry of the length rows, off by 1e-4 relative.
    let (i, j) = (6..8)
        .flat_map(|i| (0..8).map(move |j| (i, j)))
        .max_by(|a, b| jac[*a].abs().total_cmp(&jac[*b].abs()))
        .unwrap();
    jac[(i, j)] *= 1.0 + 1e-4;
    assert!(
        jacobian_error(&jac, &fd, 2) > TOLERANCE,
        "a 1e-4 relative error in one entry went unnoticed"
    );
}

#[test]
fn repeated_integrations_on_one_scratch_are_bitwise_identical() {
    let robot = Tdcr::from_ron_file(design_path("tdcr_two_segment.ron")).unwrap();
    let model = model_of(&robot);
    let mut rng = Rng::new(3);
    let start = random_start(&mut rng, model.n_tendons);
    let other = random_start(&mut rng, model.n_tendons);
    let mut scratch = LegScratch::new();
    let nd = 6 + model.n_tendons;
    let run = |s: &LegStart, sc: &mut LegScratch| {
        let mut e = LegEnd::zeros();
        let mut sens = LegSensitivities::new(nd);
        integrate_leg_with_sensitivities(&model, s, sc, &mut e, &mut sens, None).unwrap();
        (e, sens.d)
    };
    let first = run(&start, &mut scratch);
    for _ in 0..20 {
        run(&other, &mut scratch);
        assert_eq!(run(&start, &mut scratch), first);
    }
    // The primal-only integration gives the same tip as the one with sensitivities.
    let mut e = LegEnd::zeros();
    integrate_leg(&model, &start, &mut scratch, &mut e, None).unwrap();
    assert_eq!(e, first.0);
}
