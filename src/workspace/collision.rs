//! Self-collision checks of the workspace sweep (paper Sec. V-B, MODEL.md §6): every disk
//! of every leg is a sphere of the design's disk radius; spheres of different legs must not
//! overlap, and no sphere may cross the platform triangle (the triangle of the three
//! coupling points at the pose). Touching (distance exactly equal to the sum of radii, or
//! to the radius for the triangle) is not a collision.
//!
//! The workspace sweep first rules collisions out from the legs' knots, which its
//! per-point analysis records at no cost ([`CollisionChecker::clear_by_knots`]), and
//! computes the disks only where the knots cannot tell ([`CollisionChecker::check`]).
//! Why (callgrind, the reference's sweep z ∈ [−6, 0] mm, φ = 0.2, one thread): the
//! partial steps to the disks in every analysis (≈ 92 k instructions a sample) and the
//! pairwise check (≈ 15 k) were 7.7 % of its instructions; with the knots first the sweep
//! takes 4 449.3 M → 4 145.1 M instructions (−6.8 %), the map byte for byte the same.

use nalgebra::Vector3;

use crate::boundary::leg_start;
use crate::error::SolveError;
use crate::kinetostatics::RobotState;
use crate::model::Model;
use crate::rod::tendon::TendonUnknown;
use crate::rod::{LegEnd, LegShape, LegsScratch, integrate_legs};

/// What collides first (legs numbered from 0, disks from 1 at s = L/n_d).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Collision {
    /// Disk `disk_a` of leg `leg_a` overlaps disk `disk_b` of leg `leg_b` (`leg_a < leg_b`).
    Legs {
        /// First leg.
        leg_a: usize,
        /// Its disk.
        disk_a: usize,
        /// Second leg.
        leg_b: usize,
        /// Its disk.
        disk_b: usize,
    },
    /// Disk `disk` of leg `leg` crosses the platform triangle.
    Platform {
        /// The leg.
        leg: usize,
        /// Its disk.
        disk: usize,
    },
}

/// Whether spheres of radii `r_a`, `r_b` \[m\] centred at `a`, `b` overlap:
/// |a − b| < r_a + r_b (touching is allowed).
pub fn spheres_overlap(a: &Vector3<f64>, r_a: f64, b: &Vector3<f64>, r_b: f64) -> bool {
    (a - b).norm_squared() < (r_a + r_b) * (r_a + r_b)
}

