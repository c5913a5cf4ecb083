//! The workspace sweep (MODEL.md §6): determinism across runs and thread counts, every
//! point a true equilibrium at its position, actuation limits, gridding, settings errors.

mod common;

use std::collections::BTreeSet;

use common::design_path;
use nalgebra::{Rotation3, Vector3};
use tdpcr::Tdpcr;
use tdpcr::kinetostatics::{RobotState, Solver};
use tdpcr::rod::Wrench;
use tdpcr::workspace::collision::CollisionChecker;
use tdpcr::workspace::{WorkspaceMap, WorkspacePoint, WorkspaceSettings, files, sweep_workspace};

fn reference() -> Tdpcr {
    Tdpcr::from_ron_file(design_path("lilge2022.ron")).unwrap()
}

/// A sweep that takes seconds: Δ = 10 mm, 8 rays, 3 planes.
fn coarse() -> WorkspaceSettings {
    WorkspaceSettings {
        step: 0.01,
        angle_step: 0.8,
        z_range: [-0.01, 0.01],
        ..Default::default()
    }
}

/// The largest |Δq_i| \[m\] between the states of two points.
fn q_difference(a: &WorkspacePoint, b: &WorkspacePoint) -> f64 {
    a.state
        .q
        .iter()
        .zip(&b.state.q)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn sweep_on(threads: usize, design: &Tdpcr, settings: &WorkspaceSettings) -> WorkspaceMap {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| sweep_workspace(design, settings).unwrap())
}

/// Everything of a map except timing and thread count.
fn comparable(map: &WorkspaceMap) -> (String, String) {
    let mut s = map.summary.clone();
    s.wall_time_s = 0.0;
    s.solves_per_second = 0.0;
    s.threads = 0;
    (files::points_csv(map), serde_json::to_string(&s).unwrap())
}

#[test]
fn coarse_sweep_is_identical_across_runs_and_thread_counts() {
    let design = reference();
    let settings = coarse();
    let one = sweep_on(1, &design, &settings);
    let two = sweep_on(2, &design, &settings);
    let again = sweep_on(2, &design, &settings);
    assert!(one.summary.counts.reachable > 50, "{:?}", one.summary);
    assert_eq!(one.summary.planes_reached, 3);
    assert_eq!(comparable(&one), comparable(&two), "1 vs 2 threads");
    assert_eq!(comparable(&two), comparable(&again), "two runs");
    assert_eq!(one.points, two.points);
    assert_eq!(two.summary.threads, 2);
}

#[test]
fn points_csv_formatted_in_parallel_blocks_keeps_the_order_of_the_map() {
    let mut map = sweep_on(1, &reference(), &coarse());
    // Past several formatting blocks: the coarse cells again and again, each copy moved
    // so that every line names its point.
    let cells = map.points.clone();
    while map.points.len() < 10_000 {
        let k = map.points.len();
        let mut p = cells[k % cells.len()].clone();
        p.position[0] = k as f64;
        map.points.push(p);
    }
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| files::points_csv(&map))
    };
    let (one, two) = (on(1), on(2));
    assert_eq!(one, two);
    let lines: Vec<&str> = two.lines().collect();
    assert_eq!(lines.len(), map.points.len() + 1);
    for (k, (line, p)) in lines[1..].iter().zip(&map.points).enumerate() {
        let x = line.split(',').next().unwrap();
        assert_eq!(x.parse::<f64>().unwrap(), p.position[0], "line {k}");
        assert_eq!(
            line.split(',').count(),
            lines[0].split(',').count(),
            "line {k}"
        );
    }
}

