//! The paper's motion-sequence experiment (Tab. VII), on deterministic sequences:
//! 1300 IK poses of the 6-DoF design mixing translations and rotations (steps ≤ 1 mm and
//! ≤ 1°), and 1000 FK actuations of the 9-DoF design (steps ≤ 0.1 mm in the tendons and
//! ≤ 1 mm in translation), each warm-started from the previous step.
use std::f64::consts::TAU;

use nalgebra::{Rotation3, Vector3};
use tdpcr::Tdpcr;
use tdpcr::kinetostatics::Solver;
use tdpcr::model::Pose;
use tdpcr::rod::Wrench;
use tdpcr::trajectory::{Targets, run_trajectory};

fn design(file: &str) -> Tdpcr {
    Tdpcr::from_ron_file(format!("{}/designs/{file}", env!("CARGO_MANIFEST_DIR"))).unwrap()
}

fn main() {
    let w = Wrench::default();
    // IK: around the solved home pose.
    let mut solver = Solver::new(&design("lilge2022.ron"));
    let home = solver.solve_fk(&[0.0; 6], &w, None).unwrap().state;
    let (p0, r0) = (Vector3::from(home.position), Vector3::from(home.rotvec));
    let n = 1300;
    let poses: Vec<Pose> = (0..n)
        .map(|k| {
            let t = k as f64 / n as f64;
            let p = p0
                + Vector3::new(
                    0.02 * (TAU * 2.0 * t).sin(),
                    0.02 * (TAU * 3.0 * t).sin(),
                    0.015 * (TAU * t).sin(),
                );
            let r = r0
                + Vector3::new(
                    0.1 * (TAU * t).sin(),
                    0.1 * (TAU * 2.0 * t).sin(),
                    0.15 * (TAU * 3.0 * t).sin(),
                );
            Pose {
                position: p,
                rotation: *Rotation3::new(r).matrix(),
            }
        })
        .collect();
    let (_, stats) = run_trajectory(&mut solver, &Targets::Poses(poses), &w);
    println!("IK, 6-DoF, {} poses: {stats:?}", n);
    // FK: 9-DoF actuation sequence starting at q = 0.
    let mut solver = Solver::new(&design("lilge2022_redundant.ron"));
    let n = 1000;
    let qs: Vec<Vec<f64>> = (0..n)
        .map(|k| {
            let t = k as f64 / n as f64;
            (0..3)
                .flat_map(|leg| {
                    let ph = leg as f64;
                    [
                        0.003 * (TAU * 2.0 * t + ph).sin() - 0.003 * ph.sin(),
                        0.002 * (TAU * t + ph).sin() - 0.002 * ph.sin(),
                        0.02 * (TAU * t).sin(),
                    ]
                })
                .collect()
        })
        .collect();
    let (steps, stats) = run_trajectory(&mut solver, &Targets::Actuations(qs), &w);
    println!("FK, 9-DoF, {} steps: {stats:?}", n);
    let failed: Vec<usize> = steps
        .iter()
        .filter(|s| !s.converged)
        .map(|s| s.step)
        .collect();
    println!("failed steps: {failed:?}");
}
