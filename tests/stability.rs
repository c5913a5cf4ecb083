//! Stability with the actuators held (MODEL.md §4b): the platform stiffness from the
//! boundary blocks inverts the compliance; a known unstable equilibrium is flagged; and a
//! perturbed equilibrium, relaxed with the actuators held, grows or decays at the rate the
//! stiffness predicts.

mod common;

use common::design_path;
use nalgebra::{DVector, Matrix6, Rotation3, Vector3, Vector6};
use tdpcr::Tdpcr;
use tdpcr::analysis::stability::platform_stiffness;
use tdpcr::analysis::{AnalysisSettings, UnitScaling};
use tdpcr::kinetostatics::{RobotState, Solver};
use tdpcr::model::Pose;
use tdpcr::rod::Wrench;

/// A solver with the default settings: the cold IK of the twist below lands on the
/// unstable equilibrium with them (as `tdpcr ik` does), and on a stable one of the same
/// pose with a tolerance of 1e-11 (the continuation takes another path).
fn solver(file: &str) -> Solver {
    Solver::new(&Tdpcr::from_ron_file(design_path(file)).unwrap()).unwrap()
}

/// Cold IK at the origin with orientation `rotvec` \[rad\].
fn solve_at(s: &mut Solver, rotvec: [f64; 3]) -> RobotState {
    let pose = Pose {
        position: Vector3::zeros(),
        rotation: Rotation3::from_scaled_axis(Vector3::from(rotvec)).into_inner(),
    };
    s.solve_ik(&pose, &Wrench::default(), None).unwrap().state
}

/// The −45° twist about z of paper Fig. 8 (bottom left).
const TWIST: [f64; 3] = [0.0, 0.0, -std::f64::consts::FRAC_PI_4];

#[test]
fn the_twist_of_fig_8_is_unstable_when_legs_bend_horizontally_and_stable_when_vertically() {
    let settings = AnalysisSettings::default();
    for (file, expect_stable) in [("lilge2022_psi0.ron", false), ("lilge2022.ron", true)] {
        let mut s = solver(file);
        let home = solve_at(&mut s, [0.0; 3]);
        let a = s.analyze(&home, &Wrench::default(), &settings).unwrap();
        assert!(a.stability.stable, "{file}: home {:?}", a.stability);
        let twist = solve_at(&mut s, TWIST);
        let a = s.analyze(&twist, &Wrench::default(), &settings).unwrap();
        let st = a.stability;
        assert_eq!(st.stable, expect_stable, "{file}: twist {st:?}");
        // The flag is the sign of the smallest eigenvalue, and the model is conservative:
        // sym(C) is all of C up to the discretization.
        assert_eq!(st.eigenvalues[0] > 0.0, st.stable, "{st:?}");
        assert!(
            st.asymmetry < 1e-4,
            "{file}: asymmetry {:.1e}",
            st.asymmetry
        );
        if !expect_stable {
            assert!(st.eigenvalues_c_p[0] < 0.0, "{st:?}");
        }
    }
}

/// The platform residual rows b\[0..6\] (Σn − f_ext, Σa × n − l_ext) with the actuators and
/// the platform pose held, after the legs are brought to equilibrium (their 3 × (6 + n_t)
/// rows solved by Newton on their own square blocks B_u,l).
fn held_platform_residual(s: &mut Solver, state: &mut RobotState) -> Vector6<f64> {
    let model = s.model().clone();
    let nu = model.n_leg_unknowns();
    for _ in 0..30 {
        let (r, b) = s.blocks_at(state, &Wrench::default()).unwrap();
        let leg_residual = r.rows(6, 3 * nu).amax();
        if leg_residual < 1e-12 {
            return Vector6::from_fn(|i, _| r[i]);
        }
        for leg in 0..3 {
            let (row, col) = (6 + leg * nu, leg * nu);
            let b_ul = b.b_u.view((row, col), (nu, nu)).into_owned();
            let rhs = -DVector::from_iterator(nu, r.rows(row, nu).iter().copied());
            let dy = b_ul
                .lu()
                .solve(&rhs)
                .expect("a leg's block is regular here");
            for (k, d) in dy.iter().enumerate() {
                state.y_u[col + k] += d;
            }
        }
    }
    panic!("the legs did not settle with the platform held");
}

/// Moves a state's platform by δx = \[δp; δθ\] (R ← exp(δθ^) R).
fn displaced(state: &RobotState, dx: &Vector6<f64>) -> RobotState {
    let pose = state.pose();
    let rotation = Rotation3::from_scaled_axis(dx.fixed_rows::<3>(3).into_owned())
        * Rotation3::from_matrix_unchecked(pose.rotation);
    RobotState {
        position: (pose.position + dx.fixed_rows::<3>(0)).into(),
        rotvec: rotation.scaled_axis().into(),
        ..state.clone()
    }
}

