//! The real design evaluation (coarse workspace sweeps) on the reference design and on
//! designs that cannot be scored.

use std::path::Path;

use tdpcr::Tdpcr;
use tdpcr_optim::config::EvaluationConfig;
use tdpcr_optim::evaluate::{Evaluator, evaluate_point};
use tdpcr_optim::objectives::{Infeasibility, Outcome};
use tdpcr_optim::space::{Bounds, DesignParameter, ParameterSpace};
use tdpcr_optim::workspace_eval::WorkspaceEvaluator;

fn reference() -> Tdpcr {
    Tdpcr::from_ron_file(Path::new(env!("CARGO_MANIFEST_DIR")).join("../designs/lilge2022.ron"))
        .unwrap()
}

fn coarse(orientations: Vec<(f64, f64, f64)>) -> EvaluationConfig {
    EvaluationConfig {
        step: 0.02,
        angle_step: 0.8,
        z_range: (-0.06, 0.06),
        orientations,
        max_iterations: 20,
        tolerance: 1e-8,
        chord_contraction: 0.1,
        probe_iterations: 15,
    }
}

#[test]
fn the_reference_design_is_feasible_with_consistent_measures() {
    let e = WorkspaceEvaluator::new(&coarse(vec![(0.0, 0.0, 0.0)]));
    let Outcome::Feasible(m) = e.evaluate(&reference()) else {
        panic!("reference infeasible");
    };
    let cell = 0.02f64.powi(3);
    assert!(m.reachable_cells > 10, "{m:?}");
    assert_eq!(m.volume_reachable, m.reachable_cells as f64 * cell);
    assert_eq!(m.volume_non_singular, m.non_singular_cells as f64 * cell);
    assert_eq!(
        m.singularity_margin,
        m.non_singular_cells as f64 / m.reachable_cells as f64
    );
    assert!(m.singularity_margin > 0.5 && m.singularity_margin <= 1.0);
    for r in [m.rcond_j_p, m.rcond_j_o, m.rcond_c_p, m.rcond_c_o] {
        assert!(r.mean > 0.05 && r.mean <= 1.0 && r.min <= r.mean, "{r:?}");
    }
    assert!(m.min_tension >= 0.0 && m.min_scaled_rcond_b_xu >= 0.0);
    assert!(m.non_finite().is_none());
    // Deterministic.
    assert_eq!(e.evaluate(&reference()), Outcome::Feasible(m.clone()));

    // Two orientations: volumes are the mean, cells the sum.
    let two = WorkspaceEvaluator::new(&coarse(vec![(0.0, 0.0, 0.0), (0.0, 0.0, 0.0)]));
    let Outcome::Feasible(m2) = two.evaluate(&reference()) else {
        panic!("reference infeasible");
    };
    assert_eq!(m2.volume_non_singular, m.volume_non_singular);
    assert_eq!(m2.reachable_cells, 2 * m.reachable_cells);
    assert!((m2.rcond_j_p.mean - m.rcond_j_p.mean).abs() < 1e-12);
    assert_eq!(m2.rcond_j_p.min, m.rcond_j_p.min);
}

#[test]
fn designs_that_cannot_be_scored_are_infeasible_with_a_reason_not_a_panic() {
    let e = WorkspaceEvaluator::new(&coarse(vec![(0.0, 0.0, 0.0)]));
    // Disks of 6 cm: the legs' disks overlap at home.
    let mut fat = reference();
    fat.leg.disks.radius = 0.06;
    match e.evaluate(&fat) {
        Outcome::Infeasible {
            reason: Infeasibility::InvalidHome { message },
        } => assert!(message.contains("collides"), "{message}"),
        other => panic!("{other:?}"),
    }
    // A parameter combination that breaks a design rule never reaches the evaluator.
    let space = ParameterSpace::new(
        reference(),
        vec![
            Bounds {
                parameter: DesignParameter::TendonOffset,
                min: 0.004,
                max: 0.008,
            },
            Bounds {
                parameter: DesignParameter::DiskRadius,
                min: 0.005,
                max: 0.007,
            },
        ],
    );
    let (outcome, _) = evaluate_point(&space, &e, &[1.0, 0.0]);
    match outcome {
        Outcome::Infeasible {
            reason: Infeasibility::InvalidDesign { message },
        } => assert!(
            message.contains("leg.tendons[0].offset = 0.008"),
            "{message}"
        ),
        other => panic!("{other:?}"),
    }
    // Legs a thousand times softer cannot hold the platform at home within the limits
    // (or the home solve fails): a reason, never a crash.
    let mut soft = reference();
    soft.leg.youngs_modulus = 54e6;
    match e.evaluate(&soft) {
        Outcome::Infeasible { reason } => {
            assert!(matches!(
                reason,
                Infeasibility::InvalidHome { .. } | Infeasibility::HomeNotSolved { .. }
            ));
        }
        Outcome::Feasible(m) => panic!("soft legs feasible: {m:?}"),
    }
}