#[test]
fn every_point_is_an_equilibrium_that_fk_finds_again_from_its_q() {
    let design = reference();
    let settings = coarse();
    let map = sweep_on(2, &design, &settings);
    let mut solver = Solver::new(&design).unwrap();
    // FK near a Type II singularity can stall just above 1e-10 (round-off of the SI
    // residual); 1e-9 still pins the pose far below the 1e-6 m asked for.
    solver.settings.tolerance = 1e-9;
    let limits = &design.actuation_limits;
    for p in &map.points {
        let (r, _) = solver.blocks_at(&p.state, &Wrench::default()).unwrap();
        assert!(
            r.norm() <= settings.tolerance,
            "residual {} at {:?}",
            r.norm(),
            p.cell
        );
        // q within limits: [bend, translation] per leg.
        for leg in p.state.q.chunks(2) {
            assert!(
                leg[0].abs() <= limits.tendon_displacement
                    && leg[1].abs() <= limits.base_translation
            );
        }
        // FK from q, warm-started 2 mm and 0.01 rad away from the answer.
        let mut init: RobotState = p.state.clone();
        init.position[0] += 0.002;
        init.position[1] -= 0.002;
        init.rotvec[2] += 0.01;
        let fk = solver
            .solve_fk(&p.state.q, &Wrench::default(), Some(&init))
            .unwrap();
        let d = (Vector3::from(fk.state.position) - Vector3::from(p.position)).norm();
        assert!(d <= 1e-6, "FK lands {d:.2e} m away at {:?}", p.cell);
        let r = Rotation3::new(Vector3::from(fk.state.rotvec));
        assert!(r.angle_to(&Rotation3::identity()) <= 1e-6);
    }
}

#[test]
fn points_sit_in_their_cells_on_the_planes() {
    let settings = coarse();
    let map = sweep_on(2, &reference(), &settings);
    let h = settings.step / 2.0 + 1e-12;
    let mut seen = BTreeSet::new();
    for p in &map.points {
        assert!(seen.insert(p.cell), "cell {:?} twice", p.cell);
        let centre = p.cell.map(|i| i as f64 * settings.step);
        assert!((p.position[0] - centre[0]).abs() <= h && (p.position[1] - centre[1]).abs() <= h);
        assert!((p.position[2] - centre[2]).abs() <= 1e-12);
    }
    // Sorted by (z, y, x); the origin of each plane is a reachable cell.
    let keys: Vec<[i64; 3]> = map
        .points
        .iter()
        .map(|p| [p.cell[2], p.cell[1], p.cell[0]])
        .collect();
    assert!(keys.windows(2).all(|w| w[0] < w[1]));
    for k in -1..=1 {
        assert!(map.plane(k).any(|p| p.cell == [0, 0, k] && p.reachable()));
    }
    let s = &map.summary;
    assert_eq!(s.counts.reachable + s.counts.collision, map.points.len());
    assert!((s.volume.reachable - s.counts.reachable as f64 * 1e-6).abs() < 1e-15);
    assert!(s.rcond.j_p.min <= s.rcond.j_p.mean && s.rcond.j_p.mean <= s.rcond.j_p.max);
    assert!(s.solves >= map.points.len() && s.solves_per_second > 0.0);
}

#[test]
fn tighter_actuation_limits_give_a_subset_of_the_cells() {
    let loose_design = reference();
    let mut tight_design = reference();
    tight_design.actuation_limits.tendon_displacement = 0.004;
    tight_design.actuation_limits.base_translation = 0.03;
    let settings = coarse();
    let loose = sweep_on(2, &loose_design, &settings);
    let tight = sweep_on(2, &tight_design, &settings);
    let cells = |m: &WorkspaceMap, reachable: bool| -> BTreeSet<[i64; 3]> {
        m.points
            .iter()
            .filter(|p| !reachable || p.reachable())
            .map(|p| p.cell)
            .collect()
    };
    assert!(cells(&tight, false).is_subset(&cells(&loose, false)));
    assert!(cells(&tight, true).is_subset(&cells(&loose, true)));
    assert!(
        tight.summary.counts.reachable < loose.summary.counts.reachable,
        "{} vs {}",
        tight.summary.counts.reachable,
        loose.summary.counts.reachable
    );
    for p in &tight.points {
        for leg in p.state.q.chunks(2) {
            assert!(
                leg[0].abs() <= 0.004 && leg[1].abs() <= 0.03,
                "{:?}",
                p.state.q
            );
        }
    }
}

