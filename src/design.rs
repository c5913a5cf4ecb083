//! Design files: what a user writes (RON, SI units), and the rules a design must satisfy.
//!
//! Two kinds of file share the same [`Leg`]:
//! - [`Tdcr`]: one tendon-driven continuum robot, base at the origin, straight along +z;
//! - [`Tdpcr`]: the parallel robot of three identical legs holding a platform (MODEL.md §1).
//!
//! Loading ([`Tdcr::from_ron_file`], [`Tdpcr::from_ron_file`]) parses, rejects unknown
//! fields, and validates every value, listing all broken rules at once.

use std::f64::consts::PI;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{DesignError, Violations};

/// Most tendons one leg may carry (sizes the allocation-free integrator buffers).
pub const MAX_TENDONS: usize = 12;

/// Most spacer disks one leg may carry. Disks are not integration step boundaries, but
/// an integration that records the legs' shapes takes a partial step to each disk inside
/// a step (6 right-hand sides each with the default method), so the disk count bounds
/// the cost of those integrations (the workspace sweep's and the design search's exact
/// Jacobians, shape outputs) from below; a count of 100 000 ran for minutes without a word
/// when disks were step boundaries.
pub const MAX_DISKS: usize = 1000;

/// Longest rod length accepted \[m\]: far beyond any continuum robot (the bundled designs'
/// legs are 0.145-0.2 m); longer rods only diverge.
pub const MAX_LEG_LENGTH: f64 = 10.0;

/// The range of Young's modulus accepted \[Pa\]: from hydrogels (≈ 1e3 Pa) to beyond
/// diamond (1.2e12 Pa). Outside it the rod's stiffness and its loads differ by more
/// orders of magnitude than the solver's tolerances span: a modulus of 1e308 Pa passed
/// validation and every solve diverged.
pub const YOUNGS_MODULUS_RANGE: [f64; 2] = [1e3, 1e13];

/// Largest mass accepted for the backbone, the disks and the platform \[kg\] (the
/// bundled designs' are 0.3–34 g).
pub const MAX_MASS: f64 = 1e3;

/// The range of a tendon's axial stiffness (EA)_t accepted \[N\] (the bundled designs':
/// 1000 N; a steel cable of 1 mm² about 2e5 N).
pub const TENDON_STIFFNESS_RANGE: [f64; 2] = [1e-3, 1e10];

/// Largest pretension accepted \[N\] (the design search's range ends at a few newtons).
pub const MAX_PRETENSION: f64 = 1e6;

/// Largest magnitude of a gravity component accepted \[m/s²\] (100 g).
pub const MAX_GRAVITY: f64 = 1e3;

/// Default number of fixed integration steps over the whole leg length (with the default
/// [`Integrator::Rk5`]; MODEL.md §5).
pub const DEFAULT_INTEGRATION_STEPS: usize = 10;

/// The fixed-step explicit Runge–Kutta method of the leg integration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Integrator {
    /// The classical fourth-order method (4 right-hand sides per step); with 26 steps, the
    /// default before 2026-11-26.
    Rk4,
    /// Butcher's fifth-order method (6 right-hand sides per step): at 10 steps about as
    /// accurate as `Rk4` at 26, with 60 instead of 104 right-hand sides (MODEL.md §5).
    #[default]
    Rk5,
}

/// One tendon, routed straight (parallel to the backbone) at a fixed offset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tendon {
    /// Angle about the rod axis, from the body x-axis \[rad\].
    pub angle: f64,
    /// Distance from the backbone centre line \[m\].
    pub offset: f64,
    /// Arc length at which the tendon is attached to its last disk \[m\], in (0, L].
    pub end: f64,
}

/// The spacer disks: equally spaced, the last one at the tip.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Disks {
    /// Number of disks (≥ 1); disk j sits at s = j·L/count, j = 1..count.
    pub count: usize,
    /// Mass of one disk \[kg\].
    pub mass: f64,
    /// Disk radius \[m\], used for collision checks; tendon offsets must fit inside.
    pub radius: f64,
}

