//! Kinetostatic analysis of a solved configuration (MODEL.md §4; paper Sec. IV–V):
//! Jacobians, compliance, singularity measures and flags, manipulability and compliance
//! ellipsoids, from the exact boundary blocks B_x, B_q, B_w, B_u.
//!
//! With δb = B_x δx + B_q δq + B_w δw + B_u δy_u = 0 (eq. 17):
//! - \[J_FK; Λ_FK\] = −\[B_x B_u\]⁻¹ B_q (eqs. 18–19): J_FK is 6 × n_q, rows δp \[m\] then
//!   δθ \[rad\] (world frame, R ← exp(δθ^) R), columns q \[m\].
//! - \[C; Λ_C\] = −\[B_x B_u\]⁻¹ B_w (eqs. 22–23): C = ∂x/∂w is 6 × 6, columns f_ext \[N\]
//!   then l_ext \[N·m\]; C_p = C\[0..3, 0..3\] \[m/N\], C_o = C\[3..6, 3..6\] \[rad/(N·m)\].
//! - J_IK (n_q × 6) and Λ_IK: for the 6-DoF design −\[B_q B_u\]⁻¹ B_x (eqs. 20–21). For
//!   the 9-DoF design \[B_q B_u\] is 36 × 39 and J_IK is the Moore–Penrose right inverse
//!   J_FK⁺ = J_FKᵀ (J_FK J_FKᵀ)⁻¹: of all actuation changes that produce δx it gives the
//!   one with the least ‖δq‖₂ \[m\] (the least-‖δq‖ solution of eq. 20), and
//!   Λ_IK = Λ_FK J_IK. The 6-DoF design falls back to the same J_FK⁺ (with singular
//!   values below n·ε·σ_max dropped) where \[B_q B_u\] is exactly singular (Type I).
//! - J_p = J_FK\[0..3, :\], J_o = J_FK\[3..6, :\] (3 × n_q); their ellipsoids are those of
//!   J Jᵀ (3 × 3): semi-axes are the singular values of J.
//!
//! Singular matrices are an expected outcome: rcond is then 0 (or tiny) and the flags
//! say which kind. Where \[B_x B_u\] is exactly singular (a zero pivot, or a solution that
//! overflows) J_FK, Λ_FK, C and Λ_C do not exist and the analysis returns
//! [`AnalysisError::Singular`] naming the matrix and its rcond; nothing is ever NaN.
//!
//! rcond: raw SI as in the paper (Type II when rcond(\[B_x B_u\]) < 3.5e-9), and
//! unit-scaled ([`scaling`]) for design scoring.
//!
//! The leg unknowns' γ columns are the paper's (τ = γ², Θ = γ² when slack): the blocks
//! must be evaluated with [`TendonUnknown::Gamma`](crate::rod::tendon::TendonUnknown), as
//! [`Solver::blocks_at`](crate::kinetostatics::Solver::blocks_at) does (and
//! [`Solver::analyze`](crate::kinetostatics::Solver::analyze) with it).

pub mod ellipsoid;
mod lanczos;
#[cfg(feature = "plots")]
pub mod plot;
mod qr;
pub mod rcond;
pub mod scaling;
pub mod stability;

use nalgebra::{DMatrix, Dim, Matrix, Matrix3, Matrix6, RawStorage, SMatrix};
use serde::Serialize;

use crate::boundary::BoundaryJacobians;
use crate::model::{MAX_ACTUATORS, Model};
use crate::rod::tendon::tension;
use lanczos::{Lanczos, Start};
use qr::{LegQr, Scales, WideBuffers, back_substitute, back_substitute_rows};

pub use crate::error::AnalysisError;
pub use ellipsoid::Ellipsoid;
pub use scaling::UnitScaling;
pub use stability::Stability;

/// Thresholds of the singularity flags, on raw SI rcond values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AnalysisSettings {
    /// Type I (loss of actuation authority) when rcond(\[B_q B_u\]) is below this.
    pub type_i_threshold: f64,
    /// Type II (uncontrolled platform motion) when rcond(\[B_x B_u\]) is below this
    /// (paper Sec. V-B: ε_s = 3.5e-9).
    pub type_ii_threshold: f64,
    /// Leg singularity when rcond(B_u) is below this. Independently of it, a leg is also
    /// flagged when both tendons of one of its antagonistic pairs carry no tension
    /// (γ ≤ 0 for both): the pair's actuator then moves nothing but slack, whatever the
    /// conditioning of B_u (paper Sec. V-D).
    pub leg_threshold: f64,
}

impl Default for AnalysisSettings {
    /// The paper's ε_s = 3.5e-9 for Type II. The same value for Type I and legs: the
    /// three matrices share B_u and its scale (on the reference design at home their raw
    /// rcond is 1.0e-8, 3.2e-8 and 3.2e-8), and rcond(B_u) falls below it when the last
    /// taut tendon of a pair carries less than about 10 mN.
    fn default() -> Self {
        Self {
            type_i_threshold: 3.5e-9,
            type_ii_threshold: 3.5e-9,
            leg_threshold: 3.5e-9,
        }
    }
}