/// The 9-DoF design swept with steps within the actuation limits: no ray ends at a
/// limit, every point keeps its q within them, and the rays reach further than with
/// least-norm steps (whose q leaves the limits).
#[cfg(feature = "qp")]
#[test]
fn the_redundant_design_swept_within_the_limits_keeps_every_q_inside() {
    use tdpcr::kinetostatics::{Objective, Redundancy};
    let design = Tdpcr::from_ron_file(design_path("lilge2022_redundant.ron")).unwrap();
    let settings = WorkspaceSettings {
        step: 0.006,
        angle_step: 0.6,
        z_range: [0.0, 0.0],
        ..Default::default()
    };
    let free = sweep_on(2, &design, &settings);
    let strict = sweep_on(
        2,
        &design,
        &WorkspaceSettings {
            redundancy: Redundancy::WithinLimits(Objective::LeastChange),
            ..settings
        },
    );
    assert!(
        free.summary.ray_ends.actuation_limits > 0,
        "{:?}",
        free.summary.ray_ends
    );
    assert_eq!(strict.summary.ray_ends.actuation_limits, 0);
    let limits = design.actuation_limits;
    for p in &strict.points {
        for leg in p.state.q.chunks(3) {
            assert!(
                leg[0].abs() <= limits.tendon_displacement
                    && leg[1].abs() <= limits.tendon_displacement
                    && leg[2].abs() <= limits.base_translation,
                "{:?}",
                p.state.q
            );
        }
    }
    assert!(
        strict.summary.counts.reachable > free.summary.counts.reachable,
        "{} vs {}",
        strict.summary.counts.reachable,
        free.summary.counts.reachable
    );
}

/// The 9-DoF design's least-norm rays retry a step whose run fails on a step across a
/// tendon's kink with one-sided steps (`Solver::across_kinks`; MODEL.md "The 9-DoF sweeps
/// across tendon kinks"): on the plane z = 0 (Δ = 3 mm, 32 rays) 14 rays end unconverged
/// without the retry and none with it, the map has 888 reachable cells instead of 753,
/// and 671 of the 765 points before keep their q within 1e-9 m (the rest lie beyond a
/// retried step, on rays that went on from another solution).
#[test]
fn the_redundant_design_sweeps_across_tendon_kinks() {
    let design = Tdpcr::from_ron_file(design_path("lilge2022_redundant.ron")).unwrap();
    let settings = WorkspaceSettings {
        step: 0.003,
        angle_step: 0.2,
        z_range: [0.0, 0.0],
        ..Default::default()
    };
    let retried = sweep_on(2, &design, &settings);
    let ended = sweep_on(
        2,
        &design,
        &WorkspaceSettings {
            one_sided_kinks: false,
            ..settings
        },
    );
    let (a, b) = (&retried.summary, &ended.summary);
    assert!(b.ray_ends.not_converged >= 5, "{:?}", b.ray_ends);
    assert_eq!(a.ray_ends.not_converged, 0, "{:?}", a.ray_ends);
    assert!(
        a.counts.reachable >= b.counts.reachable + 50,
        "{} against {}",
        a.counts.reachable,
        b.counts.reachable
    );
    let kept = ended
        .points
        .iter()
        .filter(|p| {
            retried
                .points
                .iter()
                .any(|r| r.position == p.position && q_difference(p, r) < 1e-9)
        })
        .count();
    assert!(
        5 * kept >= 4 * ended.points.len(),
        "{kept} of {} points kept",
        ended.points.len()
    );
}

#[test]
fn bad_settings_are_all_reported_with_field_value_and_rule() {
    let settings = WorkspaceSettings {
        step: 0.0,
        angle_step: 7.0,
        z_range: [0.1, -0.1],
        rotvec: [f64::NAN, 0.0, 0.0],
        chord_contraction: 1.0,
        probe_iterations: 0,
        ..Default::default()
    };
    let msg = sweep_workspace(&reference(), &settings)
        .unwrap_err()
        .to_string();
    for part in [
        "step = 0: expected in [1e-5, 1] m",
        "angle_step = 7: expected in [1e-4, pi] rad",
        "z_range = 0.1,-0.1: expected two finite numbers ZMIN <= ZMAX [m]",
        "rotvec = [NaN, 0.0, 0.0]: expected finite numbers of length <= 1000 rad",
        "chord_contraction = 1: expected in [0, 1)",
        "probe_iterations = 0: expected >= 1",
    ] {
        assert!(msg.contains(part), "missing '{part}' in: {msg}");
    }
}

