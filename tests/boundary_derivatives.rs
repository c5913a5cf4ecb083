//! The exact blocks B_x, B_q, B_w, B_u against central finite differences
//! (Richardson-extrapolated, O(h⁴); steps 1e-4 in pose and q, 1e-2 in the wrench,
//! 4e-3·max(1, |x|) in γ and u(0), 1e-7 in v(0)), and the product's finite-difference
//! baseline against the exact blocks.
//!
//! Error measure: each block's rows are grouped by kind (platform force, platform moment,
//! coupling position, joint moment, tendon lengths), and each column is scaled by a
//! characteristic size of its unknown (position 1 cm, rotation 0.1 rad, bending
//! actuation 1 mm, translation 1 cm, force 1 N, moment 0.1 N·m, γ or ζ 1, u(0) 1/L,
//! v(0) 1e-4), so one row kind shares a unit. The relative error of a row kind is
//! max|exact − FD| / max|FD| over its rows and all (scaled) columns, as in the leg tests.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{Rng, central_difference, design_path};
use nalgebra::{DMatrix, DVector, Rotation3, Vector3};
use tdpcr::Tdpcr;
use tdpcr::boundary::{
    BoundaryJacobians, BoundaryPoint, BoundaryScratch, FiniteDifference, boundary_derivatives,
    boundary_derivatives_fd, boundary_residual, boundary_residual_with_derivatives,
    convert_tendon_unknowns, gamma_columns_to_linear,
};
use tdpcr::model::{Model, Pose};
use tdpcr::rod::Wrench;
use tdpcr::rod::tendon::TendonUnknown;

/// Row kind of row i: 0 force, 1 moment, 2 coupling, 3 joint moment, 4 lengths.
fn row_kind(model: &Model, i: usize) -> usize {
    if i < 6 {
        return i / 3;
    }
    let j = (i - 6) % model.n_leg_unknowns();
    if j < 3 {
        2
    } else if j < 6 {
        3
    } else {
        4
    }
}

/// Worst relative error over row kinds: for each kind, max|exact − FD|·c_j / max|FD|·c_j
/// over its rows and all columns, with c_j the characteristic size of column j's unknown.
fn sub_block_error(
    a: &DMatrix<f64>,
    fd: &DMatrix<f64>,
    rows: &[usize],
    col_scale: &[f64],
) -> (f64, String) {
    let mut worst = (0.0, String::new());
    let n_rk = rows.iter().max().unwrap() + 1;
    for rk in 0..n_rk {
        let (mut num, mut den) = (0.0f64, 0.0f64);
        let mut at = (0, 0);
        for i in (0..a.nrows()).filter(|&i| rows[i] == rk) {
            for j in 0..a.ncols() {
                let e = (a[(i, j)] - fd[(i, j)]).abs() * col_scale[j];
                if e > num {
                    num = e;
                    at = (i, j);
                }
                den = den.max(fd[(i, j)].abs() * col_scale[j]);
            }
        }
        let rel = if den > 0.0 {
            num / den
        } else if num > 0.0 {
            f64::INFINITY
        } else {
            0.0
        };
        if rel > worst.0 {
            worst = (
                rel,
                format!(
                    "rows of kind {rk}, entry {at:?}: exact {:e} vs fd {:e}",
                    a[at], fd[at]
                ),
            );
        }
    }
    worst
}

fn random_point(model: &Model, rng: &mut Rng) -> (Pose, Vec<f64>, Wrench, Vec<f64>) {
    let axis = Vector3::new(
        rng.uniform(-1.0, 1.0),
        rng.uniform(-1.0, 1.0),
        rng.uniform(-1.0, 1.0),
    );
    let pose = Pose {
        position: Vector3::new(
            rng.uniform(-0.03, 0.03),
            rng.uniform(-0.03, 0.03),
            rng.uniform(-0.03, 0.03),
        ),
        rotation: *Rotation3::new(axis * 0.2).matrix(),
    };
    let q: Vec<f64> = (0..model.n_actuators())
        .map(|k| {
            if k % (model.pairs + 1) == model.pairs {
                rng.uniform(-0.05, 0.05)
            } else {
                rng.uniform(-0.008, 0.008)
            }
        })
        .collect();
    let wrench = Wrench {
        force: model.platform_weight
            + Vector3::new(
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
            ),
        moment: Vector3::new(
            rng.uniform(-0.05, 0.05),
            rng.uniform(-0.05, 0.05),
            rng.uniform(-0.05, 0.05),
        ),
    };
    let nt = model.n_tendons();
    let mut y_u = vec![];
    for _ in 0..3 {
        for k in 0..nt {
            // Taut and slack tendons (γ < 0), away from the kink at 0.
            let g = rng.uniform(0.3, 2.0);
            y_u.push(if k % 2 == 1 { -0.05 * g } else { g });
        }
        y_u.extend([
            rng.uniform(-5.0, 5.0),
            rng.uniform(-5.0, 5.0),
            rng.uniform(-0.5, 0.5),
        ]);
        y_u.extend([
            rng.uniform(-1e-4, 1e-4),
            rng.uniform(-1e-4, 1e-4),
            1.0 + rng.uniform(-2e-4, 0.0),
        ]);
    }
    (pose, q, wrench, y_u)
}