/// Reciprocal condition numbers σ_min/σ_max of the analysis' matrices.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Rconds {
    /// \[B_x B_u\] (Type II measure).
    pub b_xu: f64,
    /// \[B_q B_u\] (Type I measure).
    pub b_qu: f64,
    /// B_u (leg-singularity measure).
    pub b_u: f64,
    /// J_p (isotropy of the position manipulability ellipsoid).
    pub j_p: f64,
    /// J_o (isotropy of the orientation manipulability ellipsoid).
    pub j_o: f64,
    /// C_p (isotropy of the position compliance ellipsoid).
    pub c_p: f64,
    /// C_o (isotropy of the orientation compliance ellipsoid).
    pub c_o: f64,
}

impl Rconds {
    /// Every rcond 0 (the measures of an exactly singular \[B_x B_u\]).
    pub const ZERO: Self = Self {
        b_xu: 0.0,
        b_qu: 0.0,
        b_u: 0.0,
        j_p: 0.0,
        j_o: 0.0,
        c_p: 0.0,
        c_o: 0.0,
    };
}

/// Which singularities the configuration is at or near.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Singularity {
    /// rcond(\[B_q B_u\]) below [`AnalysisSettings::type_i_threshold`].
    pub type_i: bool,
    /// rcond(\[B_x B_u\]) below [`AnalysisSettings::type_ii_threshold`].
    pub type_ii: bool,
    /// rcond(B_u) below [`AnalysisSettings::leg_threshold`], or a tendon pair with both
    /// tendons slack.
    pub leg: bool,
}

/// The four ellipsoids of paper Fig. 8 (raw SI).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ellipsoids {
    /// Position manipulability, from J_p \[m/m\].
    pub j_p: Ellipsoid,
    /// Orientation manipulability, from J_o \[rad/m\].
    pub j_o: Ellipsoid,
    /// Position compliance, from C_p \[m/N\].
    pub c_p: Ellipsoid,
    /// Orientation compliance, from C_o \[rad/(N·m)\].
    pub c_o: Ellipsoid,
}

/// Everything the linearization says about one configuration (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Analysis {
    /// J_FK = ∂x/∂q (6 × n_q): rows δp \[m\], δθ \[rad\]; columns q \[m\].
    pub j_fk: DMatrix<f64>,
    /// Λ_FK = ∂y_u/∂q (3 (6 + n_t) × n_q).
    pub lambda_fk: DMatrix<f64>,
    /// J_IK = ∂q/∂x (n_q × 6); the least-‖δq‖ right inverse of J_FK for the 9-DoF design.
    pub j_ik: DMatrix<f64>,
    /// Λ_IK = ∂y_u/∂x (3 (6 + n_t) × 6).
    pub lambda_ik: DMatrix<f64>,
    /// Compliance C = ∂x/∂w (6 × 6): columns f_ext \[N\], l_ext \[N·m\].
    pub compliance: DMatrix<f64>,
    /// Λ_C = ∂y_u/∂w (3 (6 + n_t) × 6).
    pub lambda_c: DMatrix<f64>,
    /// rcond of the raw SI matrices (as in the paper).
    pub rcond: Rconds,
    /// rcond of the unit-scaled matrices ([`UnitScaling`]); C_p and C_o scale uniformly,
    /// so their values equal the raw ones.
    pub rcond_scaled: Rconds,
    /// Singularity flags from the raw rcond values and the tendon states.
    pub singularity: Singularity,
    /// Manipulability and compliance ellipsoids (raw SI).
    pub ellipsoids: Ellipsoids,
    /// Smallest tendon tension over all tendons of all legs \[N\] (0 if any is slack).
    pub min_tension: f64,
    /// Stability with the actuators held, from the signs of sym(C) ([`stability`]).
    pub stability: Stability,
}

impl Analysis {
    /// Position Jacobian J_p = rows 0..3 of J_FK (3 × n_q) \[m/m\].
    pub fn j_p(&self) -> DMatrix<f64> {
        self.j_fk.rows(0, 3).into_owned()
    }

    /// Orientation Jacobian J_o = rows 3..6 of J_FK (3 × n_q) \[rad/m\].
    pub fn j_o(&self) -> DMatrix<f64> {
        self.j_fk.rows(3, 3).into_owned()
    }

    /// Position compliance C_p = C\[0..3, 0..3\] \[m/N\].
    pub fn c_p(&self) -> Matrix3<f64> {
        self.compliance.fixed_view::<3, 3>(0, 0).into_owned()
    }

    /// Orientation compliance C_o = C\[3..6, 3..6\] \[rad/(N·m)\].
    pub fn c_o(&self) -> Matrix3<f64> {
        self.compliance.fixed_view::<3, 3>(3, 3).into_owned()
    }
}