#[test]
fn a_design_that_breaks_its_rules_is_rejected_before_sweeping() {
    let mut design = reference();
    design.leg.disks.radius = -0.006;
    let msg = sweep_workspace(&design, &coarse()).unwrap_err().to_string();
    assert!(
        msg.contains("leg.disks.radius = -0.006: expected > 0 m"),
        "{msg}"
    );
}

/// The plane z = 0 of `file` at Δ = 6 mm with 32 rays.
fn plane_zero(file: &str) -> WorkspaceMap {
    let design = Tdpcr::from_ron_file(design_path(file)).unwrap();
    let settings = WorkspaceSettings {
        step: 0.006,
        angle_step: 0.2,
        z_range: [0.0, 0.0],
        ..Default::default()
    };
    sweep_workspace(&design, &settings).unwrap()
}

/// Whether a fresh analysis of the point's state finds it stable (MODEL.md §4b).
fn stable(solver: &mut Solver, state: &RobotState) -> bool {
    solver
        .analyze(state, &Wrench::default(), &Default::default())
        .map(|a| a.stability.stable)
        .unwrap_or(false)
}

#[test]
fn unstable_equilibria_end_rays_and_are_recorded_but_not_reachable() {
    // The ψ = 0 design has unstable equilibria inside its z = 0 slice (MODEL.md §1).
    let map = plane_zero("lilge2022_psi0.ron");
    let s = &map.summary;
    assert!(s.ray_ends.unstable > 0, "{:?}", s.ray_ends);
    assert!(s.counts.unstable > 0, "{:?}", s.counts);
    let design = Tdpcr::from_ron_file(design_path("lilge2022_psi0.ron")).unwrap();
    let mut solver = Solver::new(&design).unwrap();
    let (mut reachable, mut unstable) = (0, 0);
    for p in &map.points {
        assert_eq!(
            stable(&mut solver, &p.state),
            p.metrics.stable,
            "{:?}",
            p.cell
        );
        if p.reachable() {
            reachable += 1;
        } else if !p.metrics.stable {
            unstable += 1;
            assert!(
                p.metrics.min_compliance_eigenvalue <= 0.0,
                "{:?}",
                p.metrics
            );
        }
    }
    assert_eq!(
        (reachable, unstable),
        (s.counts.reachable, s.counts.unstable)
    );
    assert!(s.table_iii.per_sample.all_count > s.table_iii.per_sample.regular_count);
}

#[test]
fn no_reachable_cell_of_the_reference_design_is_unstable() {
    let design = reference();
    let settings = WorkspaceSettings {
        step: 0.01,
        angle_step: 0.3,
        z_range: [-0.1, 0.12],
        ..Default::default()
    };
    let map = sweep_workspace(&design, &settings).unwrap();
    let s = &map.summary;
    assert_eq!((s.counts.unstable, s.ray_ends.unstable), (0, 0), "{s:?}");
    assert!(s.counts.reachable > 1000, "{:?}", s.counts);
    let mut solver = Solver::new(&design).unwrap();
    for p in map.points.iter().filter(|p| p.reachable()) {
        assert!(stable(&mut solver, &p.state), "{:?}", p.cell);
    }
}

#[test]
fn leg_singularity_lines_are_flagged_where_a_pair_changes_its_taut_side() {
    let map = plane_zero("lilge2022.ron");
    let switched: Vec<_> = map.points.iter().filter(|p| p.metrics.leg_switch).collect();
    assert!(switched.len() >= 6, "{}", switched.len());
    for p in &switched {
        assert!(p.metrics.singularity.leg);
    }
    // The home cell lies between the three lines (Fig. 9): no pair switches there.
    let home = map.points.iter().find(|p| p.cell == [0, 0, 0]).unwrap();
    assert!(!home.metrics.leg_switch);
}

