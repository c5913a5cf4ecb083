//! Deterministic sampling of actuation vectors (benchmarks, Monte Carlo studies).

use crate::design::Tdpcr;
use crate::error::Error;
use crate::kinetostatics::Solver;
use crate::model::{Model, Pose};
use crate::random::SplitMix64;
use crate::rod::Wrench;

/// An endless, deterministic stream of actuation vectors (SplitMix64 of a seed): each
/// bending value uniform in ±`tendon_displacement`; the translations a common offset
/// uniform in ±0.8 `base_translation` plus a per-leg offset uniform in ±0.2
/// `base_translation` (independent translations of ±100 mm on 145 mm legs mostly ask
/// for configurations without an equilibrium).
#[derive(Debug, Clone)]
pub struct ActuationSampler {
    rng: SplitMix64,
    bend: f64,
    translation: f64,
    n: usize,
    pairs: usize,
}

impl ActuationSampler {
    /// The stream for `model`'s actuation limits and `seed`.
    pub fn new(model: &Model, seed: u64) -> Self {
        Self {
            rng: SplitMix64::new(seed),
            bend: model.limits.tendon_displacement,
            translation: model.limits.base_translation,
            n: model.n_actuators(),
            pairs: model.pairs,
        }
    }

    /// Uniform in [−1, 1).
    fn uniform(&mut self) -> f64 {
        self.rng.unit() * 2.0 - 1.0
    }
}

impl Iterator for ActuationSampler {
    type Item = Vec<f64>;

    fn next(&mut self) -> Option<Vec<f64>> {
        let common = 0.8 * self.translation * self.uniform();
        let q = (0..self.n)
            .map(|k| {
                if k % (self.pairs + 1) == self.pairs {
                    common + 0.2 * self.translation * self.uniform()
                } else {
                    self.bend * self.uniform()
                }
            })
            .collect();
        Some(q)
    }
}

/// The first `count` vectors of [`ActuationSampler`] for `model` and `seed`.
pub fn seeded_actuations(model: &Model, count: usize, seed: u64) -> Vec<Vec<f64>> {
    ActuationSampler::new(model, seed).take(count).collect()
}

/// Seeded actuation vectors that have an equilibrium on the branch of the home
/// configuration, with that equilibrium's platform pose.
#[derive(Debug, Clone)]
pub struct ReachableSample {
    /// The accepted actuation vectors \[m\].
    pub actuations: Vec<Vec<f64>>,
    /// The platform pose of each, found by path following.
    pub poses: Vec<Pose>,
    /// Draws rejected because the path from q = 0 ended (a fold: no equilibrium on the
    /// home branch) before reaching them.
    pub rejected: Vec<Vec<f64>>,
}

/// Steps of the straight path from q = 0 that certify a draw.
const CERTIFYING_STEPS: usize = 50;

/// The first `count` draws of [`ActuationSampler`] (for `design`, `seed`) that can be
/// reached from the solved q = 0 configuration (under the platform weight) by
/// `CERTIFYING_STEPS` (50) warm-started FK solves along the straight line in q. A benchmark
/// of cold FK needs targets that have an equilibrium: with independent base translations
/// many draws lie beyond a fold of the home branch (MODEL.md §4, Type II), where no
/// solver can converge.
///
/// # Errors
/// [`Error::Solve`] if the q = 0 configuration itself does not solve.
pub fn seeded_reachable_actuations(
    design: &Tdpcr,
    count: usize,
    seed: u64,
) -> Result<ReachableSample, Error> {
    let mut solver = Solver::new(design)?;
    let w = Wrench::default();
    let zero = vec![0.0; solver.model().n_actuators()];
    let home = solver.solve_fk(&zero, &w, None)?.state;
    let mut sample = ReachableSample {
        actuations: Vec::with_capacity(count),
        poses: Vec::with_capacity(count),
        rejected: Vec::new(),
    };
    let draws = ActuationSampler::new(solver.model(), seed);
    for q in draws {
        if sample.actuations.len() == count {
            break;
        }
        let mut state = home.clone();
        let reached = (1..=CERTIFYING_STEPS).all(|k| {
            let l = k as f64 / CERTIFYING_STEPS as f64;
            let qk: Vec<f64> = q.iter().map(|x| x * l).collect();
            match solver.solve_fk(&qk, &w, Some(&state)) {
                Ok(s) => {
                    state = s.state;
                    true
                }
                Err(_) => false,
            }
        });
        if reached {
            sample.poses.push(state.pose());
            sample.actuations.push(q);
        } else {
            sample.rejected.push(q);
        }
    }
    Ok(sample)
}

