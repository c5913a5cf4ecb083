//! One tendon-driven continuum robot alone (MODEL.md §8): base fixed at the world origin,
//! tip loaded by a wrench, tendons tension- or displacement-controlled.
//!
//! Unknowns, in order: γ_k for each tendon (displacement control only), u(0) (3), v(0) (3).
//! Residual rows, in order: tip force n(L) − Σ f_t,k − F (3, N), tip moment
//! m(L) − Σ l_t,k − M (3, N·m), then per tendon the length constraint (eq. 15, m,
//! displacement control only): s_k(end_k) + Θ_k − (1 + τ_k/(EA)_t)·end_k − Δℓ_k.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use crate::design::MAX_LEG_LENGTH;
use crate::design::{MAX_TENDONS, Tdcr};
use crate::error::{Error, MAX_FRAME_DRIFT, SolveError, Violations, frame_drift};
use crate::input_range::{diverged_if_non_finite, tdcr_inputs};
use crate::newton::{
    self, NewtonReport, NewtonScratch, NewtonSettings, NonlinearSystem, RowScales,
};
use crate::rod::tendon::{slack, slack_derivative, tension, tension_derivative};
use crate::rod::{
    Frame, LegEnd, LegModel, LegScratch, LegSensitivities, LegShape, LegStart, integrate_leg,
    integrate_leg_with_sensitivities,
};

pub use crate::rod::cold_guess::{TdcrState, TendonControl, cold_guess, cold_guess_at};

/// External wrench at the tip, world frame.
pub type TipWrench = crate::rod::Wrench;

/// A converged solve.
#[derive(Debug, Clone, PartialEq)]
pub struct TdcrSolution {
    /// Tip frame.
    pub tip: Frame,
    /// Tension of each tendon \[N\].
    pub tensions: Vec<f64>,
    /// Slack Θ_k of each tendon \[m\] (0 when taut; always 0 in tension control).
    pub slacks: Vec<f64>,
    /// The solved unknowns.
    pub state: TdcrState,
    /// Newton iterations and residual.
    pub report: NewtonReport,
    /// ‖F‖₂ in test units ([`NewtonSettings::tolerance`]) after each iteration, starting
    /// with the initial guess.
    pub residual_history: Vec<f64>,
    /// Frames at the base and every disk.
    pub shape: LegShape,
}

/// Solves single-TDCR problems; holds every buffer, so repeated solves do not allocate
/// inside the Newton loop.
#[derive(Debug, Clone)]
pub struct TdcrSolver {
    model: LegModel,
    leg: LegScratch,
    sens: LegSensitivities,
    newton: [NewtonScratch; 2],
    /// Newton settings (tolerance on the residual norm in test units, iteration limit).
    pub settings: NewtonSettings,
}

impl TdcrSolver {
    /// A solver for a validated robot.
    pub fn new(robot: &Tdcr) -> Self {
        let (gx, gy, gz) = robot.gravity;
        let model = LegModel::new(&robot.leg, Vector3::new(gx, gy, gz));
        let settings = NewtonSettings::default();
        let nt = model.n_tendons;
        Self {
            leg: LegScratch::new(),
            sens: LegSensitivities::new(6 + nt),
            newton: [
                NewtonScratch::new(6, settings.max_iterations),
                NewtonScratch::new(6 + nt, settings.max_iterations),
            ],
            model,
            settings,
        }
    }

    /// The leg model.
    pub fn model(&self) -> &LegModel {
        &self.model
    }