/// (name, exact, reference, column scales) of one Jacobian block.
type BlockPair<'a> = (&'a str, &'a DMatrix<f64>, &'a DMatrix<f64>, Vec<f64>);

/// Which input a column perturbs.
#[derive(Clone, Copy)]
enum Input {
    Position(usize),
    Rotation(usize),
    Actuation(usize),
    Wrench(usize),
    Unknown(usize),
}

/// Reference blocks by extrapolated central differences of the residual.
fn reference_blocks(
    model: &Model,
    pose: &Pose,
    q: &[f64],
    wrench: &Wrench,
    y_u: &[f64],
    tendon_unknown: TendonUnknown,
) -> BoundaryJacobians {
    let mut sc = BoundaryScratch::new(model);
    let mut out = BoundaryJacobians::new(model);
    let nu = model.n_leg_unknowns();
    let nt = model.n_tendons();
    let mut column = |input: Input, h: f64| {
        central_difference(
            |d| {
                let (mut pose, mut q, mut wrench, mut y_u) =
                    (*pose, q.to_vec(), *wrench, y_u.to_vec());
                match input {
                    Input::Position(c) => pose.position[c] += d,
                    Input::Rotation(c) => {
                        let mut axis = Vector3::zeros();
                        axis[c] = d;
                        pose.rotation = Rotation3::new(axis).matrix() * pose.rotation;
                    }
                    Input::Actuation(c) => q[c] += d,
                    Input::Wrench(c) if c < 3 => wrench.force[c] += d,
                    Input::Wrench(c) => wrench.moment[c - 3] += d,
                    Input::Unknown(c) => y_u[c] += d,
                }
                let mut r = DVector::zeros(model.n_residuals());
                let p = BoundaryPoint {
                    pose: &pose,
                    q: &q,
                    wrench: &wrench,
                    y_u: &y_u,
                    tendon_unknown,
                };
                boundary_residual(model, &mut sc, &p, &mut r).unwrap();
                r
            },
            h,
        )
    };
    for c in 0..3 {
        out.b_x.set_column(c, &column(Input::Position(c), 1e-4));
        out.b_x.set_column(3 + c, &column(Input::Rotation(c), 1e-4));
    }
    for c in 0..q.len() {
        out.b_q.set_column(c, &column(Input::Actuation(c), 1e-4));
    }
    for c in 0..6 {
        out.b_w.set_column(c, &column(Input::Wrench(c), 1e-2));
    }
    for c in 0..y_u.len() {
        let k = c % nu;
        let h = if k < nt + 3 {
            4e-3 * y_u[c].abs().max(1.0)
        } else {
            1e-7
        };
        out.b_u.set_column(c, &column(Input::Unknown(c), h));
    }
    out
}

/// The γ columns of B_u converted to the solver's ζ ([`gamma_columns_to_linear`]) are
/// the blocks evaluated in ζ directly, at the same point.
/// The model of a bundled design, its evaluation buffers and two sets of blocks.
fn model_and_buffers(file: &str) -> (Model, BoundaryScratch, [BoundaryJacobians; 2]) {
    let design = Tdpcr::from_ron_file(design_path(file)).unwrap();
    let model = Model::new(&design);
    let sc = BoundaryScratch::new(&model);
    let blocks = [
        BoundaryJacobians::new(&model),
        BoundaryJacobians::new(&model),
    ];
    (model, sc, blocks)
}