/// One tendon-driven Cosserat rod (MODEL.md §2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Leg {
    /// Rod length L \[m\].
    pub length: f64,
    /// Radius of the solid round backbone \[m\].
    pub backbone_radius: f64,
    /// Young's modulus E \[Pa\].
    pub youngs_modulus: f64,
    /// Poisson ratio ν, in (−1, 0.5); G = E / (2(1 + ν)).
    pub poisson_ratio: f64,
    /// Backbone mass \[kg\] (spread uniformly over L with the disk masses).
    pub backbone_mass: f64,
    /// Spacer disks.
    pub disks: Disks,
    /// Axial stiffness of each tendon (EA)_t \[N\].
    pub tendon_stiffness: f64,
    /// The tendons, in the order used for tensions and displacements.
    pub tendons: Vec<Tendon>,
    /// Optional: fixed integration steps over the whole length (default
    /// [`DEFAULT_INTEGRATION_STEPS`]). Steps are spread over the intervals between the
    /// points where tendons end, in proportion to their lengths and at least one per
    /// interval; disks inside a step get their frames from partial steps.
    #[serde(default = "default_integration_steps")]
    pub integration_steps: usize,
    /// Optional: the integration method (default [`Integrator::Rk5`]).
    #[serde(default)]
    pub integrator: Integrator,
}

fn default_integration_steps() -> usize {
    DEFAULT_INTEGRATION_STEPS
}

/// A single tendon-driven continuum robot: base frame = world frame, rod along +z.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tdcr {
    /// Gravitational acceleration in the world frame \[m/s²\].
    pub gravity: (f64, f64, f64),
    /// The robot.
    pub leg: Leg,
}

/// The platform (end-effector) of the parallel robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Platform {
    /// Side length L_a of the equilateral coupling triangle \[m\].
    pub side_length: f64,
    /// Platform mass m_p \[kg\].
    pub mass: f64,
}

/// Actuation limits (symmetric about zero).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuationLimits {
    /// Largest |q_b| per tendon pair \[m\].
    pub tendon_displacement: f64,
    /// Largest |q_t| per base \[m\].
    pub base_translation: f64,
}

/// A tendon-driven parallel continuum robot (MODEL.md §1).
///
/// The leg's tendons come in antagonistic pairs (tendon 2j and 2j+1 at opposite
/// angles): one pair gives the 6-DoF design, two pairs the 9-DoF design.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tdpcr {
    /// Gravitational acceleration in the world frame \[m/s²\].
    pub gravity: (f64, f64, f64),
    /// The leg used three times.
    pub leg: Leg,
    /// The platform.
    pub platform: Platform,
    /// Rigid link L_c from rod tip to spherical joint, along the tip tangent \[m\].
    pub coupling_offset: f64,
    /// Angle α between each leg and the platform plane \[rad\].
    pub alpha: f64,
    /// Rotation β of each leg about world z, away from pointing at the centre \[rad\].
    pub beta: f64,
    /// Optional roll ψ of each base frame about its leg tangent \[rad\] (default 0).
    #[serde(default)]
    pub psi: f64,
    /// Optional angles θ_i of the coupling points in the platform frame \[rad\]
    /// (default 90°, 210°, 330°).
    #[serde(default = "default_coupling_angles")]
    pub coupling_angles: (f64, f64, f64),
    /// Tension τ_pre of every tendon in the unloaded straight home configuration \[N\].
    pub pretension: f64,
    /// Actuation limits.
    pub actuation_limits: ActuationLimits,
}

fn default_coupling_angles() -> (f64, f64, f64) {
    (
        PI / 2.0,
        PI / 2.0 + 2.0 * PI / 3.0,
        PI / 2.0 + 4.0 * PI / 3.0,
    )
}

/// Reads and parses a RON file into `T`, mapping errors to [`DesignError`].
fn parse_ron_file<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T, DesignError> {
    parse_ron_str(&read_design_text(path)?, path)
}

/// The most bytes a design file may have (the bundled ones have about 2 kB).
pub const MAX_DESIGN_FILE_BYTES: u64 = 16 << 20;

