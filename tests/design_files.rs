//! Design files: bundled files load and round-trip; every rule gives a clear error.

mod common;

use common::design_path;
use tdpcr::error::DesignError;
use tdpcr::{Tdcr, Tdpcr};

const TDCR: &str = include_str!("../designs/tdcr_one_segment.ron");
const TDPCR: &str = include_str!("../designs/lilge2022.ron");

fn violations(err: DesignError) -> Vec<(String, String)> {
    match err {
        DesignError::Invalid { violations, .. } => violations
            .0
            .into_iter()
            .map(|v| (v.field, v.value))
            .collect(),
        e => panic!("expected a validation error, got {e}"),
    }
}

#[test]
fn every_bundled_design_loads_validates_and_round_trips() {
    let mut seen = 0;
    for entry in std::fs::read_dir(design_path("")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "ron") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        if text.contains("Tdpcr(") {
            let d = Tdpcr::from_ron_file(&path).unwrap();
            let again = Tdpcr::from_ron_str(&d.to_ron_string(), "round trip").unwrap();
            assert_eq!(d, again, "{}", path.display());
        } else {
            let r = Tdcr::from_ron_file(&path).unwrap();
            let again = Tdcr::from_ron_str(&r.to_ron_string(), "round trip").unwrap();
            assert_eq!(r, again, "{}", path.display());
        }
        seen += 1;
    }
    assert!(seen >= 4, "only {seen} design files found");
}

#[test]
fn the_reference_designs_carry_the_paper_values() {
    let d = Tdpcr::from_ron_file(design_path("lilge2022.ron")).unwrap();
    assert_eq!(d.n_actuators(), 6);
    assert_eq!(d.leg.length, 0.145);
    assert_eq!(d.leg.disks.count, 13);
    assert_eq!(d.platform.side_length, 0.13);
    assert_eq!(d.coupling_offset, 0.0225);
    assert_eq!(d.platform.mass, 0.0344);
    assert!((d.alpha.to_degrees() - 30.0).abs() < 1e-12);
    assert!((d.beta.to_degrees() - 60.0).abs() < 1e-12);
    let r = Tdpcr::from_ron_file(design_path("lilge2022_redundant.ron")).unwrap();
    assert_eq!(r.n_actuators(), 9);
}

#[test]
fn every_broken_rule_is_listed_at_once_with_field_and_value() {
    let text = TDCR
        .replace("length: 0.145,", "length: -0.145,")
        .replace("poisson_ratio: 0.3", "poisson_ratio: 0.5")
        .replace(
            "Tendon(angle: 0.0, offset: 0.005, end: 0.145)",
            "Tendon(angle: 0.0, offset: 0.005, end: 0.0)",
        )
        .replace(
            "Tendon(angle: 3.141592653589793, offset: 0.005, end: 0.145)",
            "Tendon(angle: 3.141592653589793, offset: 0.05, end: 0.2)",
        )
        .replace("youngs_modulus: 54e9", "youngs_modulus: 0.0")
        .replace("count: 13", "count: 0");
    let err = Tdcr::from_ron_str(&text, "bad.ron").unwrap_err();
    let msg = err.to_string();
    let v = violations(err);
    let fields: Vec<&str> = v.iter().map(|(f, _)| f.as_str()).collect();
    for expected in [
        "leg.length",
        "leg.youngs_modulus",
        "leg.poisson_ratio",
        "leg.disks.count",
        "leg.tendons[0].end",
        "leg.tendons[1].offset",
        "leg.tendons[1].end",
    ] {
        assert!(
            fields.contains(&expected),
            "{expected} missing from {fields:?}"
        );
    }
    assert!(msg.starts_with("invalid bad.ron (7 problems)"), "{msg}");
    assert!(
        msg.contains("leg.poisson_ratio = 0.5: expected in (-1, 0.5)"),
        "{msg}"
    );
    assert!(msg.contains("leg.length = -0.145: expected > 0 m"), "{msg}");
}

