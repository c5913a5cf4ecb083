//! The search space: which design parameters vary, their bounds, and the map between the
//! optimizer's unit box \[0, 1\]ⁿ and a [`Tdpcr`] design.
//!
//! A point x of the box maps coordinate-wise to values v_i = min_i + x_i (max_i − min_i),
//! which are written into a copy of the base design ([`DesignParameter::apply`]); the
//! result is validated with the library's design rules, so an invalid combination is an
//! error with the broken rules listed, never a panic.

use serde::{Deserialize, Serialize};
use tdpcr::Tdpcr;
use tdpcr::design::{MAX_LEG_LENGTH, MAX_PRETENSION};
use tdpcr::error::{DesignError, Violations};

/// A design parameter the search may vary (MODEL.md §1, §7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum DesignParameter {
    /// α, angle between each leg and the platform plane \[rad\], in (0, π/2).
    Alpha,
    /// β, rotation of each leg about world z away from the platform centre \[rad\].
    Beta,
    /// L, leg (rod) length \[m\], in (0, 10\]. Tendon end points and the backbone mass
    /// scale with L (same mass per length; a tendon that ends at the tip still does); the
    /// disk count and the integration steps stay those of the base design.
    LegLength,
    /// D, tendon offset from the backbone \[m\], in (0, 10\], the same for every tendon;
    /// at most the disk radius.
    TendonOffset,
    /// L_a, side of the equilateral coupling triangle \[m\], in (0, 10\].
    PlatformSide,
    /// L_c, rigid coupling link from rod tip to spherical joint \[m\], in \[0, 10\].
    CouplingOffset,
    /// τ_pre, pretension of every tendon in the unloaded straight home pose \[N\], in
    /// \[0, 1e6\].
    Pretension,
    /// ψ, roll of each base frame about its leg tangent \[rad\].
    Psi,
    /// Disk radius \[m\], in (0, 10\] (collision spheres; tendons run inside).
    DiskRadius,
}

impl DesignParameter {
    /// Every parameter, in a fixed order.
    pub const ALL: [Self; 9] = [
        Self::Alpha,
        Self::Beta,
        Self::LegLength,
        Self::TendonOffset,
        Self::PlatformSide,
        Self::CouplingOffset,
        Self::Pretension,
        Self::Psi,
        Self::DiskRadius,
    ];