    /// Checks the control values: count, finiteness, non-negative tensions, displacements
    /// within ±[`MAX_LEG_LENGTH`].
    fn check_control(&self, control: &TendonControl, wrench: &TipWrench) -> Result<(), Error> {
        let mut v = Violations::default();
        let nt = self.model.n_tendons;
        let (name, values, unit) = match control {
            TendonControl::Tension(t) => ("tensions", t, "N"),
            TendonControl::Displacement(d) => ("displacements", d, "m"),
        };
        let displacement = matches!(control, TendonControl::Displacement(_));
        if displacement && nt == 0 {
            v.push("displacements", "given", "a robot with at least one tendon");
        } else if values.len() != nt {
            v.push(
                name,
                crate::error::counted(values.len(), "value"),
                &format!("{nt} values, one per tendon"),
            );
        }
        for (k, &x) in values.iter().enumerate() {
            let negative_tension = !displacement && x < 0.0;
            // A displacement beyond any rod's length: a slack of 1e308 m "converged" and
            // printed as `inf mm`.
            let too_long = displacement && x.abs() > MAX_LEG_LENGTH;
            if !x.is_finite() || negative_tension || too_long {
                let rule = if negative_tension {
                    format!(">= 0 {unit}")
                } else if too_long {
                    format!("within ±{MAX_LEG_LENGTH} m (the longest rod a design takes)")
                } else {
                    format!("finite [{unit}]")
                };
                v.push(format!("{name}[{k}]"), x, &rule);
            }
        }
        push_non_finite(&mut v, "tip_force", wrench.force.as_slice());
        push_non_finite(&mut v, "tip_moment", wrench.moment.as_slice());
        if v.0.is_empty() {
            Ok(())
        } else {
            Err(Error::Input(v))
        }
    }

    /// Solves for the equilibrium under `control` and the tip `wrench`, starting from
    /// `init` if given (and of the right mode), else from the cold guess of MODEL.md §9.
    ///
    /// # Errors
    /// [`Error::Input`] for bad control values or a non-finite value in `init` (named
    /// `init.u0[i]`, `init.v0[i]`, `init.gammas[k]`); [`Error::Solve`] if Newton fails,
    /// with the residual norm and iteration count, or if the solution's integration does
    /// not resolve the leg ([`SolveError::UnderResolved`]: a tip frame off a rotation).
    pub fn solve(
        &mut self,
        control: &TendonControl,
        wrench: &TipWrench,
        init: Option<&TdcrState>,
    ) -> Result<TdcrSolution, Error> {
        self.check_control(control, wrench)?;
        if let Some(s) = init {
            check_init(s)?;
        }
        let nt = self.model.n_tendons;
        let displacement = matches!(control, TendonControl::Displacement(_));
        let n_gamma = if displacement { nt } else { 0 };
        let mut x = match init {
            Some(s) if s.gammas.len() == n_gamma => pack(s),
            _ => pack(&cold_guess(&self.model, control, wrench)),
        };
        let scratch = &mut self.newton[usize::from(displacement)];
        let mut system =
            TdcrSystem::new(&self.model, &mut self.leg, &mut self.sens, control, wrench);
        let report = newton::solve(&mut system, &mut x, &self.settings, scratch)
            .map_err(|e| diverged_if_non_finite(e, || tdcr_inputs(&self.model, control, wrench)))?;
        let state = unpack(&x, n_gamma);
        let tensions: Vec<f64> = match control {
            TendonControl::Tension(t) => t.clone(),
            TendonControl::Displacement(_) => state.gammas.iter().map(|&g| tension(g)).collect(),
        };
        let slacks = (0..nt)
            .map(|k| state.gammas.get(k).map_or(0.0, |&g| slack(g)))
            .collect();
        let mut shape = LegShape::new(&self.model);
        let mut end = LegEnd::zeros();
        integrate_leg(
            &self.model,
            &leg_start(&state, &tensions),
            &mut self.leg,
            &mut end,
            Some(&mut shape),
        )?;
        let drift = frame_drift(&end.r);
        if drift.is_nan() || drift > MAX_FRAME_DRIFT {
            let steps = self.model.intervals.iter().map(|iv| iv.steps).sum();
            return Err(Error::Solve(SolveError::UnderResolved { drift, steps }));
        }
        Ok(TdcrSolution {
            tip: Frame {
                position: end.p,
                rotation: end.r,
            },
            tensions,
            slacks,
            state,
            report,
            residual_history: scratch.residual_history().to_vec(),
            shape,
        })
    }

