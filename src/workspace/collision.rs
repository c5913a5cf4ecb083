//! Self-collision checks of the workspace sweep (paper Sec. V-B, MODEL.md §6): every disk
//! of every leg is a sphere of the design's disk radius; spheres of different legs must not
//! overlap, and no sphere may cross the platform triangle (the triangle of the three
//! coupling points at the pose). Touching (distance exactly equal to the sum of radii, or
//! to the radius for the triangle) is not a collision.

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

/// Buffers for [`CollisionChecker::check`]: one leg integration scratch and three shapes.
#[derive(Debug, Clone)]
pub struct CollisionChecker {
    scratch: LegsScratch,
    ends: [LegEnd; 3],
    shapes: [LegShape; 3],
}

impl CollisionChecker {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        let shape = || LegShape::with_capacity(model.leg.n_disks);
        Self {
            scratch: LegsScratch::new(),
            ends: [LegEnd::zeros(); 3],
            shapes: [shape(), shape(), shape()],
        }
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