/// What the workspace sweep keeps of an analysis ([`condition_blocks`]): every rcond,
/// the flags, the minimum tension and the stability, without J_IK, the Λ matrices and
/// the ellipsoids' axes. Each field equals, bit for bit, the field of the same name of
/// the [`Analysis`] of the same blocks.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Conditioning {
    /// rcond of the raw SI matrices (as in the paper).
    pub rcond: Rconds,
    /// rcond of the unit-scaled matrices ([`UnitScaling`]).
    pub rcond_scaled: Rconds,
    /// Singularity flags from the raw rcond values and the tendon states.
    pub singularity: Singularity,
    /// Smallest tendon tension over all tendons of all legs \[N\] (0 if any is slack).
    pub min_tension: f64,
    /// Stability with the actuators held, from the signs of sym(C) ([`stability`]).
    pub stability: Stability,
}

/// Analyses a configuration from its exact blocks (evaluated with γ tendon unknowns at
/// `y_u`), without any leg integration. `y_u` gives the tendon states (tensions, slack
/// pairs).
///
/// # Errors
/// [`AnalysisError::Shape`] if the blocks or `y_u` do not fit `model`;
/// [`AnalysisError::NonFinite`] for NaN or infinite inputs; [`AnalysisError::Singular`]
/// if \[B_x B_u\] is exactly singular.
pub fn analyze_blocks(
    model: &Model,
    blocks: &BoundaryJacobians,
    y_u: &[f64],
    settings: &AnalysisSettings,
) -> Result<Analysis, AnalysisError> {
    // [B_u B_x] [δy; δx] = −[B_q B_w] [δq; δw]; with Qᵀ applied, R_x Z = Qᵀ [B_q B_w].
    let mut f = Factors::new(model, blocks, y_u, 0, true)?;
    let (ny, n, nq) = (f.ny, f.n, f.nq);
    let z = &f.raw.x.w;
    let j_fk = negated_block(z, (ny, n), (6, nq));
    let lambda_fk = negated_block(z, (0, n), (ny, nq));
    let compliance = negated_block(z, (ny, n + nq), (6, 6));
    let lambda_c = negated_block(z, (0, n + nq), (ny, 6));
    let (j_ik, lambda_ik) = inverse_jacobian(&mut f.raw, &j_fk, &lambda_fk);
    let ellipsoids = Ellipsoids {
        j_p: Ellipsoid::of(&j_fk.rows(0, 3)),
        j_o: Ellipsoid::of(&j_fk.rows(3, 3)),
        c_p: Ellipsoid::of_matrix3(&compliance.fixed_view::<3, 3>(0, 0).into_owned()),
        c_o: Ellipsoid::of_matrix3(&compliance.fixed_view::<3, 3>(3, 3).into_owned()),
    };
    let c = f.conditioning(
        model,
        y_u,
        settings,
        &j_fk,
        &compliance,
        Purpose::Analysis(&ellipsoids),
    );
    f.recycle();
    Ok(Analysis {
        j_fk,
        lambda_fk,
        j_ik,
        lambda_ik,
        lambda_c,
        rcond: c.rcond,
        rcond_scaled: c.rcond_scaled,
        singularity: c.singularity,
        ellipsoids,
        min_tension: c.min_tension,
        stability: c.stability,
        compliance,
    })
}

/// The [`Conditioning`] part of [`analyze_blocks`] (the same values, bit for bit), at
/// less cost: of the back substitution for J_FK and C only the six pose rows, no J_IK,
/// no Λ. For the workspace sweep, which analyses every point it solves.
///
/// # Errors
/// As [`analyze_blocks`] (Λ_FK and Λ_C are not formed: where only they would overflow,
/// this returns the measures and [`analyze_blocks`] [`AnalysisError::Singular`]).
pub fn condition_blocks(
    model: &Model,
    blocks: &BoundaryJacobians,
    y_u: &[f64],
    settings: &AnalysisSettings,
) -> Result<Conditioning, AnalysisError> {
    condition_blocks_with(model, blocks, y_u, settings, true)
}

/// The unit-scaled rconds of \[B_x B_u\], \[B_q B_u\] and B_u of `blocks` that passed
/// [`condition_blocks_with`] (so their sizes and entries are checked), as
/// [`condition_blocks`] gives them in `rcond_scaled`, bit for bit (a singular matrix has
/// rcond 0).
pub(crate) fn scaled_block_rconds(model: &Model, blocks: &BoundaryJacobians) -> [f64; 3] {
    let n = 3 * model.n_leg_unknowns() + 6;
    with_work(n, |work| {
        scaled_rconds(model, blocks, &UnitScaling::new(model), work)
    })
}