/// The point of the (filled) triangle `tri` closest to `p` (Ericson, *Real-Time
/// Collision Detection*, §5.1.5: Voronoi regions of vertices, then edges, then the face).
pub fn closest_point_on_triangle(p: &Vector3<f64>, tri: &[Vector3<f64>; 3]) -> Vector3<f64> {
    let [a, b, c] = tri;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Whether the sphere of radius `r` \[m\] centred at `centre` crosses the filled triangle
/// `tri`: its distance to the triangle is below `r` (touching is allowed).
pub fn sphere_crosses_triangle(centre: &Vector3<f64>, r: f64, tri: &[Vector3<f64>; 3]) -> bool {
    (centre - closest_point_on_triangle(centre, tri)).norm_squared() < r * r
}

/// The first collision among disk spheres of radius `radius` \[m\] at `disks[leg][j]`
/// (disk j + 1 of each leg) and the platform triangle `platform`, if any. Leg pairs are
/// checked first (in the order (0, 1), (0, 2), (1, 2)), then each leg against the platform.
pub fn first_collision(
    disks: &[&[Vector3<f64>]; 3],
    radius: f64,
    platform: &[Vector3<f64>; 3],
) -> Option<Collision> {
    for (leg_a, leg_b) in [(0, 1), (0, 2), (1, 2)] {
        for (ia, a) in disks[leg_a].iter().enumerate() {
            for (ib, b) in disks[leg_b].iter().enumerate() {
                if spheres_overlap(a, radius, b, radius) {
                    return Some(Collision::Legs {
                        leg_a,
                        disk_a: ia + 1,
                        leg_b,
                        disk_b: ib + 1,
                    });
                }
            }
        }
    }
    for (leg, d) in disks.iter().enumerate() {
        for (j, c) in d.iter().enumerate() {
            if sphere_crosses_triangle(c, radius, platform) {
                return Some(Collision::Platform { leg, disk: j + 1 });
            }
        }
    }
    None
}

/// Bound on the backbone's speed |dp/ds| = |v| (1 + extension and shear strain) that the
/// knot test ([`CollisionChecker::clear_by_knots`]) assumes: a disk at arc distance Δs
/// from a knot is within this × Δs of it. The modelled backbones stay within strains of
/// 1e-3 (|v| ≤ 1.001 over solved states of every bundled robot design, in this module's
/// tests; a real backbone yields at about 1 %), so the bound holds with a factor of
/// about 1.5 to spare.
pub const SPEED_BOUND: f64 = 1.5;

/// Allowance \[m\] for the integration's own error in a disk's and a knot's position
/// (the disks are within 1e-7 L, 15 nm for the bundled legs, of a 16× finer
/// integration's): 1 µm.
pub const POSITION_SLACK: f64 = 1e-6;

/// Buffers for [`CollisionChecker::check`]: one leg integration scratch and three shapes,
/// and the knots' margins of [`CollisionChecker::clear_by_knots`].
#[derive(Debug, Clone)]
pub struct CollisionChecker {
    scratch: LegsScratch,
    ends: [LegEnd; 3],
    shapes: [LegShape; 3],
    /// (knot index, margin \[m\]) of every knot that is the nearest knot of a disk:
    /// every such disk is within the margin of its knot.
    knot_margins: Vec<(usize, f64)>,
    /// How many knots a leg has ([`LegModel::knot_arcs`](crate::rod::LegModel::knot_arcs)).
    knot_count: usize,
}

impl CollisionChecker {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        let shape = || LegShape::new(&model.leg);
        let knots: Vec<f64> = model.leg.knot_arcs().collect();
        let mut knot_margins: Vec<(usize, f64)> = Vec::new();
        for disk in 1..=model.leg.n_disks {
            let arc = model.leg.disk_arc(disk);
            let (k, distance) = knots
                .iter()
                .map(|s| (s - arc).abs())
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap_or((0, arc));
            let margin = SPEED_BOUND * distance + POSITION_SLACK;
            match knot_margins.iter_mut().find(|(i, _)| *i == k) {
                Some((_, m)) => *m = m.max(margin),
                None => knot_margins.push((k, margin)),
            }
        }
        Self {
            scratch: LegsScratch::new(),
            ends: [LegEnd::zeros(); 3],
            shapes: [shape(), shape(), shape()],
            knot_margins,
            knot_count: knots.len(),
        }
    }

    /// Whether the legs' knots (`shapes` recorded with at least
    /// [`ShapeDetail::Knots`](crate::rod::ShapeDetail) at the solved `state`) prove that
    /// no disk collides: every disk is within its knot's margin (the arc distance to its
    /// nearest knot × [`SPEED_BOUND`] + [`POSITION_SLACK`]), so knots farther apart than
    /// 2 r plus their margins hold no overlapping disks, and a knot farther than r plus its
    /// margin from the platform triangle no disk that crosses it. `false` says only that
    /// the knots cannot tell ([`CollisionChecker::check`] can).
    ///
    /// Measured (Δ = 3 mm sweeps): the disks were needed for 0 of the reference's 378 319
    /// solves and 212 of the ψ = 0 twin's 252 147 (BENCHMARKS.md, section "Collisions
    /// from the knots").
    pub fn clear_by_knots(
        &self,
        model: &Model,
        state: &RobotState,
        shapes: &[LegShape; 3],
    ) -> bool {
        if shapes.iter().any(|s| s.knots.len() != self.knot_count) {
            return false;
        }
        let r = model.leg.disk_radius;
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            let (knots_a, knots_b) = (&shapes[a].knots, &shapes[b].knots);
            for &(ka, ma) in &self.knot_margins {
                for &(kb, mb) in &self.knot_margins {
                    let clearance = 2.0 * r + ma + mb;
                    if (knots_a[ka] - knots_b[kb]).norm_squared() < clearance * clearance {
                        return false;
                    }
                }
            }
        }
        let pose = state.pose();
        let platform = model
            .coupling_points
            .map(|c| pose.position + pose.rotation * c);
        shapes.iter().all(|s| {
            self.knot_margins
                .iter()
                .all(|&(k, m)| !sphere_crosses_triangle(&s.knots[k], r + m, &platform))
        })
    }

    /// Integrates the three legs of a solved `state` (y_u with γ, as states carry it) to
    /// get the disk centres, and returns the first collision, if any.
    ///
    /// # Errors
    /// [`SolveError::NonFinite`] if a leg integration blows up (not for a solved state).
    pub fn check(
        &mut self,
        model: &Model,
        state: &RobotState,
    ) -> Result<Option<Collision>, SolveError> {
        let starts =
            [0, 1, 2].map(|i| leg_start(model, i, &state.q, &state.y_u, TendonUnknown::Gamma));
        let (scratch, ends) = (&mut self.scratch, &mut self.ends);
        integrate_legs(
            &model.leg,
            &starts,
            scratch,
            ends,
            None,
            Some(&mut self.shapes),
        )?;
        Ok(first_collision_of(model, state, &self.shapes))
    }

    /// Disk centres \[m\] of leg `leg` from the last [`CollisionChecker::check`].
    pub fn disk_centres(&self, leg: usize) -> &[Vector3<f64>] {
        self.shapes[leg].positions.get(1..).unwrap_or(&[])
    }
}