/// The text of the design file `path`, at most [`MAX_DESIGN_FILE_BYTES`] (reading
/// `/dev/zero` took all the memory there was).
///
/// # Errors
/// [`DesignError::Io`] if it cannot be read, is not UTF-8 or is longer.
pub fn read_design_text(path: &Path) -> Result<String, DesignError> {
    read_text_at_most(path, MAX_DESIGN_FILE_BYTES, "a design file").map_err(|source| {
        DesignError::Io {
            path: path.to_path_buf(),
            source,
        }
    })
}

/// The text of the file `path` if it has at most `max_bytes` bytes (a user's file given
/// as `what`: reading `/dev/zero` whole took all the memory there was).
///
/// # Errors
/// The read's error; [`std::io::ErrorKind::InvalidData`] if it is not UTF-8 or longer
/// than `max_bytes` ("longer than N bytes: not WHAT").
pub fn read_text_at_most(path: &Path, max_bytes: u64, what: &str) -> std::io::Result<String> {
    use std::io::Read;
    let mut text = String::new();
    std::fs::File::open(path)?
        .take(max_bytes + 1)
        .read_to_string(&mut text)?;
    if text.len() as u64 > max_bytes {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("longer than {max_bytes} bytes: not {what}"),
        ));
    }
    Ok(text)
}

fn parse_ron_str<T: for<'de> Deserialize<'de>>(text: &str, path: &Path) -> Result<T, DesignError> {
    ron::de::from_str(text).map_err(|e| DesignError::Parse {
        path: path.to_path_buf(),
        line: e.span.start.line,
        column: e.span.start.col,
        message: e.code.to_string(),
    })
}

/// Serializes with struct names, so the output loads back.
fn to_ron_string<T: Serialize>(value: &T) -> String {
    let config = ron::ser::PrettyConfig::new().struct_names(true);
    ron::ser::to_string_pretty(value, config).expect("design structs always serialize")
}

fn check_finite(v: &mut Violations, field: &str, value: f64) -> bool {
    if value.is_finite() {
        true
    } else {
        v.push(field, value, "a finite number");
        false
    }
}

fn check_positive(v: &mut Violations, field: &str, value: f64, unit: &str) {
    if !(value.is_finite() && value > 0.0) {
        v.push(field, value, &format!("> 0 {unit}"));
    }
}

fn check_non_negative(v: &mut Violations, field: &str, value: f64, unit: &str) {
    if !(value.is_finite() && value >= 0.0) {
        v.push(field, value, &format!(">= 0 {unit}"));
    }
}

/// The rule of a length bounded by the longest leg.
fn within_leg_length() -> String {
    format!("<= {MAX_LEG_LENGTH} m (the largest leg length)")
}

/// `value` at most `max` (a finite value; non-finite ones are the other checks').
fn check_at_most(v: &mut Violations, field: &str, value: f64, max: f64, expected: &str) {
    if value.is_finite() && value > max {
        v.push(field, value, expected);
    }
}

/// `value` within `[lo, hi]` (a positive value; others are [`check_positive`]'s).
fn check_within(v: &mut Violations, field: &str, value: f64, [lo, hi]: [f64; 2], expected: &str) {
    if value.is_finite() && value > 0.0 && !(lo..=hi).contains(&value) {
        v.push(field, value, expected);
    }
}

fn check_gravity(v: &mut Violations, g: (f64, f64, f64)) {
    for (name, x) in [("gravity.0", g.0), ("gravity.1", g.1), ("gravity.2", g.2)] {
        if check_finite(v, name, x) && x.abs() > MAX_GRAVITY {
            v.push(
                name,
                x,
                &format!("within +-{MAX_GRAVITY} m/s^2 (100 g; Earth's is 9.81)"),
            );
        }
    }
}