/// [`condition_blocks`] (`complete`) or the workspace sweep's part of it: without the
/// unit-scaled rconds of \[B_x B_u\], \[B_q B_u\] and B_u (a second factorization; their
/// entries of `rcond_scaled` are NaN), which the sweep needs only at the points that
/// represent its cells and gets there from the same blocks by [`scaled_block_rconds`]
/// (the same values, bit for bit), and with only the sign part of the stability
/// ([`Stability::of_compliance_sign`]). Every other field is the same, bit for bit.
pub(crate) fn condition_blocks_with(
    model: &Model,
    blocks: &BoundaryJacobians,
    y_u: &[f64],
    settings: &AnalysisSettings,
    complete: bool,
) -> Result<Conditioning, AnalysisError> {
    let ny = 3 * model.n_leg_unknowns();
    let f = Factors::new(model, blocks, y_u, ny, complete)?;
    let (n, nq) = (f.n, f.nq);
    let z = &f.raw.x.w;
    // On the stack (the values of `analyze_blocks`' matrices): no allocation.
    let mut j_fk = PoseByActuators::zeros();
    let mut j_fk = j_fk.columns_mut(0, nq);
    j_fk.copy_from(&z.view((ny, n), (6, nq)));
    j_fk.neg_mut();
    let compliance = Matrix6::from_fn(|r, c| -z[(ny + r, n + nq + c)]);
    let purpose = if complete {
        Purpose::Conditioning
    } else {
        Purpose::Sweep
    };
    let conditioning = f.conditioning(model, y_u, settings, &j_fk, &compliance, purpose);
    f.recycle();
    Ok(conditioning)
}

/// The raw and unit-scaled triangles of one configuration's blocks, the shared first
/// stage of [`analyze_blocks`] and [`condition_blocks`].
struct Factors {
    /// Raw SI triangles; after [`Factors::solve`] the columns right of R_x hold Z.
    raw: Triangles,
    /// rcond of the unit-scaled \[B_x B_u\], \[B_q B_u\], B_u.
    scaled_rconds: [f64; 3],
    scaling: UnitScaling,
    /// Leg unknowns of all legs n_y, unknowns n = n_y + 6, actuators n_q.
    ny: usize,
    n: usize,
    nq: usize,
}

/// Runs `f` with this thread's analysis buffers, sized for n unknowns.
fn with_work<T>(n: usize, f: impl FnOnce(&mut Work) -> T) -> T {
    WORK.with_borrow_mut(|slot| {
        let work = match slot {
            Some(w) if w.lz.capacity() >= n + 3 => w,
            _ => slot.insert(Work::new(n + 3)),
        };
        f(work)
    })
}

/// The rconds of the unit-scaled \[B_x B_u\], \[B_q B_u\] and B_u ([`UnitScaling`]):
/// rows divided and columns multiplied by the characteristic sizes of `scaling`, factored
/// apart from the raw blocks (checked inputs, in `work`).
fn scaled_rconds(
    model: &Model,
    blocks: &BoundaryJacobians,
    scaling: &UnitScaling,
    work: &mut Work,
) -> [f64; 3] {
    let (nq, nu) = (model.n_actuators(), model.n_leg_unknowns());
    let ny = 3 * nu;
    let n = ny + 6;
    // Rows, then the columns of B_u, B_x and B_q, in one kept buffer.
    let mut buf = std::mem::take(&mut work.scales);
    buf.clear();
    buf.extend((0..n).map(|i| 1.0 / scaling.row(i)));
    buf.extend((0..ny).map(|j| scaling.leg_unknown(j)));
    buf.extend((0..6).map(|c| scaling.pose(c)));
    buf.extend((0..nq).map(|j| scaling.actuation(j)));
    let (rows, cols) = buf.split_at(n);
    let (cols_u, cols) = cols.split_at(ny);
    let (cols_x, cols_q) = cols.split_at(6);
    let cols = [cols_u, cols_x, cols_q];
    let scales = Scales { rows, cols: &cols };
    let triangles = Triangles::new(blocks, nu, Some(scales), work);
    let rconds = triangles.rconds;
    triangles.recycle(work);
    work.scales = buf;
    rconds
}

impl Factors {
    /// Hands the raw triangles' storage back to this thread's analysis buffers.
    fn recycle(self) {
        WORK.with_borrow_mut(|slot| {
            if let Some(work) = slot {
                self.raw.recycle(work);
            }
        });
    }

    /// [`Factors::factor`], then [`Factors::solve`] for rows `from..n` of Z.
    ///
    /// # Errors
    /// As [`Factors::factor`] and [`Factors::solve`].
    fn new(
        model: &Model,
        blocks: &BoundaryJacobians,
        y_u: &[f64],
        from: usize,
        scaled: bool,
    ) -> Result<Self, AnalysisError> {
        let mut f = Self::factor(model, blocks, y_u, scaled)?;
        match f.solve(from) {
            Ok(()) => Ok(f),
            Err(e) => {
                f.recycle();
                Err(e)
            }
        }
    }

