//! The cell map: cubic cells of side Δ \[m\] centred on the grid (i Δ, j Δ, k Δ), each
//! represented by one solved point ([`WorkspacePoint`], chosen by [`representatives`]), and
//! the categories a cell falls into ([`Categories`]).

use serde::Serialize;

use crate::kinetostatics::RobotState;

use super::metrics::PointMetrics;
use super::walk::{Ray, Sample};

/// One cell of the map, represented by one solved configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkspacePoint {
    /// Grid cell (i, j, k): centre (i Δ, j Δ, k Δ).
    pub cell: [i64; 3],
    /// Solved platform position \[m\] (in the cell, within Δ/2 of its centre in x and y).
    pub position: [f64; 3],
    /// The solved configuration (q, leg unknowns); a warm start for nearby poses.
    pub state: RobotState,
    /// Tendon tensions \[N\], legs concatenated (n_t per leg).
    pub tensions: Vec<f64>,
    /// The disks collide (not part of the reachable workspace).
    pub collision: bool,
    /// rcond, singularity flags, stability and minimum tension. An unstable point
    /// (`!metrics.stable`) ended its ray and is not part of the reachable workspace.
    pub metrics: PointMetrics,
}

impl WorkspacePoint {
    /// Reachable: valid, stable and collision-free.
    pub fn reachable(&self) -> bool {
        !self.collision && self.metrics.stable
    }
}

/// A count or volume per category of cell.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Categories<T> {
    /// Reachable (valid, collision-free) cells.
    pub reachable: T,
    /// Reachable cells not near any singularity (Type I, Type II or leg).
    pub non_singular: T,
    /// Reachable cells near a Type I singularity.
    pub near_type_i: T,
    /// Reachable cells near a Type II singularity.
    pub near_type_ii: T,
    /// Reachable cells near a leg singularity.
    pub near_leg_singularity: T,
    /// Cells with only colliding solutions.
    pub collision: T,
    /// Cells with only unstable solutions (where rays ended because the equilibrium is
    /// unstable with the actuators held).
    pub unstable: T,
}

/// The chosen sample of a cell.
pub(super) struct Representative<'a> {
    /// (j, i): y index, then x index.
    pub(super) cell: (i64, i64),
    /// The sample that represents the cell.
    pub(super) sample: &'a Sample,
}

/// A sample competing to represent a cell.
struct Candidate<'a> {
    /// 0 valid, 1 colliding, 2 unstable (lower is better).
    rank: u8,
    /// Squared distance to the cell centre in units of Δ².
    distance2: f64,
    sample: &'a Sample,
}

impl Candidate<'_> {
    /// Valid before colliding before unstable, then nearer the centre; on a tie the earlier
    /// sample (in (ray, step) order) stays.
    fn better_than(&self, other: &Self) -> bool {
        self.rank < other.rank || (self.rank == other.rank && self.distance2 < other.distance2)
    }
}

/// One representative per cell of a plane (see the module documentation), in (j, i) order.
pub(super) fn representatives<'a>(
    step: f64,
    origin: &'a Sample,
    rays: &'a [Ray],
) -> Vec<Representative<'a>> {
    use std::collections::BTreeMap;
    let mut best: BTreeMap<(i64, i64), Candidate> = BTreeMap::new();
    let all = std::iter::once(origin).chain(rays.iter().flat_map(|r| r.samples.iter()));
    for sample in all {
        let (x, y) = (
            sample.state.position[0] / step,
            sample.state.position[1] / step,
        );
        let (i, j) = (x.round(), y.round());
        let rank = if !sample.metrics.stable {
            2
        } else {
            u8::from(sample.collision)
        };
        let candidate = Candidate {
            rank,
            distance2: (x - i).powi(2) + (y - j).powi(2),
            sample,
        };
        let cell = (j as i64, i as i64);
        if best.get(&cell).is_none_or(|b| candidate.better_than(b)) {
            best.insert(cell, candidate);
        }
    }
    best.into_iter()
        .map(|(cell, c)| Representative {
            cell,
            sample: c.sample,
        })
        .collect()
}