    /// The residual and its exact Jacobian at `state` (for tests and diagnostics).
    ///
    /// # Errors
    /// As [`TdcrSolver::solve`], for bad input or a non-finite integration.
    pub fn residual_and_jacobian(
        &mut self,
        control: &TendonControl,
        wrench: &TipWrench,
        state: &TdcrState,
    ) -> Result<(DVector<f64>, DMatrix<f64>), Error> {
        self.check_control(control, wrench)?;
        let x = pack(state);
        let n = x.len();
        let mut r = DVector::zeros(n);
        let mut j = DMatrix::zeros(n, n);
        let mut system =
            TdcrSystem::new(&self.model, &mut self.leg, &mut self.sens, control, wrench);
        system.residual_and_jacobian(&x, &mut r, &mut j)?;
        Ok((r, j))
    }

    /// The residual alone at `state`.
    ///
    /// # Errors
    /// As [`TdcrSolver::residual_and_jacobian`].
    pub fn residual(
        &mut self,
        control: &TendonControl,
        wrench: &TipWrench,
        state: &TdcrState,
    ) -> Result<DVector<f64>, Error> {
        self.check_control(control, wrench)?;
        let x = pack(state);
        let mut r = DVector::zeros(x.len());
        let mut system =
            TdcrSystem::new(&self.model, &mut self.leg, &mut self.sens, control, wrench);
        system.residual(&x, &mut r)?;
        Ok(r)
    }
}

/// Each non-finite entry of `values` as the violation `name[i]`.
fn push_non_finite(v: &mut Violations, name: &str, values: &[f64]) {
    for (i, x) in values.iter().enumerate() {
        if !x.is_finite() {
            v.push(format!("{name}[{i}]"), x, "a finite number");
        }
    }
}

/// Every value of a warm start finite (a NaN ran Newton from a NaN guess).
fn check_init(s: &TdcrState) -> Result<(), Error> {
    let mut v = Violations::default();
    push_non_finite(&mut v, "init.u0", &s.u0);
    push_non_finite(&mut v, "init.v0", &s.v0);
    push_non_finite(&mut v, "init.gammas", &s.gammas);
    if v.0.is_empty() {
        Ok(())
    } else {
        Err(Error::Input(v))
    }
}

fn pack(s: &TdcrState) -> DVector<f64> {
    DVector::from_iterator(
        s.gammas.len() + 6,
        s.gammas
            .iter()
            .chain(s.u0.iter())
            .chain(s.v0.iter())
            .copied(),
    )
}

fn unpack(x: &DVector<f64>, n_gamma: usize) -> TdcrState {
    let o = n_gamma;
    TdcrState {
        u0: [x[o], x[o + 1], x[o + 2]],
        v0: [x[o + 3], x[o + 4], x[o + 5]],
        gammas: x.rows(0, n_gamma).iter().copied().collect(),
    }
}

fn leg_start(state: &TdcrState, tensions: &[f64]) -> LegStart {
    let mut t = [0.0; MAX_TENDONS];
    t[..tensions.len()].copy_from_slice(tensions);
    LegStart {
        base: Frame::identity(),
        u0: Vector3::from(state.u0),
        v0: Vector3::from(state.v0),
        tensions: t,
    }
}

/// The shooting residual of one TDCR as a [`NonlinearSystem`].
struct TdcrSystem<'a> {
    model: &'a LegModel,
    leg: &'a mut LegScratch,
    sens: &'a mut LegSensitivities,
    control: &'a TendonControl,
    wrench: &'a TipWrench,
    end: LegEnd,
}

impl<'a> TdcrSystem<'a> {
    fn new(
        model: &'a LegModel,
        leg: &'a mut LegScratch,
        sens: &'a mut LegSensitivities,
        control: &'a TendonControl,
        wrench: &'a TipWrench,
    ) -> Self {
        Self {
            model,
            leg,
            sens,
            control,
            wrench,
            end: LegEnd::zeros(),
        }
    }

    fn n_gamma(&self) -> usize {
        match self.control {
            TendonControl::Tension(_) => 0,
            TendonControl::Displacement(_) => self.model.n_tendons,
        }
    }