    /// The raw triangles and their rconds, and (if `scaled`) the unit-scaled rconds
    /// (else NaN).
    ///
    /// # Errors
    /// [`AnalysisError::Shape`] or [`AnalysisError::NonFinite`] for inputs that do not fit.
    fn factor(
        model: &Model,
        blocks: &BoundaryJacobians,
        y_u: &[f64],
        scaled: bool,
    ) -> Result<Self, AnalysisError> {
        check_inputs(model, blocks, y_u)?;
        let n = 3 * model.n_leg_unknowns() + 6;
        Ok(with_work(n, |work| {
            Self::factor_with(model, blocks, work, scaled)
        }))
    }

    /// [`Factors::factor`] for checked inputs, in `work`.
    fn factor_with(
        model: &Model,
        blocks: &BoundaryJacobians,
        work: &mut Work,
        scaled: bool,
    ) -> Self {
        let (nq, nu) = (model.n_actuators(), model.n_leg_unknowns());
        let ny = 3 * nu;
        let n = ny + 6;
        let raw = Triangles::new(blocks, nu, None, work);
        let scaling = UnitScaling::new(model);
        let scaled_rconds = if scaled {
            scaled_rconds(model, blocks, &scaling, work)
        } else {
            [f64::NAN; 3]
        };
        Self {
            raw,
            scaled_rconds,
            scaling,
            ny,
            n,
            nq,
        }
    }

    /// Solves R_x Z = Qᵀ \[B_q B_w\] for rows `from..n` of Z (rows n_y..n are δx: J_FK
    /// and C; rows below n_y are Λ_FK and Λ_C; rows below `from` are left partly
    /// reduced).
    ///
    /// # Errors
    /// [`AnalysisError::Singular`] if R_x has a zero pivot or anything of the factors is
    /// not finite afterwards.
    fn solve(&mut self, from: usize) -> Result<(), AnalysisError> {
        let (n, nq) = (self.n, self.nq);
        let x = &mut self.raw.x;
        let finite = |x: &LegQr| lanczos::all_finite(x.w.as_slice());
        if back_substitute_rows(x, n, n..n + nq + 6, from) && finite(x) {
            Ok(())
        } else {
            Err(AnalysisError::Singular {
                matrix: "[B_x B_u]",
                rcond: self.raw.rconds[0],
                undefined: "J_FK, Λ_FK, C and Λ_C",
            })
        }
    }

    /// The rconds, flags, tension and stability from J_FK (6 × n_q) and C (6 × 6), for
    /// `purpose`.
    fn conditioning<RJ: Dim, CJ: Dim, SJ, RC: Dim, CC: Dim, SC>(
        &self,
        model: &Model,
        y_u: &[f64],
        settings: &AnalysisSettings,
        j_fk: &Matrix<f64, RJ, CJ, SJ>,
        compliance: &Matrix<f64, RC, CC, SC>,
        purpose: Purpose,
    ) -> Conditioning
    where
        SJ: RawStorage<f64, RJ, CJ>,
        SC: RawStorage<f64, RC, CC>,
    {
        let (raw_blocks, scaled_rconds, scaling) =
            (self.raw.rconds, self.scaled_rconds, &self.scaling);
        let [j_p, j_o, c_p, c_o] = match purpose {
            Purpose::Analysis(e) => [e.j_p.rcond(), e.j_o.rcond(), e.c_p.rcond(), e.c_o.rcond()],
            Purpose::Conditioning | Purpose::Sweep => [
                ellipsoid::rcond_of(&j_fk.rows(0, 3)),
                ellipsoid::rcond_of(&j_fk.rows(3, 3)),
                ellipsoid::rcond_of_matrix3(&compliance.fixed_view::<3, 3>(0, 0).into_owned()),
                ellipsoid::rcond_of_matrix3(&compliance.fixed_view::<3, 3>(3, 3).into_owned()),
            ],
        };
        let rcond = Rconds {
            b_xu: raw_blocks[0],
            b_qu: raw_blocks[1],
            b_u: raw_blocks[2],
            j_p,
            j_o,
            c_p,
            c_o,
        };
        let mut scaled_j = PoseByActuators::zeros();
        let mut scaled_j = scaled_j.columns_mut(0, self.nq);
        for c in 0..self.nq {
            for r in 0..6 {
                scaled_j[(r, c)] = j_fk[(r, c)] * scaling.actuation(c) / scaling.pose(r);
            }
        }
        let rcond_scaled = Rconds {
            b_xu: scaled_rconds[0],
            b_qu: scaled_rconds[1],
            b_u: scaled_rconds[2],
            j_p: ellipsoid::rcond_of(&scaled_j.rows(0, 3)),
            j_o: ellipsoid::rcond_of(&scaled_j.rows(3, 3)),
            // Uniformly scaled blocks: σ_min/σ_max unchanged.
            c_p: rcond.c_p,
            c_o: rcond.c_o,
        };
        let singularity = Singularity {
            type_i: rcond.b_qu < settings.type_i_threshold,
            type_ii: rcond.b_xu < settings.type_ii_threshold,
            leg: rcond.b_u < settings.leg_threshold || slack_pair(model, y_u),
        };
        Conditioning {
            rcond,
            rcond_scaled,
            singularity,
            min_tension: min_tension(model, y_u),
            stability: match purpose {
                Purpose::Sweep => Stability::of_compliance_sign(model, compliance),
                Purpose::Analysis(_) | Purpose::Conditioning => {
                    Stability::of_compliance(model, compliance)
                }
            },
        }
    }
}