    /// Short name used in CSV headers, the log and the report (`alpha`, `leg_length`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Self::Alpha => "alpha",
            Self::Beta => "beta",
            Self::LegLength => "leg_length",
            Self::TendonOffset => "tendon_offset",
            Self::PlatformSide => "platform_side",
            Self::CouplingOffset => "coupling_offset",
            Self::Pretension => "pretension",
            Self::Psi => "psi",
            Self::DiskRadius => "disk_radius",
        }
    }

    /// Symbol in MODEL.md.
    pub fn symbol(self) -> &'static str {
        match self {
            Self::Alpha => "α",
            Self::Beta => "β",
            Self::LegLength => "L",
            Self::TendonOffset => "D",
            Self::PlatformSide => "L_a",
            Self::CouplingOffset => "L_c",
            Self::Pretension => "τ_pre",
            Self::Psi => "ψ",
            Self::DiskRadius => "r_disk",
        }
    }

    /// SI unit.
    pub fn unit(self) -> &'static str {
        match self {
            Self::Alpha | Self::Beta | Self::Psi => "rad",
            Self::Pretension => "N",
            _ => "m",
        }
    }

    /// The parameter's value in `design` (the tendon offset of the first tendon).
    pub fn get(self, design: &Tdpcr) -> f64 {
        match self {
            Self::Alpha => design.alpha,
            Self::Beta => design.beta,
            Self::LegLength => design.leg.length,
            Self::TendonOffset => design.leg.tendons.first().map_or(0.0, |t| t.offset),
            Self::PlatformSide => design.platform.side_length,
            Self::CouplingOffset => design.coupling_offset,
            Self::Pretension => design.pretension,
            Self::Psi => design.psi,
            Self::DiskRadius => design.leg.disks.radius,
        }
    }

    /// Writes `value` into `design` (see the variants for what else changes with it).
    pub fn apply(self, design: &mut Tdpcr, value: f64) {
        match self {
            Self::Alpha => design.alpha = value,
            Self::Beta => design.beta = value,
            Self::LegLength => {
                let old = design.leg.length;
                let ratio = value / old;
                design.leg.length = value;
                design.leg.backbone_mass *= ratio;
                for t in &mut design.leg.tendons {
                    // A tendon ending at the tip keeps ending exactly there.
                    t.end = if t.end == old { value } else { t.end * ratio };
                }
            }
            Self::TendonOffset => {
                for t in &mut design.leg.tendons {
                    t.offset = value;
                }
            }
            Self::PlatformSide => design.platform.side_length = value,
            Self::CouplingOffset => design.coupling_offset = value,
            Self::Pretension => design.pretension = value,
            Self::Psi => design.psi = value,
            Self::DiskRadius => design.leg.disks.radius = value,
        }
    }

    /// Whether `value` is admissible (physically, and within the design files' limits
    /// `tdpcr::design::{MAX_LEG_LENGTH, MAX_PRETENSION}`), and the rule as text.
    pub fn admissible(self, value: f64) -> (bool, &'static str) {
        let finite = value.is_finite();
        match self {
            Self::Alpha => (
                finite && value > 0.0 && value < std::f64::consts::FRAC_PI_2,
                "in (0, pi/2) rad",
            ),
            Self::Beta | Self::Psi => (finite, "a finite angle [rad]"),
            // The design files' bounds (`tdpcr::design`): a search space beyond them made
            // every candidate there infeasible ("invalid design") one by one.
            Self::LegLength | Self::TendonOffset | Self::PlatformSide | Self::DiskRadius => (
                finite && value > 0.0 && value <= MAX_LEG_LENGTH,
                "in (0, 10] m (a design's lengths are at most 10 m)",
            ),
            Self::CouplingOffset => (
                finite && (0.0..=MAX_LEG_LENGTH).contains(&value),
                "in [0, 10] m (a design's lengths are at most 10 m)",
            ),
            Self::Pretension => (
                finite && (0.0..=MAX_PRETENSION).contains(&value),
                "in [0, 1e6] N (a design's largest pretension)",
            ),
        }
    }
}

impl std::fmt::Display for DesignParameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One varying parameter and its closed interval \[min, max\] (in its SI unit).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bounds {
    /// Which parameter.
    pub parameter: DesignParameter,
    /// Lower bound (parameter unit).
    pub min: f64,
    /// Upper bound (parameter unit), > min.
    pub max: f64,
}

/// The varying parameters applied to a base design.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterSpace {
    base: Tdpcr,
    bounds: Vec<Bounds>,
}

impl ParameterSpace {
    /// The space of `bounds` around `base` (bounds are checked by the config's validation).
    pub fn new(base: Tdpcr, bounds: Vec<Bounds>) -> Self {
        Self { base, bounds }
    }

    /// Number of varying parameters n.
    pub fn dimension(&self) -> usize {
        self.bounds.len()
    }

    /// The bounds, in box-coordinate order.
    pub fn bounds(&self) -> &[Bounds] {
        &self.bounds
    }

    /// The base design (the reference).
    pub fn base(&self) -> &Tdpcr {
        &self.base
    }

    /// Parameter values of the box point `x` (each x_i clamped into \[0, 1\]).
    pub fn values(&self, x: &[f64]) -> Vec<f64> {
        self.bounds
            .iter()
            .zip(x)
            .map(|(b, &t)| b.min + t.clamp(0.0, 1.0) * (b.max - b.min))
            .collect()
    }

    /// The box point of parameter values (not clamped: a value outside its bounds maps
    /// outside \[0, 1\]).
    pub fn normalize(&self, values: &[f64]) -> Vec<f64> {
        self.bounds
            .iter()
            .zip(values)
            .map(|(b, &v)| (v - b.min) / (b.max - b.min))
            .collect()
    }