/// The first collision of a solved `state` whose legs have the frames `shapes` (e.g.
/// [`Solver::shapes`](crate::kinetostatics::Solver::shapes) after its analysis), if any.
pub fn first_collision_of(
    model: &Model,
    state: &RobotState,
    shapes: &[LegShape; 3],
) -> Option<Collision> {
    let pose = state.pose();
    let platform = model
        .coupling_points
        .map(|c| pose.position + pose.rotation * c);
    // positions[0] is the base (s = 0), not a disk.
    let disks = shapes
        .each_ref()
        .map(|s| s.positions.get(1..).unwrap_or(&[]));
    first_collision(&disks, model.leg.disk_radius, &platform)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::Tdpcr;
    use crate::kinetostatics::Solver;
    use crate::random::SplitMix64;
    use crate::rod::Wrench;

    /// Every disk is within its knot's margin, with the margin's factor of safety: over
    /// solved states of every bundled robot design (FK at q = 0 and at random actuations),
    /// no disk is farther from its nearest knot than 1.001 × the arc distance (the
    /// backbone's speed |v| ≤ 1.001; [`SPEED_BOUND`] assumes 1.5), and the knots recorded
    /// with the disks are the integration's knots, the last one the tip.
    #[test]
    fn disks_lie_within_their_knots_margins() {
        let mut rng = SplitMix64::new(17);
        for name in [
            "lilge2022",
            "lilge2022_psi0",
            "lilge2022_redundant",
            "lilge2022_redundant_psi0",
        ] {
            let file = format!("{}/designs/{name}.ron", env!("CARGO_MANIFEST_DIR"));
            let mut solver = Solver::new(&Tdpcr::from_ron_file(&file).unwrap()).unwrap();
            let model = solver.model().clone();
            let mut checker = CollisionChecker::new(&model);
            let knots: Vec<f64> = model.leg.knot_arcs().collect();
            let mut solved = 0;
            for draw in 0..6 {
                let q: Vec<f64> = (0..model.n_actuators())
                    .map(|_| {
                        if draw == 0 {
                            0.0
                        } else {
                            rng.uniform(-3e-3, 3e-3)
                        }
                    })
                    .collect();
                let Ok(solution) = solver.solve_fk(&q, &Wrench::default(), None) else {
                    continue;
                };
                solved += 1;
                checker.check(&model, &solution.state).unwrap();
                for (leg, shape) in checker.shapes.iter().enumerate() {
                    assert_eq!(shape.knots.len(), knots.len(), "{name}");
                    assert_eq!(shape.knots.last(), shape.positions.last(), "{name}");
                    assert_eq!(shape.knots[0], shape.positions[0], "{name}");
                    for disk in 1..=model.leg.n_disks {
                        let arc = model.leg.disk_arc(disk);
                        let p = shape.positions[disk];
                        let (k, ds) = knots
                            .iter()
                            .map(|s| (s - arc).abs())
                            .enumerate()
                            .min_by(|a, b| a.1.total_cmp(&b.1))
                            .unwrap();
                        let d = (p - shape.knots[k]).norm();
                        assert!(
                            d <= 1.001 * ds + 1e-12,
                            "{name} leg {leg} disk {disk}: {d:.3e} m from knot {k} at {ds:.3e} m"
                        );
                        let margin = checker.knot_margins.iter().find(|m| m.0 == k).unwrap().1;
                        assert!(d < margin);
                    }
                }
            }
            assert!(solved >= 4, "{name}: {solved} of 6 FK solves");
        }
    }

    /// The knots clear the reference robot at q = 0 (the check at its disks finds
    /// nothing), and do not clear a robot whose disks are so large that they collide.
    #[test]
    fn knots_clear_only_what_the_disks_clear() {
        let file = format!("{}/designs/lilge2022.ron", env!("CARGO_MANIFEST_DIR"));
        let design = Tdpcr::from_ron_file(&file).unwrap();
        for (radius, collides) in [(0.006, false), (0.04, true)] {
            let mut design = design.clone();
            design.leg.disks.radius = radius;
            let mut solver = Solver::new(&design).unwrap();
            let model = solver.model().clone();
            let q = vec![0.0; model.n_actuators()];
            let state = solver.solve_fk(&q, &Wrench::default(), None).unwrap().state;
            let mut checker = CollisionChecker::new(&model);
            assert_eq!(checker.check(&model, &state).unwrap().is_some(), collides);
            let clear = checker.clear_by_knots(&model, &state, &checker.shapes);
            assert_eq!(clear, !collides, "disk radius {radius} m");
        }
    }

    const R: f64 = 0.006;

    fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
        Vector3::new(x, y, z)
    }

    #[test]
    fn spheres_touching_do_not_overlap_but_closer_ones_do() {
        let a = v(0.0, 0.0, 0.0);
        assert!(!spheres_overlap(&a, R, &v(0.012, 0.0, 0.0), R), "touching");
        assert!(spheres_overlap(&a, R, &v(0.0119, 0.0, 0.0), R), "overlap");
        assert!(!spheres_overlap(&a, R, &v(0.0, 0.02, 0.0), R), "clear");
        assert!(spheres_overlap(&a, R, &a, R), "concentric");
        // Diagonal separation just below and above 2r.
        let d = 0.012 / 3f64.sqrt();
        assert!(spheres_overlap(&a, R, &v(d, d, d * 0.999), R));
        assert!(!spheres_overlap(&a, R, &v(d, d, d * 1.001), R));
    }

    /// An equilateral triangle in the plane z = 0, circumradius 1.
    fn triangle() -> [Vector3<f64>; 3] {
        let p = |deg: f64| {
            let t = deg.to_radians();
            v(t.cos(), t.sin(), 0.0)
        };
        [p(90.0), p(210.0), p(330.0)]
    }

    #[test]
    fn closest_point_covers_face_edges_and_vertices() {
        let tri = triangle();
        let close = |a: Vector3<f64>, b: Vector3<f64>| (a - b).norm() < 1e-12;
        // Face: straight below/above.
        assert!(close(
            closest_point_on_triangle(&v(0.1, 0.2, 0.5), &tri),
            v(0.1, 0.2, 0.0)
        ));
        // Each vertex region: far beyond the vertex along its radius.
        for c in &tri {
            assert!(close(closest_point_on_triangle(&(c * 3.0), &tri), *c));
        }
        // Each edge region: beyond the edge midpoint, off the plane.
        for i in 0..3 {
            let (a, b) = (tri[i], tri[(i + 1) % 3]);
            let mid = (a + b) / 2.0;
            let p = mid * 2.0 + v(0.0, 0.0, 0.3);
            assert!(close(closest_point_on_triangle(&p, &tri), mid), "edge {i}");
        }
    }

    #[test]
    fn sphere_crosses_the_triangle_face_only_when_closer_than_its_radius() {
        let tri = triangle();
        assert!(
            !sphere_crosses_triangle(&v(0.0, 0.0, 0.5), 0.5, &tri),
            "touching"
        );
        assert!(
            sphere_crosses_triangle(&v(0.0, 0.0, 0.499), 0.5, &tri),
            "crossing"
        );
        assert!(
            sphere_crosses_triangle(&v(0.0, 0.0, -0.499), 0.5, &tri),
            "below"
        );
        assert!(
            sphere_crosses_triangle(&v(0.2, -0.1, 0.0), 0.01, &tri),
            "centre in it"
        );
        assert!(
            !sphere_crosses_triangle(&v(0.0, 0.0, 0.6), 0.5, &tri),
            "clear"
        );
    }

    #[test]
    fn sphere_beside_an_edge_or_a_vertex_is_measured_to_that_feature() {
        // Exactly representable: the edge a–b lies on y = −0.5.
        let exact = [v(-1.0, -0.5, 0.0), v(1.0, -0.5, 0.0), v(0.0, 1.0, 0.0)];
        let crosses = |c: Vector3<f64>, r: f64| sphere_crosses_triangle(&c, r, &exact);
        assert!(!crosses(v(0.0, -0.75, 0.0), 0.25), "edge touch");
        assert!(crosses(v(0.0, -0.74, 0.0), 0.25), "edge cross");
        assert!(!crosses(v(0.0, -0.8, 0.0), 0.25), "edge clear");
        assert!(!crosses(v(0.25, 0.0, 0.5), 0.5), "face touch");
        // Vertex b = (1, −0.5, 0) touched exactly from beyond it along x.
        assert!(!crosses(v(1.25, -0.5, 0.0), 0.25), "vertex touch");
        assert!(crosses(v(1.24, -0.5, 0.0), 0.25), "vertex cross");
        let tri = triangle();
        // Beyond the top vertex (0, 1, 0), off the plane: distance to the vertex counts,
        // although the centre is within r of the plane and of the edges' lines.
        let p = v(0.0, 1.3, 0.3);
        let d = (0.3f64 * 0.3 + 0.3 * 0.3).sqrt();
        assert!(
            !sphere_crosses_triangle(&p, d * 0.999, &tri),
            "vertex clear"
        );
        assert!(sphere_crosses_triangle(&p, d * 1.001, &tri), "vertex cross");
        // Within r of the plane but outside the triangle: no crossing.
        assert!(!sphere_crosses_triangle(&v(3.0, 3.0, 0.0), 0.5, &tri));
    }

    #[test]
    fn first_collision_names_legs_and_disks() {
        let leg = |x: f64| -> Vec<Vector3<f64>> { (1..=3).map(|j| v(x, 0.0, j as f64)).collect() };
        let (l0, l1, l2) = (leg(0.0), leg(1.0), leg(2.0));
        let platform = [v(10.0, 0.0, -5.0), v(11.0, 0.0, -5.0), v(10.0, 1.0, -5.0)];
        assert_eq!(first_collision(&[&l0, &l1, &l2], 0.4, &platform), None);
        let mut l2 = l2;
        l2[1] = v(1.5, 0.0, 2.0); // 0.5 from leg 1's disk 2
        assert_eq!(
            first_collision(&[&l0, &l1, &l2], 0.3, &platform),
            Some(Collision::Legs {
                leg_a: 1,
                disk_a: 2,
                leg_b: 2,
                disk_b: 2
            })
        );
        let platform = [v(-1.0, -1.0, 3.1), v(1.0, -1.0, 3.1), v(0.0, 1.0, 3.1)];
        assert_eq!(
            first_collision(&[&l0, &l1, &leg(5.0)], 0.2, &platform),
            Some(Collision::Platform { leg: 0, disk: 3 })
        );
    }
}