#[test]
fn gamma_columns_converted_to_linear_are_the_linear_blocks() {
    let mut rng = Rng::new(11);
    for file in ["lilge2022.ron", "lilge2022_redundant.ron"] {
        let (model, mut sc, [mut by_gamma, mut by_zeta]) = model_and_buffers(file);
        let m = model.n_residuals();
        let mut r = DVector::zeros(m);
        for _ in 0..3 {
            let (pose, q, wrench, y_u) = random_point(&model, &mut rng);
            let mut zeta = y_u.clone();
            convert_tendon_unknowns(
                &model,
                &mut zeta,
                TendonUnknown::Gamma,
                TendonUnknown::Linear,
            );
            for (y, unknown, out) in [
                (&y_u, TendonUnknown::Gamma, &mut by_gamma),
                (&zeta, TendonUnknown::Linear, &mut by_zeta),
            ] {
                let p = BoundaryPoint {
                    pose: &pose,
                    q: &q,
                    wrench: &wrench,
                    y_u: y,
                    tendon_unknown: unknown,
                };
                boundary_derivatives(&model, &mut sc, &p, &mut r, out).unwrap();
            }
            let mut converted = by_gamma.b_u.clone();
            assert!(gamma_columns_to_linear(&model, &y_u, &mut converted, 0));
            let err = (&converted - &by_zeta.b_u).amax() / by_zeta.b_u.amax();
            assert!(err < 1e-12, "{file}: relative difference {err:.2e}");
            // A tendon exactly at γ = 0 has no ζ column to recover.
            let mut at_kink = y_u.clone();
            at_kink[model.tendon_unknown_indices().next().unwrap()] = 0.0;
            assert!(!gamma_columns_to_linear(
                &model,
                &at_kink,
                &mut converted,
                0
            ));
        }
    }
}

#[test]
fn exact_blocks_match_central_differences_for_both_designs() {
    let mut rng = Rng::new(5);
    let mut overall: f64 = 0.0;
    let mut baseline_worst: f64 = 0.0;
    for file in ["lilge2022.ron", "lilge2022_redundant.ron"] {
        let design = Tdpcr::from_ron_file(design_path(file)).unwrap();
        let model = Model::new(&design);
        let m = model.n_residuals();
        assert_eq!(m, if model.pairs == 1 { 30 } else { 36 });
        let rows: Vec<usize> = (0..m).map(|i| row_kind(&model, i)).collect();
        let mut sc = BoundaryScratch::new(&model);
        let mut exact = BoundaryJacobians::new(&model);
        let mut baseline = BoundaryJacobians::new(&model);
        let (mut r1, mut r2) = (DVector::zeros(m), DVector::zeros(m));
        for trial in 0..6 {
            // The paper's γ, and the solver's piecewise-linear variable (off its kink).
            let tendon_unknown = if trial % 2 == 0 {
                TendonUnknown::Gamma
            } else {
                TendonUnknown::Linear
            };
            let (pose, q, wrench, y_u) = random_point(&model, &mut rng);
            let p = BoundaryPoint {
                pose: &pose,
                q: &q,
                wrench: &wrench,
                y_u: &y_u,
                tendon_unknown,
            };
            boundary_derivatives(&model, &mut sc, &p, &mut r1, &mut exact).unwrap();
            boundary_derivatives_fd(
                &model,
                &mut sc,
                &p,
                FiniteDifference::Central,
                &mut r2,
                &mut baseline,
            )
            .unwrap();
            assert_eq!(
                r1, r2,
                "the residual does not depend on the Jacobian method"
            );
            let fd = reference_blocks(&model, &pose, &q, &wrench, &y_u, tendon_unknown);
            let nu = model.n_leg_unknowns();
            let nt = model.n_tendons();
            // Column scales of B_u: γ or ζ 1, u(0) 1/L, v(0) 1e-4.
            let b_u_scales: Vec<f64> = (0..3 * nu)
                .map(|j| match j % nu {
                    k if k < nt => 1.0,
                    k if k < nt + 3 => 1.0 / 0.145,
                    _ => 1e-4,
                })
                .collect();
            let kinds: [BlockPair; 4] = [
                (
                    "B_x",
                    &exact.b_x,
                    &fd.b_x,
                    (0..6).map(|j| if j < 3 { 0.01 } else { 0.1 }).collect(),
                ),
                (
                    "B_q",
                    &exact.b_q,
                    &fd.b_q,
                    (0..model.n_actuators())
                        .map(|j| {
                            if j % (model.pairs + 1) == model.pairs {
                                0.01
                            } else {
                                0.001
                            }
                        })
                        .collect(),
                ),
                (
                    "B_w",
                    &exact.b_w,
                    &fd.b_w,
                    (0..6).map(|j| if j < 3 { 1.0 } else { 0.1 }).collect(),
                ),
                ("B_u", &exact.b_u, &fd.b_u, b_u_scales.clone()),
            ];
            let baselines = [&baseline.b_x, &baseline.b_q, &baseline.b_w, &baseline.b_u];
            for ((name, a, f, cols), b) in kinds.into_iter().zip(baselines) {
                let (err, at) = sub_block_error(a, f, &rows, &cols);
                assert!(
                    err <= 1e-6,
                    "{file} {name}: relative error {err:.2e} at {at}"
                );
                overall = overall.max(err);
                // The product's plain central-difference baseline is limited by round-off
                // in the stiff force rows (~1e-6); it must still agree to 1e-4.
                let (err, at) = sub_block_error(b, a, &rows, &cols);
                assert!(
                    err <= 1e-4,
                    "{file} {name} baseline: relative error {err:.2e} at {at}"
                );
                baseline_worst = baseline_worst.max(err);
            }
            // Negative controls: the measure sees a flipped column and a 1e-4 error in the
            // largest entry of the joint-moment rows of B_u.
            let mut flipped = exact.b_u.clone();
            flipped.column_mut(nt + 1).neg_mut();
            assert!(sub_block_error(&flipped, &fd.b_u, &rows, &b_u_scales).0 > 1e-3);
            let (i, j) = (0..m)
                .filter(|&i| rows[i] == 3)
                .flat_map(|i| (0..3 * nu).map(move |j| (i, j)))
                .max_by(|a, b| {
                    (fd.b_u[*a] * b_u_scales[a.1])
                        .abs()
                        .total_cmp(&(fd.b_u[*b] * b_u_scales[b.1]).abs())
                })
                .unwrap();
            let mut nudged = exact.b_u.clone();
            nudged[(i, j)] *= 1.0 + 1e-4;
            assert!(sub_block_error(&nudged, &fd.b_u, &rows, &b_u_scales).0 > 1e-6);
        }
    }
    eprintln!("worst relative error of the boundary blocks: {overall:.2e}");
    eprintln!("worst relative error of the central-difference baseline: {baseline_worst:.2e}");
}

