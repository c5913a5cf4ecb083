//! Shared fixtures for the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

use tdpcr::design::{Disks, Leg, Tdcr, Tendon};

/// Path of a bundled design file.
pub fn design_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("designs")
        .join(name)
}

/// The reference one-segment TDCR (MODEL.md §1 leg, gravity along −z).
pub fn reference_tdcr() -> Tdcr {
    Tdcr::from_ron_file(design_path("tdcr_one_segment.ron")).expect("bundled design loads")
}

/// The reference leg with the given tendons and gravity.
pub fn leg_with(tendons: Vec<Tendon>, gravity: (f64, f64, f64)) -> Tdcr {
    let mut robot = reference_tdcr();
    robot.gravity = gravity;
    robot.leg.tendons = tendons;
    robot
}

/// A bare reference leg (no tendons).
pub fn bare_leg() -> Leg {
    Leg {
        length: 0.145,
        backbone_radius: 0.0005,
        youngs_modulus: 54e9,
        poisson_ratio: 0.3,
        backbone_mass: 0.0012,
        disks: Disks {
            count: 13,
            mass: 0.0003,
            radius: 0.006,
        },
        tendon_stiffness: 1000.0,
        tendons: vec![],
        integration_steps: tdpcr::design::DEFAULT_INTEGRATION_STEPS,
        integrator: tdpcr::design::Integrator::default(),
    }
}

/// Deterministic pseudo-random numbers (the library's SplitMix64), so failures reproduce.
#[allow(unused_imports)]
pub use tdpcr::random::SplitMix64 as Rng;

/// Worst entry-wise mismatch between an analytic and a finite-difference column block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mismatch {
    /// max |a − fd| / max(|fd|_inf, floor): the relative error in the ∞-norm of the block.
    pub relative: f64,
    pub analytic: f64,
    pub fd: f64,
}

/// Relative ∞-norm error of `analytic` against `fd`; `floor` keeps blocks whose true value
/// is (near) zero from dividing by round-off.
pub fn relative_error(analytic: &[f64], fd: &[f64], floor: f64) -> Mismatch {
    let scale = fd.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(floor);
    let mut worst = Mismatch {
        relative: 0.0,
        analytic: 0.0,
        fd: 0.0,
    };
    for (a, f) in analytic.iter().zip(fd) {
        let rel = (a - f).abs() / scale;
        if rel > worst.relative || rel.is_nan() {
            worst = Mismatch {
                relative: rel,
                analytic: *a,
                fd: *f,
            };
        }
    }
    worst
}

/// Central difference of `f` at offset 0 with step `h`, Richardson-extrapolated:
/// (4 C(h/2) − C(h)) / 3 with C(h) = (f(h) − f(−h)) / 2h. Truncation error O(h⁴), so a
/// step large enough to keep round-off small is still accurate.
pub fn central_difference<F>(mut f: F, h: f64) -> nalgebra::DVector<f64>
where
    F: FnMut(f64) -> nalgebra::DVector<f64>,
{
    let c_h = (f(h) - f(-h)) / (2.0 * h);
    let c_half = (f(h / 2.0) - f(-h / 2.0)) / h;
    (c_half * 4.0 - c_h) / 3.0
}