impl Leg {
    /// Appends every broken rule of this leg to `v`; field names start with `prefix`.
    pub fn check(&self, prefix: &str, v: &mut Violations) {
        let f = |name: &str| format!("{prefix}.{name}");
        check_positive(v, &f("length"), self.length, "m");
        if self.length.is_finite() && self.length > MAX_LEG_LENGTH {
            v.push(
                f("length"),
                self.length,
                &format!(
                    "<= {MAX_LEG_LENGTH} m (a continuum robot's rod; the bundled designs' \
                     are 0.145-0.2 m)"
                ),
            );
        }
        check_positive(v, &f("backbone_radius"), self.backbone_radius, "m");
        check_positive(v, &f("youngs_modulus"), self.youngs_modulus, "Pa");
        let [e_lo, e_hi] = YOUNGS_MODULUS_RANGE;
        check_within(
            v,
            &f("youngs_modulus"),
            self.youngs_modulus,
            YOUNGS_MODULUS_RANGE,
            &format!(
                "in [{e_lo:e}, {e_hi:e}] Pa (silicone rubber about 1e6, nitinol 5e10-8e10, \
                 diamond 1.2e12)"
            ),
        );
        if !(self.poisson_ratio > -1.0 && self.poisson_ratio < 0.5) {
            v.push(f("poisson_ratio"), self.poisson_ratio, "in (-1, 0.5)");
        }
        check_non_negative(v, &f("backbone_mass"), self.backbone_mass, "kg");
        let mass_bound = format!("<= {MAX_MASS:e} kg");
        check_at_most(
            v,
            &f("backbone_mass"),
            self.backbone_mass,
            MAX_MASS,
            &mass_bound,
        );
        if !(1..=MAX_DISKS).contains(&self.disks.count) {
            v.push(
                f("disks.count"),
                self.disks.count,
                &format!("in 1..={MAX_DISKS} (each disk costs a partial integration step)"),
            );
        }
        check_non_negative(v, &f("disks.mass"), self.disks.mass, "kg");
        check_at_most(v, &f("disks.mass"), self.disks.mass, MAX_MASS, &mass_bound);
        check_positive(v, &f("disks.radius"), self.disks.radius, "m");
        // The disks and the backbone are no larger than the largest rod (a radius of
        // 1e308 m overflowed the collision checks and the 3D views' coordinates).
        for (field, radius) in [
            ("disks.radius", self.disks.radius),
            ("backbone_radius", self.backbone_radius),
        ] {
            if radius.is_finite() && radius > MAX_LEG_LENGTH {
                v.push(f(field), radius, &within_leg_length());
            }
        }
        check_positive(v, &f("tendon_stiffness"), self.tendon_stiffness, "N");
        let [k_lo, k_hi] = TENDON_STIFFNESS_RANGE;
        check_within(
            v,
            &f("tendon_stiffness"),
            self.tendon_stiffness,
            TENDON_STIFFNESS_RANGE,
            &format!("in [{k_lo:e}, {k_hi:e}] N (the axial stiffness EA of a tendon)"),
        );
        if !(1..=100_000).contains(&self.integration_steps) {
            v.push(
                f("integration_steps"),
                self.integration_steps,
                "in 1..=100000",
            );
        }
        if self.tendons.len() > MAX_TENDONS {
            v.push(
                f("tendons"),
                format!("{} tendons", self.tendons.len()),
                &format!("at most {MAX_TENDONS} tendons"),
            );
        }
        for (k, t) in self.tendons.iter().enumerate() {
            let tf = |name: &str| format!("{prefix}.tendons[{k}].{name}");
            check_finite(v, &tf("angle"), t.angle);
            if !(t.offset.is_finite() && t.offset > 0.0) {
                v.push(tf("offset"), t.offset, "> 0 m");
            } else if self.disks.radius > 0.0 && t.offset > self.disks.radius {
                v.push(
                    tf("offset"),
                    t.offset,
                    &format!(
                        "<= disks.radius = {} m (the tendon runs through the disks)",
                        self.disks.radius
                    ),
                );
            }
            if !(t.end.is_finite() && t.end > 0.0 && t.end <= self.length) {
                v.push(
                    tf("end"),
                    t.end,
                    &format!(
                        "in (0, length = {}] m (an arc length on the rod)",
                        self.length
                    ),
                );
            }
        }
    }
}