/// Reachable cells of each plane of a sweep.
fn cells_per_plane(map: &WorkspaceMap) -> Vec<usize> {
    let (lo, hi) = (map.points[0].cell[2], map.points.last().unwrap().cell[2]);
    (lo..=hi)
        .map(|k| map.plane(k).filter(|p| p.reachable()).count())
        .collect()
}

#[test]
fn a_plane_origin_where_leg_singularity_lines_meet_does_not_starve_its_plane() {
    // At z = −54 mm every leg's slack tendon of the reference design is within 8 µm of
    // taut at the plane origin: the first steps switch pairs in most directions.
    let settings = WorkspaceSettings {
        step: 0.003,
        angle_step: 0.1,
        z_range: [-0.057, -0.051],
        ..Default::default()
    };
    let map = sweep_workspace(&reference(), &settings).unwrap();
    let n = cells_per_plane(&map);
    assert_eq!(n.len(), 3);
    let neighbours = (n[0] + n[2]) as f64 / 2.0;
    assert!(
        (n[1] as f64 / neighbours - 1.0).abs() < 0.1,
        "cells per plane {n:?}"
    );
}

/// The one-sided kink columns (the default) against the two-sided Newton of before, on
/// the reference design's planes z = −12 … 0 mm at Δ = 3 mm, φ = 0.1 rad: the same cells
/// on the same solutions (q within 1e-9 m where a cell is solved at the same position),
/// none lost, at most a handful gained, for fewer than half the Newton Jacobians
/// (measured: 5 532 → 1 575; the full Δ = 3 mm sweep: 169 242 → 45 721 with the tangent
/// ray starts, 30 cells gained).
#[test]
fn one_sided_kink_columns_keep_the_map_for_fewer_jacobians() {
    let design = reference();
    let settings = WorkspaceSettings {
        angle_step: 0.1,
        z_range: [-0.012, 0.0],
        ..Default::default()
    };
    let one_sided = sweep_on(2, &design, &settings);
    let two_sided = sweep_on(
        2,
        &design,
        &WorkspaceSettings {
            one_sided_kinks: false,
            ..settings
        },
    );
    let (a, b) = (&one_sided.summary, &two_sided.summary);
    assert!(b.counts.reachable > 5000, "{:?}", b.counts);
    assert!(
        2 * a.jacobian_evaluations < b.jacobian_evaluations,
        "Jacobians: one-sided {}, two-sided {}",
        a.jacobian_evaluations,
        b.jacobian_evaluations
    );
    let cells = |m: &WorkspaceMap| m.points.iter().map(|p| p.cell).collect::<BTreeSet<_>>();
    let (ca, cb) = (cells(&one_sided), cells(&two_sided));
    assert!(cb.is_subset(&ca), "lost: {:?}", cb.difference(&ca));
    assert!(
        ca.len() - cb.len() <= 10,
        "{} against {}",
        ca.len(),
        cb.len()
    );
    let mut compared = 0;
    for p in &two_sided.points {
        let q = one_sided.points.iter().find(|o| o.cell == p.cell).unwrap();
        if q.position != p.position {
            continue;
        }
        compared += 1;
        let dq = q_difference(p, q);
        assert!(dq < 1e-9, "cell {:?}: q differs by {dq:e} m", p.cell);
    }
    assert!(compared > 5000, "{compared} cells compared");
}

/// The design search's sweep of the reference design (Δ = 12 mm, φ = 0.3, ε_b = 1e-8, 20
/// iterations) with the chord contraction of its default config: the same cells with
/// the same flags, q within 1e-7 m (2.1e-8 m measured) and at most three fifths of the
/// Newton Jacobians (917 against 1 844 measured; MODEL.md "Newton with chord steps").
#[test]
fn a_looser_chord_contraction_keeps_the_coarse_map_for_fewer_jacobians() {
    let settings = search_grid();
    let (tight, loose) = same_coarse_map(
        &settings,
        &WorkspaceSettings {
            chord_contraction: 0.5,
            ..settings.clone()
        },
    );
    let (a, b) = (&tight.summary, &loose.summary);
    assert!(
        5 * b.jacobian_evaluations <= 3 * a.jacobian_evaluations,
        "Jacobians: 0.5 {}, 0.1 {}",
        b.jacobian_evaluations,
        a.jacobian_evaluations
    );
}