/// What [`Factors::conditioning`] computes the measures for.
#[derive(Debug, Clone, Copy)]
enum Purpose<'a> {
    /// [`analyze_blocks`], which has the ellipsoids: the rconds of J_p, J_o, C_p and C_o
    /// are theirs.
    Analysis(&'a Ellipsoids),
    /// [`condition_blocks`]: the same values, the rconds without the axes' directions.
    Conditioning,
    /// The workspace sweep: as `Conditioning`, with only the sign part of the stability
    /// ([`Stability::of_compliance_sign`]).
    Sweep,
}

/// A 6 × n_q matrix (J_FK) on the stack: the first n_q ≤ [`MAX_ACTUATORS`] columns.
type PoseByActuators = SMatrix<f64, 6, MAX_ACTUATORS>;

/// Sizes and finiteness of the inputs.
fn check_inputs(
    model: &Model,
    blocks: &BoundaryJacobians,
    y_u: &[f64],
) -> Result<(), AnalysisError> {
    let (n, nq, ny) = (
        model.n_residuals(),
        model.n_actuators(),
        3 * model.n_leg_unknowns(),
    );
    for (what, m, cols) in [
        ("b_x", &blocks.b_x, 6),
        ("b_q", &blocks.b_q, nq),
        ("b_w", &blocks.b_w, 6),
        ("b_u", &blocks.b_u, ny),
    ] {
        if m.shape() != (n, cols) {
            return Err(AnalysisError::Shape {
                what,
                found: format!("{}×{}", m.nrows(), m.ncols()),
                expected: format!("{n}×{cols}"),
            });
        }
        if !lanczos::all_finite(m.as_slice()) {
            return Err(AnalysisError::NonFinite { what });
        }
    }
    if y_u.len() != ny {
        return Err(AnalysisError::Shape {
            what: "y_u",
            found: format!("{} values", y_u.len()),
            expected: format!("{ny} values"),
        });
    }
    if !lanczos::all_finite(y_u) {
        return Err(AnalysisError::NonFinite { what: "y_u" });
    }
    Ok(())
}

/// J_IK and Λ_IK (see the module docs).
fn inverse_jacobian(
    raw: &mut Triangles,
    j_fk: &DMatrix<f64>,
    lambda_fk: &DMatrix<f64>,
) -> (DMatrix<f64>, DMatrix<f64>) {
    if let Some(qr) = &mut raw.q {
        // [B_u B_q] [δy; δq] = −B_x δx; the pose columns follow R_q.
        let ny = qr.ny;
        let n = ny + 6;
        if back_substitute(qr, n, n..n + 6) {
            let z = qr.w.columns(n, 6);
            if z.iter().all(|x| x.is_finite()) {
                return (
                    negated_block(&qr.w, (ny, n), (6, 6)),
                    negated_block(&qr.w, (0, n), (ny, 6)),
                );
            }
        }
    }
    let j_ik = right_inverse(j_fk);
    let lambda_ik = lambda_fk * &j_ik;
    (j_ik, lambda_ik)
}

/// −z\[r0..r0 + nr, c0..c0 + nc\] as a new matrix, column by column from z's
/// column-major storage (the same values as nalgebra's negated view, which went element
/// by element through its iterator: about 18 k instructions of a 9-DoF analysis).
fn negated_block(
    z: &DMatrix<f64>,
    (r0, c0): (usize, usize),
    (nr, nc): (usize, usize),
) -> DMatrix<f64> {
    let ld = z.nrows();
    assert!(
        r0 + nr <= ld && c0 + nc <= z.ncols(),
        "block ({r0}, {c0}) + ({nr}, {nc}) outside a {ld} × {} matrix",
        z.ncols()
    );
    let src = z.as_slice();
    let mut data = Vec::with_capacity(nr * nc);
    for c in c0..c0 + nc {
        data.extend(src[c * ld + r0..c * ld + r0 + nr].iter().map(|x| -x));
    }
    DMatrix::from_vec(nr, nc, data)
}