    /// The varying parameters' values in `design`.
    pub fn values_of(&self, design: &Tdpcr) -> Vec<f64> {
        self.bounds
            .iter()
            .map(|b| b.parameter.get(design))
            .collect()
    }

    /// The design at the box point `x`, validated.
    ///
    /// # Errors
    /// [`DesignError::Invalid`] listing every rule the combination breaks (for example a
    /// tendon offset beyond the disk radius).
    pub fn design(&self, x: &[f64]) -> Result<Tdpcr, DesignError> {
        let mut design = self.base.clone();
        for (b, v) in self.bounds.iter().zip(self.values(x)) {
            b.parameter.apply(&mut design, v);
        }
        design.validate("candidate design")?;
        Ok(design)
    }

    /// Rules of the bounds themselves, appended to `v` with fields `prefix[i].…`; with the
    /// base design, also that a tendon offset fits inside the (fixed) disk radius.
    pub fn check_bounds(bounds: &[Bounds], base: Option<&Tdpcr>, prefix: &str, v: &mut Violations) {
        if bounds.is_empty() {
            v.push(prefix, "[]", "at least one parameter");
        }
        for (i, b) in bounds.iter().enumerate() {
            let f = |name: &str| format!("{prefix}[{i}].{name}");
            if bounds[..i].iter().any(|o| o.parameter == b.parameter) {
                v.push(f("parameter"), b.parameter, "each parameter at most once");
            }
            for (name, x) in [("min", b.min), ("max", b.max)] {
                let (ok, rule) = b.parameter.admissible(x);
                if !ok {
                    v.push(f(name), x, &format!("{rule} ({})", b.parameter));
                }
            }
            if b.min.partial_cmp(&b.max) != Some(std::cmp::Ordering::Less) {
                v.push(f("max"), b.max, &format!("> min = {}", b.min));
            } else if !(b.max - b.min).is_finite() {
                // Angles take any finite value: a range of ±1e308 overflowed, and every
                // candidate's value became infinite.
                v.push(
                    f("max"),
                    b.max,
                    &format!("a finite range max − min (min = {})", b.min),
                );
            }
            if let Some(base) = base {
                let disk_varies = bounds
                    .iter()
                    .any(|o| o.parameter == DesignParameter::DiskRadius);
                let radius = base.leg.disks.radius;
                if b.parameter == DesignParameter::TendonOffset && !disk_varies && b.max > radius {
                    v.push(
                        f("max"),
                        b.max,
                        &format!("<= the base design's disk radius {radius} m (tendons run inside the disks)"),
                    );
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn base() -> Tdpcr {
        Tdpcr::from_ron_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../designs/lilge2022.ron"
        ))
        .unwrap()
    }

    /// A bound beyond a design file's magnitude limits is refused as a bound (the design
    /// refuses it too), one within them is admitted; the rules' text states the limits.
    #[test]
    fn bounds_beyond_the_design_files_limits_are_refused() {
        assert_eq!(
            (MAX_LEG_LENGTH, MAX_PRETENSION),
            (10.0, 1e6),
            "update the rules' text"
        );
        for p in DesignParameter::ALL {
            let limit = match p {
                DesignParameter::Pretension => MAX_PRETENSION,
                DesignParameter::Alpha | DesignParameter::Beta | DesignParameter::Psi => continue,
                _ => MAX_LEG_LENGTH,
            };
            assert!(p.admissible(limit).0, "{p} = {limit}");
            let beyond = 1.5 * limit;
            let (ok, rule) = p.admissible(beyond);
            assert!(!ok, "{p} = {beyond} admitted");
            let mut design = base();
            p.apply(&mut design, beyond);
            assert!(design.validate("test").is_err(), "{p} = {beyond}: {rule}");
        }
        let mut v = Violations::default();
        let bounds = [
            Bounds {
                parameter: DesignParameter::Pretension,
                min: 0.0,
                max: 2e7,
            },
            Bounds {
                parameter: DesignParameter::Beta,
                min: -1e308,
                max: 1e308,
            },
        ];
        ParameterSpace::check_bounds(&bounds, Some(&base()), "parameters", &mut v);
        let text = v.to_string();
        assert!(
            text.contains("parameters[0].max = 20000000")
                && text.contains("1e6] N")
                && text.contains("parameters[1].max = 1e308: expected a finite range"),
            "{text}"
        );
    }

    #[test]
    fn values_round_trip_through_the_box_and_every_parameter_reads_back() {
        let bounds: Vec<Bounds> = [
            (DesignParameter::Alpha, 0.3, 1.2),
            (DesignParameter::Beta, -1.0, 1.5),
            (DesignParameter::LegLength, 0.1, 0.2),
            (DesignParameter::TendonOffset, 0.003, 0.006),
            (DesignParameter::PlatformSide, 0.08, 0.16),
            (DesignParameter::CouplingOffset, 0.0, 0.04),
            (DesignParameter::Pretension, 0.0, 2.0),
            (DesignParameter::Psi, -0.5, 0.5),
            (DesignParameter::DiskRadius, 0.006, 0.01),
        ]
        .into_iter()
        .map(|(parameter, min, max)| Bounds {
            parameter,
            min,
            max,
        })
        .collect();
        let space = ParameterSpace::new(base(), bounds);
        let x = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];
        let design = space.design(&x).unwrap();
        let values = space.values(&x);
        for (b, v) in space.bounds().iter().zip(&values) {
            assert!(
                (b.parameter.get(&design) - v).abs() < 1e-15,
                "{}",
                b.parameter
            );
        }
        let back = space.normalize(&space.values_of(&design));
        for (a, b) in back.iter().zip(x) {
            assert!((a - b).abs() < 1e-12);
        }
        // L scaled the tendon ends (still at the tip) and the backbone mass.
        let l = design.leg.length;
        assert!(
            design
                .leg
                .tendons
                .iter()
                .all(|t| t.end == l && t.offset == values[3])
        );
        assert!((design.leg.backbone_mass - 0.0012 * l / 0.145).abs() < 1e-15);
        // The written design loads back.
        let again = Tdpcr::from_ron_str(&design.to_ron_string(), "written").unwrap();
        assert_eq!(again, design);
    }

    #[test]
    fn an_offset_beyond_the_disk_radius_is_an_invalid_design_not_a_panic() {
        let bounds = vec![
            Bounds {
                parameter: DesignParameter::TendonOffset,
                min: 0.003,
                max: 0.009,
            },
            Bounds {
                parameter: DesignParameter::DiskRadius,
                min: 0.004,
                max: 0.008,
            },
        ];
        let space = ParameterSpace::new(base(), bounds);
        let err = space.design(&[1.0, 0.0]).unwrap_err().to_string();
        assert!(
            err.contains("leg.tendons[0].offset = 0.009: expected <= disks.radius = 0.004 m"),
            "{err}"
        );
    }

    #[test]
    fn bad_bounds_are_all_listed() {
        let bounds = vec![
            Bounds {
                parameter: DesignParameter::Alpha,
                min: 0.5,
                max: 2.0,
            },
            Bounds {
                parameter: DesignParameter::Alpha,
                min: 0.5,
                max: 1.0,
            },
            Bounds {
                parameter: DesignParameter::LegLength,
                min: 0.2,
                max: 0.1,
            },
            Bounds {
                parameter: DesignParameter::TendonOffset,
                min: 0.002,
                max: 0.008,
            },
        ];
        let mut v = Violations::default();
        ParameterSpace::check_bounds(&bounds, Some(&base()), "parameters", &mut v);
        let text: Vec<String> = v.0.iter().map(|x| x.to_string()).collect();
        assert_eq!(
            text,
            [
                "parameters[0].max = 2: expected in (0, pi/2) rad (alpha)",
                "parameters[1].parameter = alpha: expected each parameter at most once",
                "parameters[2].max = 0.1: expected > min = 0.2",
                "parameters[3].max = 0.008: expected <= the base design's disk radius 0.006 m (tendons run inside the disks)",
            ]
        );
    }
}