impl Tdcr {
    /// Loads and validates a single-TDCR file.
    ///
    /// # Errors
    /// [`DesignError::Io`], [`DesignError::Parse`] with line and column, or
    /// [`DesignError::Invalid`] listing every broken rule.
    pub fn from_ron_file(path: impl AsRef<Path>) -> Result<Self, DesignError> {
        let path = path.as_ref();
        let robot: Self = parse_ron_file(path)?;
        robot.validate(&path.display().to_string())?;
        Ok(robot)
    }

    /// Parses and validates RON text (`source` names it in errors).
    pub fn from_ron_str(text: &str, source: &str) -> Result<Self, DesignError> {
        let robot: Self = parse_ron_str(text, Path::new(source))?;
        robot.validate(source)?;
        Ok(robot)
    }

    /// Checks every rule; all violations are reported together.
    pub fn validate(&self, source: &str) -> Result<(), DesignError> {
        let mut v = Violations::default();
        check_gravity(&mut v, self.gravity);
        self.leg.check("leg", &mut v);
        v.into_result(source)
    }

    /// The design as RON text (loads back with [`Tdcr::from_ron_str`]).
    pub fn to_ron_string(&self) -> String {
        to_ron_string(self)
    }
}

impl Tdpcr {
    /// Loads and validates a parallel-robot design file.
    ///
    /// # Errors
    /// As [`Tdcr::from_ron_file`].
    pub fn from_ron_file(path: impl AsRef<Path>) -> Result<Self, DesignError> {
        let path = path.as_ref();
        let design: Self = parse_ron_file(path)?;
        design.validate(&path.display().to_string())?;
        Ok(design)
    }

    /// Parses and validates RON text (`source` names it in errors).
    pub fn from_ron_str(text: &str, source: &str) -> Result<Self, DesignError> {
        let design: Self = parse_ron_str(text, Path::new(source))?;
        design.validate(source)?;
        Ok(design)
    }

    /// Number of antagonistic tendon pairs per leg (1: 6-DoF design, 2: 9-DoF design).
    pub fn pairs_per_leg(&self) -> usize {
        self.leg.tendons.len() / 2
    }

    /// Length of the actuation vector q: 3 · (pairs + 1).
    pub fn n_actuators(&self) -> usize {
        3 * (self.pairs_per_leg() + 1)
    }