thread_local! {
    /// The [`Work`] of the analyses on this thread, kept between calls and replaced by a
    /// larger one when a design needs it. Every buffer is written before it is read, so
    /// a reused one gives bitwise what a fresh one gives. (A fresh one per call cost
    /// about 14 allocations and 16 k instructions of zero fill per 9-DoF analysis.) With
    /// the factorizations' storage kept here too and J_FK, C and the scaled J_FK of the
    /// measures on the stack, [`condition_blocks`] (and so [`Solver::condition`](
    /// crate::kinetostatics::Solver::condition)) allocates nothing after a thread's first
    /// call (tests/no_allocation.rs; 11 small ones a 6-DoF call before, 2026-11-27); only
    /// [`analyze_blocks`]' own matrices (J_FK, Λ, J_IK, C) are allocated, as its output.
    static WORK: std::cell::RefCell<Option<Work>> = const { std::cell::RefCell::new(None) };
}

/// Work buffers of one analysis, shared by the raw and the scaled [`Triangles`].
struct Work {
    lz: Lanczos,
    wide: WideBuffers,
    /// A Lanczos start vector.
    start: Vec<f64>,
    /// R_u's top right singular vector.
    v_u: Vec<f64>,
    /// The unit scaling's row and column factors.
    scales: Vec<f64>,
    /// Storage of earlier [`LegQr`]s, reused by the next ones (none allocated in a
    /// thread's analyses after its first).
    storage: Vec<Vec<f64>>,
}

/// The triangular factors of \[B_u B_x\], B_u and (if square) \[B_u B_q\] from one
/// [`LegQr`], and the rcond of the three matrices.
struct Triangles {
    /// Columns \[R_x | Qᵀ B_q | Qᵀ B_w\] (B_w only without scales).
    x: LegQr,
    /// Columns \[R_q | Qᵀ B_x\] when \[B_q B_u\] is square (6-DoF design).
    q: Option<LegQr>,
    /// rcond of \[B_x B_u\], \[B_q B_u\], B_u.
    rconds: [f64; 3],
}

impl Work {
    /// Buffers for matrices of order up to `n`.
    fn new(n: usize) -> Self {
        Self {
            lz: Lanczos::new(n),
            wide: WideBuffers::default(),
            start: vec![0.0; n],
            v_u: Vec::with_capacity(n),
            scales: Vec::new(),
            storage: Vec::new(),
        }
    }
}

impl Triangles {
    /// Hands the factors' storage back to `work` for the next analysis.
    fn recycle(self, work: &mut Work) {
        work.storage.push(self.x.into_storage());
        if let Some(q) = self.q {
            work.storage.push(q.into_storage());
        }
    }

    /// Factors `[B_u | B_x | B_q (| B_w without scales)]`, scaled if `scales` are given.
    fn new(b: &BoundaryJacobians, nu: usize, scales: Option<Scales>, work: &mut Work) -> Self {
        let Work {
            lz,
            wide,
            start,
            v_u,
            storage,
            ..
        } = work;
        let (ny, nq) = (b.b_u.ncols(), b.b_q.ncols());
        let n = ny + 6;
        let reuse = storage.pop().unwrap_or_default();
        let legs = if scales.is_some() {
            LegQr::new(&[&b.b_u, &b.b_x, &b.b_q], nu, scales, reuse)
        } else {
            LegQr::new(&[&b.b_u, &b.b_x, &b.b_q, &b.b_w], nu, None, reuse)
        };
        let ncols = legs.w.ncols();
        let (xc, qc) = (ny..n, n..n + nq);
        // The fixed random start: a start from R_u's largest row (Rᵀe_i) saved a Lanczos
        // step but converged to a smaller Ritz value than σ_max at 1 801 of the 178 353
        // points of the reference design's sweep (rcond up to 0.64 % off, the scaled ones
        // up to 16 %).
        let sigma_u = lz.sigma_max(legs.triangle(ny), Start::Random);
        v_u.clear();
        v_u.extend_from_slice(lz.ritz());
        let v_u = &v_u[..];
        let rcond_u = ellipsoid::ratio(lz.sigma_min(legs.triangle(ny)), sigma_u);
        let (norm_x, norm_q) = (
            column_norm(&legs, xc.clone()),
            column_norm(&legs, qc.clone()),
        );
        let (q, rcond_q) = if nq == 6 {
            let mut q = legs.copy_into(storage.pop().unwrap_or_default());
            q.swap_columns(xc.clone(), qc.clone());
            q.finish(xc.clone(), qc.clone());
            let max = sigma_max_extended(lz, q.triangle(n), sigma_u, norm_q, Start::Given(v_u));
            let rc = ellipsoid::ratio(lz.sigma_min(q.triangle(n)), max);
            (Some(q), rc)
        } else {
            (None, 0.0)
        };
        // Wide [B_u B_q] (n × (n + 3), 9-DoF): its σ are those of the tall transpose,
        // formed before `finish` changes the rows below R_u; its σ_min and σ_max come
        // last.
        let wide = if nq == 6 {
            None
        } else {
            qr::wide_triangle(&legs, qc.clone(), wide);
            Some(wide.triangle(n))
        };
        if wide.is_some() {
            // M's top left singular vector is near [R_u v_u; 0] (v_u: R_u's top right
            // singular vector), and R's right ones are M's left ones reversed.
            let start = &mut start[..n];
            start.fill(0.0);
            lanczos::upper_mul(legs.triangle(ny), v_u, start);
            start.reverse();
            let norm = lanczos::dot(start, start).sqrt();
            if norm > 0.0 && norm.is_finite() {
                start.iter_mut().for_each(|x| *x /= norm);
            } else {
                start.fill(0.0);
            }
        }
        let mut x = legs;
        x.finish(xc.clone(), n..ncols);
        let max = sigma_max_extended(lz, x.triangle(n), sigma_u, norm_x, Start::Given(v_u));
        let rcond_x = ellipsoid::ratio(lz.sigma_min(x.triangle(n)), max);
        let rcond_q = match wide {
            None => rcond_q,
            Some(tri) => {
                let min = lz.sigma_min(tri);
                let start = if start[0..n].iter().all(|&x| x == 0.0) {
                    Start::Random
                } else {
                    Start::Given(&start[..n])
                };
                let max = sigma_max_extended(lz, tri, sigma_u, norm_q, start);
                ellipsoid::ratio(min, max)
            }
        };
        Self {
            x,
            q,
            rconds: [rcond_x, rcond_q, rcond_u],
        }
    }
}