/// The design search's default evaluation (chord contraction 0.5) with the progress check
/// after 8 iterations instead of 15: steps past a fold end sooner, every cell and flag of
/// the reference's grid stays.
#[test]
fn an_earlier_progress_check_keeps_the_coarse_map_for_fewer_iterations() {
    let settings = WorkspaceSettings {
        chord_contraction: 0.5,
        ..search_grid()
    };
    let (late, early) = same_coarse_map(
        &settings,
        &WorkspaceSettings {
            probe_iterations: 8,
            ..settings.clone()
        },
    );
    let (a, b) = (&late.summary, &early.summary);
    println!(
        "steps without a solution: residuals {} (probe 15), {} (probe 8); iterations {}, {}; Jacobians {}, {}; converged: {}, {}",
        a.failed_residual_evaluations,
        b.failed_residual_evaluations,
        a.failed_newton_iterations,
        b.failed_newton_iterations,
        a.failed_jacobian_evaluations,
        b.failed_jacobian_evaluations,
        a.residual_evaluations,
        b.residual_evaluations
    );
    // Measured: 710 → 651 iterations, 264 → 209 Jacobians of the steps without a solution.
    assert!(
        b.failed_newton_iterations < a.failed_newton_iterations
            && 100 * b.failed_jacobian_evaluations <= 85 * a.failed_jacobian_evaluations,
        "steps without a solution: probe 8 {} iterations, {} Jacobians; probe 15 {}, {}",
        b.failed_newton_iterations,
        b.failed_jacobian_evaluations,
        a.failed_newton_iterations,
        a.failed_jacobian_evaluations
    );
}

/// The reference's sweep on the design search's grid (Δ = 12 mm, φ = 0.3, tolerance
/// 1e-8, 20 iterations).
fn search_grid() -> WorkspaceSettings {
    WorkspaceSettings {
        step: 0.012,
        angle_step: 0.3,
        z_range: [-0.18, 0.18],
        tolerance: 1e-8,
        max_iterations: 20,
        ..Default::default()
    }
}

/// The reference's maps with `a` and `b` on two threads, checked to have the same cells,
/// singularity flags and stability, and q within 1e-7 m.
fn same_coarse_map(a: &WorkspaceSettings, b: &WorkspaceSettings) -> (WorkspaceMap, WorkspaceMap) {
    let design = reference();
    let (ma, mb) = (sweep_on(2, &design, a), sweep_on(2, &design, b));
    assert!(
        ma.summary.counts.reachable > 1500,
        "{:?}",
        ma.summary.counts
    );
    assert_eq!(ma.summary.counts, mb.summary.counts);
    assert_eq!(ma.points.len(), mb.points.len());
    for (p, q) in ma.points.iter().zip(&mb.points) {
        assert_eq!(p.cell, q.cell);
        assert_eq!(p.metrics.singularity, q.metrics.singularity, "{:?}", p.cell);
        assert_eq!(p.metrics.stable, q.metrics.stable, "{:?}", p.cell);
        let dq = q_difference(p, q);
        assert!(dq < 1e-7, "cell {:?}: q differs by {dq:e} m", p.cell);
    }
    (ma, mb)
}

/// The ψ = 0 twin and the plane z = 0 of its sweep at R_ee = Rz(−30°) (the paper's Fig. 7
/// slice, with colliding cells) at grid step `step` \[m\] and ray spacing `angle_step`.
fn rotated_psi0_slice(step: f64, angle_step: f64) -> (Tdpcr, WorkspaceSettings) {
    let design = Tdpcr::from_ron_file(design_path("lilge2022_psi0.ron")).unwrap();
    let settings = WorkspaceSettings {
        rotvec: [0.0, 0.0, -std::f64::consts::PI / 6.0],
        step,
        angle_step,
        z_range: [0.0, 0.0],
        ..Default::default()
    };
    (design, settings)
}