    /// Checks every rule; all violations are reported together.
    pub fn validate(&self, source: &str) -> Result<(), DesignError> {
        let mut v = Violations::default();
        check_gravity(&mut v, self.gravity);
        self.leg.check("leg", &mut v);
        let n = self.leg.tendons.len();
        if n != 2 && n != 4 {
            v.push(
                "leg.tendons",
                format!("{n} tendons"),
                "2 (one antagonistic pair: 6-DoF) or 4 (two pairs: 9-DoF)",
            );
        }
        for j in 0..n / 2 {
            let (a, b) = (&self.leg.tendons[2 * j], &self.leg.tendons[2 * j + 1]);
            let gap = (b.angle - a.angle).rem_euclid(2.0 * PI);
            if (gap - PI).abs() > 1e-9 {
                v.push(
                    format!("leg.tendons[{}].angle", 2 * j + 1),
                    b.angle,
                    &format!("tendon[{}].angle + pi (antagonistic pair)", 2 * j),
                );
            }
            if a.offset != b.offset || a.end != b.end {
                v.push(
                    format!("leg.tendons[{}]", 2 * j + 1),
                    format!("offset {}, end {}", b.offset, b.end),
                    &format!(
                        "the offset and end of tendon[{}] (antagonistic pair)",
                        2 * j
                    ),
                );
            }
        }
        check_positive(
            &mut v,
            "platform.side_length",
            self.platform.side_length,
            "m",
        );
        check_at_most(
            &mut v,
            "platform.side_length",
            self.platform.side_length,
            MAX_LEG_LENGTH,
            &within_leg_length(),
        );
        check_non_negative(&mut v, "platform.mass", self.platform.mass, "kg");
        check_at_most(
            &mut v,
            "platform.mass",
            self.platform.mass,
            MAX_MASS,
            &format!("<= {MAX_MASS:e} kg"),
        );
        check_non_negative(&mut v, "coupling_offset", self.coupling_offset, "m");
        check_at_most(
            &mut v,
            "coupling_offset",
            self.coupling_offset,
            MAX_LEG_LENGTH,
            &within_leg_length(),
        );
        if !(self.alpha.is_finite() && self.alpha > 0.0 && self.alpha < PI / 2.0) {
            v.push("alpha", self.alpha, "in (0, pi/2) rad");
        }
        check_finite(&mut v, "beta", self.beta);
        check_finite(&mut v, "psi", self.psi);
        let (a0, a1, a2) = self.coupling_angles;
        for (name, x) in [
            ("coupling_angles.0", a0),
            ("coupling_angles.1", a1),
            ("coupling_angles.2", a2),
        ] {
            check_finite(&mut v, name, x);
        }
        // The joints on the platform's circle span a triangle: at one point (1, 1, 1) the
        // platform turned freely about it, and every solve ran to its iteration limit.
        let area = 0.5 * ((a1 - a0).sin() + (a2 - a1).sin() + (a0 - a2).sin()).abs();
        let equilateral = 0.75 * 3f64.sqrt();
        if [a0, a1, a2].iter().all(|x| x.is_finite()) && area < 0.01 * equilateral {
            v.push(
                "coupling_angles",
                format!("({a0}, {a1}, {a2})"),
                "three joints spanning a triangle of at least 1 % of the equilateral one's \
                 area (coincident joints leave the platform free to turn)",
            );
        }
        check_non_negative(&mut v, "pretension", self.pretension, "N");
        check_at_most(
            &mut v,
            "pretension",
            self.pretension,
            MAX_PRETENSION,
            &format!("<= {MAX_PRETENSION:e} N"),
        );
        check_positive(
            &mut v,
            "actuation_limits.tendon_displacement",
            self.actuation_limits.tendon_displacement,
            "m",
        );
        check_positive(
            &mut v,
            "actuation_limits.base_translation",
            self.actuation_limits.base_translation,
            "m",
        );
        for (field, limit) in [
            (
                "actuation_limits.tendon_displacement",
                self.actuation_limits.tendon_displacement,
            ),
            (
                "actuation_limits.base_translation",
                self.actuation_limits.base_translation,
            ),
        ] {
            check_at_most(&mut v, field, limit, MAX_LEG_LENGTH, &within_leg_length());
        }
        v.into_result(source)
    }

    /// The design as RON text (loads back with [`Tdpcr::from_ron_str`]).
    pub fn to_ron_string(&self) -> String {
        to_ron_string(self)
    }
}

/// A leg of the reference design's dimensions (MODEL.md §1) with tendons at
/// `(angle [rad], end [m])`, 5 mm off the backbone: for unit tests of the rod kernel.
#[cfg(test)]
pub(crate) fn test_leg(tendons: &[(f64, f64)]) -> Leg {
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
        tendons: tendons
            .iter()
            .map(|&(angle, end)| Tendon {
                angle,
                offset: 0.005,
                end,
            })
            .collect(),
        integration_steps: DEFAULT_INTEGRATION_STEPS,
        integrator: Integrator::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 14: a tendon offset beyond the disk radius is told against the radius first,
    /// before the antagonistic-pair rule it also breaks.
    #[test]
    fn an_offset_beyond_the_disks_is_reported_against_their_radius_first() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/designs/lilge2022.ron");
        let text = std::fs::read_to_string(path).unwrap().replace(
            "Tendon(angle: 3.141592653589793, offset: 0.005",
            "Tendon(angle: 3.141592653589793, offset: 0.007",
        );
        let message = Tdpcr::from_ron_str(&text, "wide offset")
            .unwrap_err()
            .to_string();
        let radius = message
            .find("leg.tendons[1].offset = 0.007: expected <= disks.radius = 0.006 m")
            .unwrap_or_else(|| panic!("{message}"));
        let pair = message.find("antagonistic pair").unwrap_or(usize::MAX);
        assert!(radius < pair, "{message}");
    }
}