/// Σ ‖column‖² over the columns `cols` of `qr.w`.
fn column_norm(qr: &LegQr, cols: std::ops::Range<usize>) -> f64 {
    cols.map(|c| qr.w.column(c).norm_squared()).sum::<f64>()
}

/// σ_max(\[B_u E\]) from its triangle `r`, σ_u = σ_max(B_u) and ‖E‖_F² = `extra`: it
/// lies in \[σ_u, (σ_u² + ‖E‖²)^½\]; when that is narrower than the Lanczos tolerance,
/// the middle, otherwise Lanczos from `start`.
fn sigma_max_extended(
    lz: &mut Lanczos,
    r: qr::Triangle,
    sigma_u: f64,
    extra: f64,
    start: Start,
) -> f64 {
    if extra <= 4.0 * lanczos::TOLERANCE * sigma_u * sigma_u {
        0.5 * (sigma_u + (sigma_u * sigma_u + extra).sqrt())
    } else {
        lz.sigma_max(r, start)
    }
}

/// The Moore–Penrose pseudo-inverse of a 6 × n_q Jacobian (singular values below
/// max(rows, cols)·ε·σ_max dropped).
///
/// Where J has full row rank by a wide margin, from the QR factorization Jᵀ = Q R (Q
/// n_q × 6 with orthonormal columns, R 6 × 6 upper triangular): J⁺ = Jᵀ(J Jᵀ)⁻¹ = Q R⁻ᵀ,
/// which a backward-stable QR gives to about κ(J)·ε like the SVD (J Jᵀ by Cholesky
/// would square κ). Near rank deficiency (min |R_ii| ≤ 1e-8 max |R_ii|) the SVD decides
/// which singular values to drop. The SVD of the 9-DoF 6 × 9 J_FK was about 30 k
/// instructions of the 759 k of an analysis.
fn right_inverse(j: &DMatrix<f64>) -> DMatrix<f64> {
    if j.ncols() >= j.nrows() && j.nrows() > 0 {
        let qr = j.transpose().qr();
        let r = qr.r();
        let d = r.diagonal().abs();
        let (min, max) = (d.min(), d.max());
        if min > 1e-8 * max && max.is_finite() {
            // Solve R Y = Qᵀ: Y = R⁻¹Qᵀ = (J⁺)ᵀ.
            if let Some(y) = r.solve_upper_triangular(&qr.q().transpose()) {
                if lanczos::all_finite(y.as_slice()) {
                    return y.transpose();
                }
            }
        }
    }
    let svd = j.clone().svd(true, true);
    let max = svd.singular_values.iter().copied().fold(0.0, f64::max);
    let cutoff = max * j.nrows().max(j.ncols()) as f64 * f64::EPSILON;
    svd.pseudo_inverse(cutoff.max(f64::MIN_POSITIVE))
        .unwrap_or_else(|_| DMatrix::zeros(j.ncols(), j.nrows()))
}

/// Whether some leg has an antagonistic pair with both tendons slack (τ = 0).
fn slack_pair(model: &Model, y_u: &[f64]) -> bool {
    let nu = model.n_leg_unknowns();
    (0..3).any(|leg| {
        (0..model.pairs).any(|j| {
            let g = &y_u[leg * nu + 2 * j..];
            tension(g[0]) == 0.0 && tension(g[1]) == 0.0
        })
    })
}

/// Smallest tension over all tendons \[N\].
fn min_tension(model: &Model, y_u: &[f64]) -> f64 {
    let nu = model.n_leg_unknowns();
    (0..3)
        .flat_map(|leg| y_u[leg * nu..leg * nu + model.n_tendons()].iter())
        .map(|&g| tension(g))
        .fold(f64::INFINITY, f64::min)
}