/// Skipping the tension directions of slack tendons (the default) changes no block: a
/// slack tendon's column uses only its length row. Checked with both tendon unknowns, legs
/// with different numbers of slack tendons, and a tendon exactly at its kink.
#[test]
fn skipping_slack_tension_directions_changes_no_block() {
    let mut rng = Rng::new(23);
    for file in ["lilge2022.ron", "lilge2022_redundant.ron"] {
        let (model, mut sc, [mut skipped, mut full]) = model_and_buffers(file);
        let m = model.n_residuals();
        let (mut r1, mut r2) = (DVector::zeros(m), DVector::zeros(m));
        for trial in 0..4 {
            let (pose, q, wrench, mut y_u) = random_point(&model, &mut rng);
            let tendons: Vec<usize> = model.tendon_unknown_indices().collect();
            // Leg 0 all taut, one tendon of leg 1 at its kink.
            for &i in &tendons[..model.n_tendons()] {
                y_u[i] = y_u[i].abs();
            }
            y_u[tendons[model.n_tendons()]] = 0.0;
            let tendon_unknown = if trial % 2 == 0 {
                TendonUnknown::Gamma
            } else {
                TendonUnknown::Linear
            };
            let p = BoundaryPoint {
                pose: &pose,
                q: &q,
                wrench: &wrench,
                y_u: &y_u,
                tendon_unknown,
            };
            sc.keep_slack_tension_directions(false);
            boundary_derivatives(&model, &mut sc, &p, &mut r1, &mut skipped).unwrap();
            sc.keep_slack_tension_directions(true);
            boundary_derivatives(&model, &mut sc, &p, &mut r2, &mut full).unwrap();
            assert_eq!(r1, r2, "{file}, trial {trial}: residual");
            assert_eq!(skipped.b_x, full.b_x, "{file}, trial {trial}: B_x");
            assert_eq!(skipped.b_q, full.b_q, "{file}, trial {trial}: B_q");
            assert_eq!(skipped.b_u, full.b_u, "{file}, trial {trial}: B_u");
        }
    }
}