/// The IK motion of the paper's Tab. VII on deterministic terms: `count` platform poses
/// around `start` mixing translations (±20 mm in x and y, ±15 mm in z) and rotations
/// (±0.1 rad about x and y, ±0.15 rad about z), each a smooth periodic function of the
/// step, so consecutive poses differ by ≤ 1 mm and ≤ 1° for `count` ≥ 400.
pub fn ik_motion_sequence(start: &Pose, count: usize) -> Vec<Pose> {
    use nalgebra::{Rotation3, Vector3};
    use std::f64::consts::TAU;
    let r0 = Rotation3::from_matrix_unchecked(start.rotation).scaled_axis();
    (0..count)
        .map(|k| {
            let t = k as f64 / count as f64;
            let p = start.position
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
        .collect()
}

/// A closed smooth IK path of `count` platform poses around `start` that moves position
/// (±12 mm in x, ±7.5 mm in y, ±4 mm in z) and orientation (±0.08 rad about x, ±0.05 rad
/// about y, ±0.03 rad about z) together, one period per `count` poses, so its last pose
/// is one step from its first. For `count` = 200 consecutive poses differ by ≤ 0.63 mm
/// and ≤ 0.32° (the step sizes of the peer comparison of BENCHMARKS.md, issue 17).
pub fn ik_fine_path(start: &Pose, count: usize) -> Vec<Pose> {
    use nalgebra::{Rotation3, Vector3};
    use std::f64::consts::TAU;
    let r0 = Rotation3::from_matrix_unchecked(start.rotation).scaled_axis();
    (0..count)
        .map(|k| {
            let a = TAU * k as f64 / count as f64;
            let p = start.position
                + Vector3::new(0.012 * a.sin(), 0.0075 * (2.0 * a).sin(), 0.004 * a.sin());
            let r = r0
                + Vector3::new(
                    0.08 * a.sin(),
                    0.05 * (2.0 * a).sin(),
                    0.03 * (3.0 * a).sin(),
                );
            Pose {
                position: p,
                rotation: *Rotation3::new(r).matrix(),
            }
        })
        .collect()
}

/// The largest step of a closed path of poses (the last pose to the first included):
/// position \[m\] and rotation angle \[rad\].
pub fn largest_step(poses: &[Pose]) -> (f64, f64) {
    use nalgebra::Rotation3;
    let n = poses.len();
    (0..n).fold((0.0f64, 0.0f64), |(dp, dr), k| {
        let (a, b) = (&poses[k], &poses[(k + 1) % n]);
        let r = Rotation3::from_matrix_unchecked(b.rotation * a.rotation.transpose());
        (dp.max((b.position - a.position).norm()), dr.max(r.angle()))
    })
}

/// The FK motion of the paper's Tab. VII for a design with `pairs` tendon pairs per leg:
/// `count` actuation vectors from q = 0, per leg bending ±3 mm (and ±2 mm for a second
/// pair) and a common translation of ±20 mm, smooth and periodic, so consecutive vectors
/// differ by ≤ 0.1 mm in the tendons and ≤ 1 mm in translation for `count` ≥ 200.
pub fn fk_motion_sequence(pairs: usize, count: usize) -> Vec<Vec<f64>> {
    use std::f64::consts::TAU;
    (0..count)
        .map(|k| {
            let t = k as f64 / count as f64;
            (0..3)
                .flat_map(|leg| {
                    let ph = leg as f64;
                    let bend = [
                        0.003 * (TAU * 2.0 * t + ph).sin() - 0.003 * ph.sin(),
                        0.002 * (TAU * t + ph).sin() - 0.002 * ph.sin(),
                    ];
                    bend.into_iter()
                        .take(pairs)
                        .chain([0.02 * (TAU * t).sin()])
                        .collect::<Vec<_>>()
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fine_path_is_closed_and_its_steps_are_those_of_the_peer_comparison() {
        let start = Pose {
            position: nalgebra::Vector3::new(0.0, 0.0, 0.2),
            rotation: nalgebra::Matrix3::identity(),
        };
        let path = ik_fine_path(&start, 200);
        assert_eq!(path.len(), 200);
        let (dp, dr) = largest_step(&path);
        // At most the peer's steps, and not much smaller (the path is not trivially slow).
        assert!((0.55e-3..=0.63e-3).contains(&dp), "{dp} m");
        assert!(
            (0.25f64.to_radians()..=0.32f64.to_radians()).contains(&dr),
            "{dr} rad"
        );
        // Twice as many poses: half the step.
        let (dp2, dr2) = largest_step(&ik_fine_path(&start, 400));
        assert!((dp2 / dp - 0.5).abs() < 0.01 && (dr2 / dr - 0.5).abs() < 0.01);
    }

    #[test]
    fn the_seeded_stream_keeps_its_values() {
        // Pinned on 2026-11-24 (the seeded sets of BENCHMARKS.md and docs/PAPER.md).
        let design = Tdpcr::from_ron_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/designs/lilge2022.ron"
        ))
        .unwrap();
        let mut s = ActuationSampler::new(&Model::new(&design), 42);
        let first = s.next().unwrap();
        let expected: [f64; 6] = [
            -0.006801792142461598,
            0.02979442581369728,
            -0.0031161856695272497,
            0.020171587345101577,
            0.007364561530930647,
            0.027386588351979105,
        ];
        for (a, b) in first.iter().zip(expected) {
            assert_eq!(a.to_bits(), b.to_bits(), "{first:?}");
        }
        assert_eq!(
            s.next().unwrap()[5].to_bits(),
            0.04890163225829015f64.to_bits()
        );
    }
}