/// The home configuration is a cold solve and stays two-sided: with one-sided kink
/// columns the ψ = 0 twin's home at R_ee = Rz(−30°) (the paper's Fig. 7 slice) landed on
/// another equilibrium and the sweep had no valid home (0 cells; 167 collision cells
/// with the right one).
#[test]
fn the_home_of_a_rotated_slice_is_the_two_sided_cold_solve() {
    let (design, settings) = rotated_psi0_slice(0.01, 0.8);
    let map = sweep_workspace(&design, &settings).unwrap();
    assert_eq!(map.summary.planes_reached, 1, "{:?}", map.summary.path_ends);
    assert!(map.summary.counts.reachable > 0);
}

/// The sweep rules out collisions from the legs' knots where it can and integrates the
/// legs to their disks elsewhere: every cell's collision flag is what the check at the
/// disks gives for its state, on a slice with colliding cells (the ψ = 0 twin at
/// R_ee = Rz(−30°)), and most states need no second integration.
#[test]
fn knots_decide_collisions_as_the_disks_do() {
    let (design, settings) = rotated_psi0_slice(0.005, 0.2);
    let map = sweep_workspace(&design, &settings).unwrap();
    let solver = Solver::new(&design).unwrap();
    let model = solver.model();
    let mut checker = CollisionChecker::new(model);
    let mut collisions = 0;
    for p in &map.points {
        let at_disks = checker.check(model, &p.state).unwrap().is_some();
        assert_eq!(p.collision, at_disks, "cell {:?}", p.cell);
        collisions += usize::from(at_disks);
    }
    let s = &map.summary;
    assert!(collisions > 10, "{collisions} colliding cells");
    assert!(
        s.collision_integrations >= collisions && 2 * s.collision_integrations < s.solves,
        "{} second integrations, {collisions} collisions, {} solves",
        s.collision_integrations,
        s.solves
    );
}

/// The sweep computes the unit-scaled rconds of the block matrices only for the points
/// that represent cells: every cell's measures are still [`point_metrics`] of its state,
/// bit for bit (the leg-switch flags aside, which the sweep sets from the neighbours), for
/// the 6-DoF and the 9-DoF design, on a sweep with several samples in most cells.
#[test]
fn cells_get_the_measures_of_their_states_bit_for_bit() {
    use tdpcr::workspace::metrics::{AnalysisSettings, point_metrics};
    for name in ["lilge2022.ron", "lilge2022_redundant.ron"] {
        let design = Tdpcr::from_ron_file(design_path(name)).unwrap();
        let settings = WorkspaceSettings {
            step: 0.01,
            angle_step: 0.1,
            z_range: [0.0, 0.0],
            ..Default::default()
        };
        let map = sweep_workspace(&design, &settings).unwrap();
        assert!(map.summary.solves > 2 * map.points.len(), "{name}");
        let mut solver = Solver::new(&design).unwrap();
        let bits = |r: &tdpcr::workspace::metrics::Rconds| {
            [r.b_xu, r.b_qu, r.b_u, r.j_p, r.j_o, r.c_p, r.c_o].map(f64::to_bits)
        };
        for p in &map.points {
            let m = point_metrics(&mut solver, &p.state, &AnalysisSettings::default()).unwrap();
            let cell = p.cell;
            assert_eq!(bits(&p.metrics.rcond), bits(&m.rcond), "{name} {cell:?}");
            assert_eq!(
                bits(&p.metrics.rcond_scaled),
                bits(&m.rcond_scaled),
                "{name} {cell:?}"
            );
            assert_eq!(
                (p.metrics.stable, p.metrics.min_tension.to_bits()),
                (m.stable, m.min_tension.to_bits()),
                "{name} {cell:?}"
            );
            assert_eq!(
                p.metrics.min_compliance_eigenvalue.to_bits(),
                m.min_compliance_eigenvalue.to_bits()
            );
        }
    }
}