/// δx of `s` from `base`.
fn displacement(base: &RobotState, s: &RobotState) -> Vector6<f64> {
    let (p0, p) = (base.pose(), s.pose());
    let dtheta =
        Rotation3::from_matrix_unchecked(p.rotation * p0.rotation.transpose()).scaled_axis();
    let mut v = Vector6::zeros();
    v.fixed_rows_mut::<3>(0)
        .copy_from(&(p.position - p0.position));
    v.fixed_rows_mut::<3>(3).copy_from(&dtheta);
    v
}

/// D = diag(√(L³/EI) I₃, √(L/EI) I₃): unit-scaled coordinates y = D⁻¹ δx.
fn scaling(s: &Solver) -> Vector6<f64> {
    let u = UnitScaling::new(s.model());
    let (dp, dr) = ((u.length / u.force).sqrt(), (1.0 / u.moment).sqrt());
    Vector6::new(dp, dp, dp, dr, dr, dr)
}

/// Relaxes the platform from a perturbation along the softest direction of the scaled
/// stiffness, with the actuators held: y ← y − h K_s y (an overdamped motion, in which
/// the net wrench on the platform drives it; h = 0.9/λ_max keeps the stiff directions
/// decaying, so the softest one shows after a few hundred steps); returns (measured, predicted) growth of |y|
/// after `steps` steps.
fn growth_along_softest_direction(file: &str, rotvec: [f64; 3], steps: i32) -> (f64, f64) {
    let mut s = solver(file);
    let eq = solve_at(&mut s, rotvec);
    let model = s.model().clone();
    let (_, blocks) = s.blocks_at(&eq, &Wrench::default()).unwrap();
    let k = platform_stiffness(&model, blocks).expect("legs regular");
    let d = scaling(&s);
    let ks: Matrix6<f64> = Matrix6::from_fn(|r, c| d[r] * k[(r, c)] * d[c]);
    let sym = (ks + ks.transpose()) * 0.5;
    let eig = sym.symmetric_eigen();
    let (imin, lmin) = eig.eigenvalues.argmin();
    let lmax = eig.eigenvalues.amax();
    let h = 0.9 / lmax;
    let y0: Vector6<f64> = eig.eigenvectors.column(imin) * 1e-5;
    let mut state = displaced(&eq, &y0.component_mul(&d));
    for _ in 0..steps {
        let r = held_platform_residual(&mut s, &mut state);
        // δx ← δx − h D² r_p: in y = D⁻¹δx, y ← y − h D r_p = y − h K_s y.
        let dx = -(r.component_mul(&d).component_mul(&d)) * h;
        state = displaced(&state, &dx);
    }
    let y = displacement(&eq, &state).component_div(&d);
    (y.norm() / y0.norm(), (1.0 - h * lmin).powi(steps))
}

#[test]
fn a_perturbed_unstable_equilibrium_grows_at_the_rate_the_stiffness_predicts() {
    let (measured, predicted) = growth_along_softest_direction("lilge2022_psi0.ron", TWIST, 600);
    println!("growth: measured {measured:.4}, predicted {predicted:.4}");
    assert!(predicted > 3.0, "predicted growth {predicted}");
    assert!(
        (measured / predicted - 1.0).abs() < 0.01,
        "measured {measured}, predicted {predicted}"
    );
}

#[test]
fn a_perturbed_stable_equilibrium_decays_at_the_rate_the_stiffness_predicts() {
    let (measured, predicted) = growth_along_softest_direction("lilge2022.ron", TWIST, 600);
    println!("decay: measured {measured:.4}, predicted {predicted:.4}");
    assert!(predicted < 0.7, "predicted decay {predicted}");
    assert!(
        (measured / predicted - 1.0).abs() < 0.01,
        "measured {measured}, predicted {predicted}"
    );
}

#[test]
fn the_platform_stiffness_inverts_the_compliance() {
    let mut s = solver("lilge2022_psi0.ron");
    let eq = solve_at(&mut s, [0.05, -0.1, 0.2]);
    let a = s
        .analyze(&eq, &Wrench::default(), &AnalysisSettings::default())
        .unwrap();
    let model = s.model().clone();
    let (_, blocks) = s.blocks_at(&eq, &Wrench::default()).unwrap();
    let k = platform_stiffness(&model, blocks).unwrap();
    let c = Matrix6::from_fn(|r, col| a.compliance[(r, col)]);
    let d = scaling(&s);
    // K C = I, compared in unit-scaled coordinates (D⁻¹ K D⁻¹... as D K D · D⁻¹ C D⁻¹).
    let ks = Matrix6::from_fn(|r, col| d[r] * k[(r, col)] * d[col]);
    let cs = Matrix6::from_fn(|r, col| c[(r, col)] / (d[r] * d[col]));
    let err = (ks * cs - Matrix6::identity()).amax();
    assert!(err < 1e-8, "|K C − I| = {err:.2e}");
}