    /// Leg start for unknowns x.
    fn start(&self, x: &DVector<f64>) -> LegStart {
        let ng = self.n_gamma();
        let mut tensions = [0.0; MAX_TENDONS];
        match self.control {
            TendonControl::Tension(t) => tensions[..t.len()].copy_from_slice(t),
            TendonControl::Displacement(_) => {
                for k in 0..ng {
                    tensions[k] = tension(x[k]);
                }
            }
        }
        LegStart {
            base: Frame::identity(),
            u0: Vector3::new(x[ng], x[ng + 1], x[ng + 2]),
            v0: Vector3::new(x[ng + 3], x[ng + 4], x[ng + 5]),
            tensions,
        }
    }

    fn fill_residual(&self, x: &DVector<f64>, r: &mut DVector<f64>) {
        let e = &self.end;
        let f = e.n - self.wrench.force;
        let m = e.m - self.wrench.moment;
        for i in 0..3 {
            r[i] = f[i];
            r[3 + i] = m[i];
        }
        if let TendonControl::Displacement(d) = self.control {
            for k in 0..self.model.n_tendons {
                let g = x[k];
                let end_k = self.model.tendon_ends[k];
                r[6 + k] = e.lengths[k] + slack(g)
                    - (1.0 + tension(g) / self.model.tendon_stiffness) * end_k
                    - d[k];
            }
        }
    }
}

impl NonlinearSystem for TdcrSystem<'_> {
    fn dim(&self) -> usize {
        6 + self.n_gamma()
    }

    fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
        let start = self.start(x);
        integrate_leg(self.model, &start, self.leg, &mut self.end, None)?;
        self.fill_residual(x, r);
        Ok(())
    }

    fn residual_and_jacobian(
        &mut self,
        x: &DVector<f64>,
        r: &mut DVector<f64>,
        jac: &mut DMatrix<f64>,
    ) -> Result<(), SolveError> {
        let start = self.start(x);
        integrate_leg_with_sensitivities(
            self.model,
            &start,
            self.leg,
            &mut self.end,
            self.sens,
            None,
        )?;
        self.fill_residual(x, r);
        let ng = self.n_gamma();
        let rows = 6 + ng;
        // Column of one leg direction, scaled by `scale`.
        let mut put = |col: usize, d: &LegEnd, scale: f64| {
            for i in 0..3 {
                jac[(i, col)] = d.n[i] * scale;
                jac[(3 + i, col)] = d.m[i] * scale;
            }
            for k in 0..rows - 6 {
                jac[(6 + k, col)] = d.lengths[k] * scale;
            }
        };
        for j in 0..6 {
            put(ng + j, &self.sens.d[j], 1.0);
        }
        for k in 0..ng {
            put(k, &self.sens.d[6 + k], tension_derivative(x[k]));
        }
        for k in 0..ng {
            let end_k = self.model.tendon_ends[k];
            jac[(6 + k, k)] += slack_derivative(x[k])
                - end_k / self.model.tendon_stiffness * tension_derivative(x[k]);
        }
        Ok(())
    }

    fn row_weights(&self, w: &mut DVector<f64>) {
        let len = self.model.length;
        let ei = self.model.bending_stiffness();
        let force = len * len / ei;
        let moment = len / ei;
        let offset = self.model.max_offset();
        let length = 1.0 / if offset > 0.0 { offset } else { len };
        for i in 0..3 {
            w[i] = force;
            w[3 + i] = moment;
        }
        for i in 6..w.len() {
            w[i] = length;
        }
    }

    fn row_scales(&self, c: &mut DVector<f64>) {
        let m = self.model;
        let s = RowScales::of_rod(m.length, m.bending_stiffness(), m.axial_stiffness())
            .relative_to_si_test();
        for i in 0..3 {
            c[i] = s.force;
            c[3 + i] = s.moment;
        }
        for i in 6..c.len() {
            c[i] = s.length;
        }
    }
}

/// Rotation matrix as nested rows (for JSON).
pub fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}