#[test]
fn each_single_rule_is_enforced() {
    let cases: &[(&str, &str, &str)] = &[
        (
            "backbone_radius: 0.0005",
            "backbone_radius: 0.0",
            "leg.backbone_radius",
        ),
        (
            "backbone_mass: 0.0012",
            "backbone_mass: -1.0",
            "leg.backbone_mass",
        ),
        ("mass: 0.0003", "mass: -0.1", "leg.disks.mass"),
        ("count: 13", "count: 100000", "leg.disks.count"),
        ("radius: 0.006", "radius: 0.0", "leg.disks.radius"),
        ("radius: 0.006", "radius: 1e308", "leg.disks.radius"),
        (
            "backbone_radius: 0.0005",
            "backbone_radius: 20.0",
            "leg.backbone_radius",
        ),
        (
            "tendon_stiffness: 1000.0",
            "tendon_stiffness: 0.0",
            "leg.tendon_stiffness",
        ),
        (
            "poisson_ratio: 0.3",
            "poisson_ratio: -1.0",
            "leg.poisson_ratio",
        ),
        (
            "youngs_modulus: 54e9",
            "youngs_modulus: inf",
            "leg.youngs_modulus",
        ),
        (
            "gravity: (0.0, 0.0, -9.81)",
            "gravity: (0.0, NaN, -9.81)",
            "gravity.1",
        ),
        (
            "Tendon(angle: 0.0, offset: 0.005",
            "Tendon(angle: 0.0, offset: -0.005",
            "leg.tendons[0].offset",
        ),
        (
            "Tendon(angle: 0.0,",
            "Tendon(angle: inf,",
            "leg.tendons[0].angle",
        ),
    ];
    for (from, to, field) in cases {
        assert!(TDCR.contains(from), "fixture lacks {from}");
        let err = Tdcr::from_ron_str(&TDCR.replacen(from, to, 1), "case").unwrap_err();
        let v = violations(err);
        assert_eq!(v.len(), 1, "{to}: {v:?}");
        assert_eq!(v[0].0, *field);
    }
    // A tendon outside the disks is told against the disk radius first, before the
    // antagonistic-pair rule it also breaks.
    let outside = TDPCR.replacen(
        "Tendon(angle: 3.141592653589793, offset: 0.005",
        "Tendon(angle: 3.141592653589793, offset: 0.05",
        1,
    );
    assert_ne!(outside, TDPCR, "fixture lacks the second tendon");
    let v = violations(Tdpcr::from_ron_str(&outside, "o").unwrap_err());
    let fields: Vec<&str> = v.iter().map(|(f, _)| f.as_str()).collect();
    assert_eq!(fields, ["leg.tendons[1].offset", "leg.tendons[1]"]);
    let steps = TDCR.replace(
        "tendon_stiffness: 1000.0,",
        "tendon_stiffness: 1000.0, integration_steps: 0,",
    );
    assert_eq!(
        violations(Tdcr::from_ron_str(&steps, "s").unwrap_err())[0].0,
        "leg.integration_steps"
    );
}

/// Values beyond any continuum robot are refused with the bound in the message (a
/// modulus or a mass of 1e308 passed validation before and every solve then diverged);
/// the bounds themselves pass.
#[test]
fn implausible_magnitudes_are_refused_and_the_bounds_accepted() {
    let cases: &[(&str, &str, &str, &str)] = &[
        (
            "youngs_modulus: 54e9",
            "youngs_modulus: 1e308",
            "youngs_modulus: 1e13",
            "leg.youngs_modulus",
        ),
        (
            "youngs_modulus: 54e9",
            "youngs_modulus: 1e-3",
            "youngs_modulus: 1e3",
            "leg.youngs_modulus",
        ),
        (
            "tendon_stiffness: 1000.0",
            "tendon_stiffness: 1e20",
            "tendon_stiffness: 1e10",
            "leg.tendon_stiffness",
        ),
        (
            "tendon_stiffness: 1000.0",
            "tendon_stiffness: 1e-9",
            "tendon_stiffness: 1e-3",
            "leg.tendon_stiffness",
        ),
        (
            "backbone_mass: 0.0012",
            "backbone_mass: 1e308",
            "backbone_mass: 1e3",
            "leg.backbone_mass",
        ),
        (
            "Disks(count: 13, mass: 0.0003",
            "Disks(count: 13, mass: 2e3",
            "Disks(count: 13, mass: 1e3",
            "leg.disks.mass",
        ),
        (
            "platform: Platform(side_length: 0.13, mass: 0.0344)",
            "platform: Platform(side_length: 0.13, mass: 1e4)",
            "platform: Platform(side_length: 0.13, mass: 1e3)",
            "platform.mass",
        ),
        (
            "side_length: 0.13",
            "side_length: 11.0",
            "side_length: 10.0",
            "platform.side_length",
        ),
        (
            "coupling_offset: 0.0225",
            "coupling_offset: 1e9",
            "coupling_offset: 10.0",
            "coupling_offset",
        ),
        (
            "pretension: 0.0",
            "pretension: 1e7",
            "pretension: 1e6",
            "pretension",
        ),
        (
            "gravity: (0.0, 0.0, -9.81)",
            "gravity: (0.0, 0.0, -1e5)",
            "gravity: (0.0, 0.0, -1e3)",
            "gravity.2",
        ),
        (
            "tendon_displacement: 0.01",
            "tendon_displacement: 1e6",
            "tendon_displacement: 10.0",
            "actuation_limits.tendon_displacement",
        ),
        (
            "base_translation: 0.1",
            "base_translation: 20.0",
            "base_translation: 10.0",
            "actuation_limits.base_translation",
        ),
    ];
    for (from, to, bound, field) in cases {
        assert!(TDPCR.contains(from), "fixture lacks {from}");
        let err = Tdpcr::from_ron_str(&TDPCR.replacen(from, to, 1), "case").unwrap_err();
        let text = err.to_string();
        let v = violations(err);
        assert_eq!(v.len(), 1, "{to}: {v:?}");
        assert_eq!(v[0].0, *field);
        assert!(text.contains("expected"), "{text}");
        Tdpcr::from_ron_str(&TDPCR.replacen(from, bound, 1), "bound")
            .unwrap_or_else(|e| panic!("{bound}: {e}"));
    }
}