/// A sweep asked to stop (from another thread, once some rays are done) skips the rays
/// not yet started and returns `Error::Stopped` with its progress; one whose flag is
/// never set gives the plain sweep's map.
#[test]
fn a_sweep_stops_when_asked_and_is_unchanged_when_not() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use tdpcr::error::Error;
    use tdpcr::workspace::{Progress, sweep_workspace_until};
    let design = reference();
    let settings = coarse();
    let stop = AtomicBool::new(false);
    // Stops after the third ray (of 8 per plane, 3 planes).
    let progress = |p: Progress| {
        if p.rays_done >= 3 {
            stop.store(true, Ordering::Relaxed);
        }
    };
    match sweep_workspace_until(&design, &settings, &progress, &stop) {
        Err(Error::Stopped { what, done, total }) => {
            assert_eq!(what, "rays");
            assert!(done >= 3 && done < total, "{done} of {total}");
        }
        other => panic!(
            "expected Error::Stopped, got {:?}",
            other.map(|m| m.summary)
        ),
    }
    let never = AtomicBool::new(false);
    let map = sweep_workspace_until(&design, &settings, &|_| {}, &never).unwrap();
    assert_eq!(
        comparable(&map),
        comparable(&sweep_workspace(&design, &settings).unwrap())
    );
}

/// A home configuration that solves but lies beyond the actuation limits is reported as
/// invalid (both path ends `invalid_home`, the reason in `first_error`), as a colliding
/// one is; the sweep stopped with "beyond the actuation limits" instead.
#[test]
fn a_home_beyond_the_actuation_limits_is_an_invalid_home() {
    let mut design = reference();
    // The home's tendon displacements are about 1 mm.
    design.actuation_limits.tendon_displacement = 0.0005;
    let map = sweep_workspace(&design, &coarse()).unwrap();
    let ends = serde_json::to_string(&map.summary.path_ends).unwrap();
    assert_eq!(ends, r#"["invalid_home","invalid_home"]"#);
    let error = map.summary.first_error.as_deref().unwrap_or("");
    assert!(error.contains("outside the actuation limits"), "{error}");
    assert!(map.points.is_empty());
}

/// A rotation vector whose length overflows (or is beyond 1000 rad) and a z-range far
/// beyond any design are refused by name (the rotation became NaN: "pose = a non-finite
/// value"; the plane index saturated at i64::MAX).
#[test]
fn huge_rotation_vectors_and_z_ranges_are_refused() {
    for (rotvec, z_range, part) in [
        (
            [1e200, 0.0, 0.0],
            [-0.01, 0.01],
            "rotvec = [1e200, 0.0, 0.0]: expected finite numbers of length <= 1000 rad",
        ),
        (
            [0.0, 1001.0, 0.0],
            [-0.01, 0.01],
            "rotvec = [0.0, 1001.0, 0.0]",
        ),
        (
            [0.0; 3],
            [1e30, 1e30],
            "z_range = 1e30,1e30: expected within ±100 m",
        ),
    ] {
        let settings = WorkspaceSettings {
            rotvec,
            z_range,
            ..coarse()
        };
        let msg = sweep_workspace(&reference(), &settings)
            .unwrap_err()
            .to_string();
        assert!(msg.contains(part), "missing '{part}' in: {msg}");
    }
    let ok = WorkspaceSettings {
        rotvec: [0.0, 0.0, 999.0],
        z_range: [-100.0, -99.99],
        ..coarse()
    };
    assert!(ok.validate().is_ok());
}

/// The slice figures of an earlier sweep at another Δ (other planes, other names) are
/// removed when a sweep writes into the same directory (they stayed beside the new ones);
/// files that only look alike are left alone.
#[test]
fn a_sweep_replaces_an_earlier_sweeps_slice_figures() {
    let dir = std::env::temp_dir().join(format!("tdpcr-stale-figures-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let stale = dir.join("reach_z+0.066.svg");
    let alike = dir.join("my_reach_z+0.066.svg");
    std::fs::write(&stale, "<svg/>").unwrap();
    std::fs::write(&alike, "mine").unwrap();
    let map = sweep_workspace(&reference(), &coarse()).unwrap();
    let written = files::write_outputs(&map, &dir).unwrap();
    assert!(
        written.iter().any(|p| p.ends_with("reach_z+0.000.svg")),
        "{written:?}"
    );
    assert!(!stale.exists(), "the earlier sweep's figure stayed");
    assert_eq!(std::fs::read_to_string(&alike).unwrap(), "mine");
    std::fs::remove_dir_all(&dir).ok();
}