/// An evaluation at the leg starts (q, y_u) of the buffers' last integration with
/// sensitivities reuses it, whatever its pose and wrench: the residual and blocks are
/// bitwise those of fresh buffers, and only evaluations at other starts (or needing
/// shapes or tension directions the last one did not integrate) integrate again.
#[test]
fn the_last_integration_serves_evaluations_at_the_same_leg_starts() {
    let mut rng = Rng::new(29);
    for file in ["lilge2022.ron", "lilge2022_redundant.ron"] {
        let (model, mut sc, [mut blocks, mut fresh_blocks]) = model_and_buffers(file);
        let m = model.n_residuals();
        let (mut r, mut fresh_r) = (DVector::zeros(m), DVector::zeros(m));
        let (pose, q, wrench, y_u) = random_point(&model, &mut rng);
        let (other_pose, _, other_wrench, other_y) = random_point(&model, &mut rng);
        let point = |pose, wrench, y_u| BoundaryPoint {
            pose,
            q: &q,
            wrench,
            y_u,
            tendon_unknown: TendonUnknown::Gamma,
        };
        let p1 = point(&pose, &wrench, &y_u);
        // The same leg starts at another pose and wrench.
        let p1_moved = point(&other_pose, &other_wrench, &y_u);
        let p2 = point(&pose, &wrench, &other_y);
        // (evaluation, point, integrations it should add)
        #[derive(Clone, Copy, Debug)]
        enum Kind {
            Residual,
            Derivatives,
            Prepared,
        }
        let steps = [
            (Kind::Derivatives, &p1, 1),
            (Kind::Derivatives, &p1_moved, 0),
            (Kind::Residual, &p1_moved, 0),
            (Kind::Residual, &p2, 1),
            (Kind::Derivatives, &p1, 1),
            (Kind::Prepared, &p2, 1),
            (Kind::Derivatives, &p2, 0),
            (Kind::Residual, &p2, 0),
            (Kind::Derivatives, &p1_moved, 1),
        ];
        for (k, &(kind, p, added)) in steps.iter().enumerate() {
            let before = sc.integrations();
            let mut fresh = BoundaryScratch::new(&model);
            match kind {
                Kind::Derivatives => {
                    boundary_derivatives(&model, &mut sc, p, &mut r, &mut blocks).unwrap();
                    boundary_derivatives(&model, &mut fresh, p, &mut fresh_r, &mut fresh_blocks)
                        .unwrap();
                    assert_eq!(blocks, fresh_blocks, "{file}, step {k}: blocks");
                }
                Kind::Residual => {
                    boundary_residual(&model, &mut sc, p, &mut r).unwrap();
                    boundary_residual(&model, &mut fresh, p, &mut fresh_r).unwrap();
                }
                Kind::Prepared => {
                    boundary_residual_with_derivatives(&model, &mut sc, p, false, &mut r).unwrap();
                    boundary_residual(&model, &mut fresh, p, &mut fresh_r).unwrap();
                }
            }
            assert_eq!(r, fresh_r, "{file}, step {k} ({kind:?}): residual");
            assert_eq!(
                sc.integrations() - before,
                added,
                "{file}, step {k} ({kind:?}): integrations"
            );
        }
        // Shapes: recorded by an integration only when asked; an evaluation that wants
        // them does not take an integration without.
        sc.record_shapes(&model, true);
        let before = sc.integrations();
        boundary_derivatives(&model, &mut sc, &p1_moved, &mut r, &mut blocks).unwrap();
        assert_eq!(sc.integrations() - before, 1, "{file}: shapes wanted");
        let mut fresh = BoundaryScratch::new(&model);
        fresh.record_shapes(&model, true);
        boundary_derivatives(&model, &mut fresh, &p1, &mut fresh_r, &mut fresh_blocks).unwrap();
        let shapes = |s: &BoundaryScratch| {
            s.shapes()
                .unwrap()
                .iter()
                .map(|leg| format!("{leg:?}"))
                .collect::<Vec<_>>()
        };
        assert_eq!(shapes(&sc), shapes(&fresh), "{file}: shapes");
        boundary_derivatives(&model, &mut sc, &p1, &mut r, &mut blocks).unwrap();
        assert_eq!(sc.integrations() - before, 1, "{file}: shapes kept");
        // The slack tendons' tension directions, once asked for, are integrated.
        sc.keep_slack_tension_directions(true);
        boundary_derivatives(&model, &mut sc, &p1, &mut r, &mut blocks).unwrap();
        assert_eq!(sc.integrations() - before, 2, "{file}: slack directions");
        assert_eq!(blocks, fresh_blocks, "{file}: with slack directions");
    }
}