#[test]
fn parallel_design_rules_are_enforced() {
    let cases: &[(&str, &str, &str)] = &[
        ("alpha: 0.5235987755982988", "alpha: 1.7", "alpha"),
        (
            "side_length: 0.13",
            "side_length: 0.0",
            "platform.side_length",
        ),
        (
            "coupling_offset: 0.0225",
            "coupling_offset: -0.01",
            "coupling_offset",
        ),
        ("pretension: 0.0", "pretension: -1.0", "pretension"),
        (
            "tendon_displacement: 0.01",
            "tendon_displacement: 0.0",
            "actuation_limits.tendon_displacement",
        ),
        (
            "Tendon(angle: 3.141592653589793, offset: 0.005",
            "Tendon(angle: 3.0, offset: 0.005",
            "leg.tendons[1].angle",
        ),
        // Coincident joints: the platform turned freely about them (every solve ran to
        // its iteration limit); nearly coincident ones likewise.
        (
            "coupling_angles: (1.5707963267948966, 3.6651914291880923, 5.759586531581287)",
            "coupling_angles: (1.0, 1.0, 1.0)",
            "coupling_angles",
        ),
        (
            "coupling_angles: (1.5707963267948966, 3.6651914291880923, 5.759586531581287)",
            "coupling_angles: (0.0, 0.1, 0.2)",
            "coupling_angles",
        ),
    ];
    for (from, to, field) in cases {
        assert!(TDPCR.contains(from), "fixture lacks {from}");
        let v = violations(Tdpcr::from_ron_str(&TDPCR.replacen(from, to, 1), "case").unwrap_err());
        assert_eq!(v.len(), 1, "{to}: {v:?}");
        assert_eq!(v[0].0, *field);
    }
    let three = TDPCR.replace(
        "            Tendon(angle: 3.141592653589793, offset: 0.005, end: 0.145),\n",
        "            Tendon(angle: 3.141592653589793, offset: 0.005, end: 0.145),\n            Tendon(angle: 1.0, offset: 0.005, end: 0.145),\n",
    );
    assert_eq!(
        violations(Tdpcr::from_ron_str(&three, "t").unwrap_err())[0].0,
        "leg.tendons"
    );
}

#[test]
fn malformed_files_report_file_line_and_column() {
    let broken = TDCR.replace("poisson_ratio: 0.3,", "poisson_ratio: 0.3,,");
    let err = Tdcr::from_ron_str(&broken, "broken.ron").unwrap_err();
    match &err {
        DesignError::Parse { line, column, .. } => {
            let expected_line = broken.lines().position(|l| l.contains("0.3,,")).unwrap() + 1;
            assert_eq!(*line, expected_line);
            assert!(*column > 1);
        }
        e => panic!("expected a parse error, got {e}"),
    }
    assert!(err.to_string().starts_with("broken.ron:"), "{err}");
}

#[test]
fn unknown_fields_missing_fields_and_wrong_kinds_are_rejected() {
    let unknown = TDCR.replace("poisson_ratio: 0.3,", "poisson_ratio: 0.3, colour: 1.0,");
    let msg = Tdcr::from_ron_str(&unknown, "u.ron")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("colour"), "{msg}");
    let missing = TDCR.replace("        poisson_ratio: 0.3,\n", "");
    let msg = Tdcr::from_ron_str(&missing, "m.ron")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("poisson_ratio"), "{msg}");
    // A parallel design is not a single TDCR, and vice versa.
    assert!(Tdcr::from_ron_str(TDPCR, "p.ron").is_err());
    assert!(Tdpcr::from_ron_str(TDCR, "t.ron").is_err());
    for garbage in ["", "Tdcr(", "\u{0}\u{1}", "[1, 2, 3]", "Tdcr(gravity: 1)"] {
        assert!(Tdcr::from_ron_str(garbage, "g.ron").is_err());
    }
    let missing_file = Tdcr::from_ron_file("/nonexistent/robot.ron").unwrap_err();
    assert!(missing_file.to_string().contains("/nonexistent/robot.ron"));
}

/// A design file is read up to 16 MiB: `/dev/zero` (endless) is an error, not all the
/// memory there is.
#[cfg(unix)]
#[test]
fn an_endless_file_is_refused() {
    let e = Tdpcr::from_ron_file("/dev/zero").unwrap_err().to_string();
    assert!(
        e.contains("/dev/zero") && e.contains("not a design file"),
        "{e}"
    );
}
