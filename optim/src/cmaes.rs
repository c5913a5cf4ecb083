//! CMA-ES (covariance matrix adaptation evolution strategy, Hansen & Ostermeier 2001, in
//! the form of Hansen's tutorial "The CMA Evolution Strategy", 2016) with an ask/tell
//! interface, minimizing a function on the unit box \[0, 1\]ⁿ.
//!
//! **Bounds.** The strategy samples *genotypes* g ~ m + σ N(0, C) in ℝⁿ without bounds;
//! the point handed out (the *phenotype*) is g mirrored into \[0, 1\] coordinate-wise
//! ([`reflect`]: a triangle wave of period 2). The update uses the genotypes, so the
//! search distribution stays Gaussian and the step-size path is not biased by repairs
//! (the approach of pycma's boundary transformation, with a piecewise-linear map). Every
//! phenotype is in the box; an optimum on a bound is reached as the genotype mean
//! converges onto the bound.
//!
//! **Determinism.** All random numbers come from one [`Rng`] seeded by the user, drawn in
//! [`CmaEs::ask`] only; ties in [`CmaEs::tell`] are broken by candidate index. The same
//! seed and the same fitness values give the same run, bit for bit.
//!
//! ```
//! use tdpcr_optim::cmaes::{CmaEs, CmaesSettings};
//! let settings = CmaesSettings::new(vec![0.5; 3], 0.3, 7)?;
//! let mut es = CmaEs::new(&settings, 42);
//! for _ in 0..200 {
//!     let xs = es.ask();
//!     let f: Vec<f64> = xs.iter().map(|x| x.iter().map(|v| (v - 0.2).powi(2)).sum()).collect();
//!     es.tell(&f)?;
//! }
//! assert!((es.mean()[0] - 0.2).abs() < 1e-3);
//! # Ok::<(), tdpcr_optim::cmaes::CmaesError>(())
//! ```

use nalgebra::{DMatrix, DVector, SymmetricEigen};

use crate::rng::Rng;

/// Invalid settings or a misuse of ask/tell; every message names the value and the rule.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CmaesError {
    /// The initial mean is empty or has a coordinate outside \[0, 1\].
    #[error("initial mean {mean:?}: expected 1 or more coordinates, each in [0, 1]")]
    InvalidMean {
        /// The mean given.
        mean: Vec<f64>,
    },
    /// The initial step size σ₀ is not in (0, 1].
    #[error("initial step size {sigma}: expected in (0, 1] (a fraction of the box)")]
    InvalidStepSize {
        /// σ₀ given.
        sigma: f64,
    },
    /// The population size λ is below 2.
    #[error("population size {population}: expected >= 2")]
    InvalidPopulation {
        /// λ given.
        population: usize,
    },
    /// [`CmaEs::tell`] got a different number of values than [`CmaEs::ask`] handed out.
    #[error("tell got {found} fitness values: expected {expected} (one per asked candidate)")]
    FitnessCount {
        /// λ.
        expected: usize,
        /// Values given.
        found: usize,
    },
    /// A fitness value is NaN.
    #[error("fitness of candidate {index} is NaN: expected a number (use a large penalty)")]
    NanFitness {
        /// Candidate index in the generation.
        index: usize,
    },
    /// [`CmaEs::tell`] without a preceding [`CmaEs::ask`].
    #[error("tell without ask: no generation is pending")]
    NothingAsked,
}

/// The default population size of CMA-ES, λ = 4 + ⌊3 ln n⌋.
pub fn default_population(dimension: usize) -> usize {
    4 + (3.0 * (dimension.max(1) as f64).ln()).floor() as usize
}

/// Validated starting point of a run (argmin-style: settings check their values once).
#[derive(Debug, Clone, PartialEq)]
pub struct CmaesSettings {
    mean: Vec<f64>,
    sigma: f64,
    population: usize,
}

impl CmaesSettings {
    /// Initial mean (in \[0, 1\]ⁿ), initial step size σ₀ (a fraction of the box side) and
    /// population size λ (see [`default_population`]).
    ///
    /// # Errors
    /// [`CmaesError::InvalidMean`], [`CmaesError::InvalidStepSize`],
    /// [`CmaesError::InvalidPopulation`].
    pub fn new(mean: Vec<f64>, sigma: f64, population: usize) -> Result<Self, CmaesError> {
        if mean.is_empty() || !mean.iter().all(|x| (0.0..=1.0).contains(x)) {
            return Err(CmaesError::InvalidMean { mean });
        }
        if !(sigma > 0.0 && sigma <= 1.0) {
            return Err(CmaesError::InvalidStepSize { sigma });
        }
        if population < 2 {
            return Err(CmaesError::InvalidPopulation { population });
        }
        Ok(Self {
            mean,
            sigma,
            population,
        })
    }

    /// Dimension n.
    pub fn dimension(&self) -> usize {
        self.mean.len()
    }

    /// Population size λ.
    pub fn population(&self) -> usize {
        self.population
    }
}

/// Why the strategy itself considers the search finished (budgets are the caller's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Convergence {
    /// Every coordinate's standard deviation σ·√C_ii is below the tolerance.
    StepBelowTolerance {
        /// Largest σ·√C_ii.
        largest_std: f64,
    },
    /// The condition number of C exceeds 1e14 (numerically degenerate).
    IllConditioned {
        /// λ_max / λ_min of C.
        condition: f64,
    },
}

impl std::fmt::Display for Convergence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::StepBelowTolerance { largest_std } => write!(
                f,
                "converged: largest coordinate standard deviation {largest_std:.2e} (box units)"
            ),
            Self::IllConditioned { condition } => {
                write!(f, "covariance ill-conditioned (condition {condition:.2e})")
            }
        }
    }
}

/// Largest condition number of C before [`Convergence::IllConditioned`].
const MAX_CONDITION: f64 = 1e14;

/// Largest σ: beyond a few box sides the mirrored samples are uniform anyway.
const MAX_SIGMA: f64 = 4.0;

/// The strategy's state (MODEL.md §7; Hansen 2016, Table 1 and Fig. 6 for the constants).
#[derive(Debug, Clone)]
pub struct CmaEs {
    n: usize,
    lambda: usize,
    weights: Vec<f64>,
    mu_eff: f64,
    c_sigma: f64,
    d_sigma: f64,
    c_c: f64,
    c_1: f64,
    c_mu: f64,
    chi_n: f64,
    mean: DVector<f64>,
    sigma: f64,
    cov: DMatrix<f64>,
    /// Eigenvectors B of C (columns).
    basis: DMatrix<f64>,
    /// Square roots D of the eigenvalues of C.
    scales: DVector<f64>,
    p_sigma: DVector<f64>,
    p_c: DVector<f64>,
    generation: usize,
    rng: Rng,
    /// Genotypes of the pending generation (between ask and tell).
    pending: Vec<DVector<f64>>,
}

impl CmaEs {
    /// A new strategy at `settings`, drawing from the stream of `seed`.
    pub fn new(settings: &CmaesSettings, seed: u64) -> Self {
        let n = settings.dimension();
        let lambda = settings.population;
        let mu = lambda / 2;
        let raw: Vec<f64> = (1..=mu)
            .map(|i| ((lambda as f64 + 1.0) / 2.0).ln() - (i as f64).ln())
            .collect();
        let sum: f64 = raw.iter().sum();
        let weights: Vec<f64> = raw.iter().map(|w| w / sum).collect();
        let mu_eff = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
        let nf = n as f64;
        let c_sigma = (mu_eff + 2.0) / (nf + mu_eff + 5.0);
        let d_sigma = 1.0 + 2.0 * (((mu_eff - 1.0) / (nf + 1.0)).sqrt() - 1.0).max(0.0) + c_sigma;
        let c_c = (4.0 + mu_eff / nf) / (nf + 4.0 + 2.0 * mu_eff / nf);
        let c_1 = 2.0 / ((nf + 1.3).powi(2) + mu_eff);
        let c_mu =
            (1.0 - c_1).min(2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((nf + 2.0).powi(2) + mu_eff));
        let chi_n = nf.sqrt() * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));
        Self {
            n,
            lambda,
            weights,
            mu_eff,
            c_sigma,
            d_sigma,
            c_c,
            c_1,
            c_mu,
            chi_n,
            mean: DVector::from_column_slice(&settings.mean),
            sigma: settings.sigma,
            cov: DMatrix::identity(n, n),
            basis: DMatrix::identity(n, n),
            scales: DVector::from_element(n, 1.0),
            p_sigma: DVector::zeros(n),
            p_c: DVector::zeros(n),
            generation: 0,
            rng: Rng::new(seed),
            pending: Vec::new(),
        }
    }

    /// Population size λ.
    pub fn population(&self) -> usize {
        self.lambda
    }

    /// Generations completed (calls of [`CmaEs::tell`]).
    pub fn generation(&self) -> usize {
        self.generation
    }

    /// Current step size σ (box units).
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// Current mean mirrored into the box (the strategy's best guess of the optimum).
    pub fn mean(&self) -> Vec<f64> {
        self.mean.iter().map(|&g| reflect(g)).collect()
    }

    /// The next generation: λ points in \[0, 1\]ⁿ. Asking again before [`CmaEs::tell`]
    /// discards the pending generation and draws a new one.
    pub fn ask(&mut self) -> Vec<Vec<f64>> {
        let bd = &self.basis * DMatrix::from_diagonal(&self.scales);
        self.pending = (0..self.lambda)
            .map(|_| {
                let z = DVector::from_fn(self.n, |_, _| self.rng.normal());
                &self.mean + self.sigma * (&bd * z)
            })
            .collect();
        self.pending
            .iter()
            .map(|g| g.iter().map(|&v| reflect(v)).collect())
            .collect()
    }

    /// Updates the strategy with the fitness (to minimize) of each asked candidate, in
    /// the order [`CmaEs::ask`] returned them. Ties rank by candidate index.
    ///
    /// # Errors
    /// [`CmaesError::NothingAsked`], [`CmaesError::FitnessCount`],
    /// [`CmaesError::NanFitness`]; the state is unchanged on error.
    pub fn tell(&mut self, fitness: &[f64]) -> Result<(), CmaesError> {
        if self.pending.is_empty() {
            return Err(CmaesError::NothingAsked);
        }
        if fitness.len() != self.lambda {
            return Err(CmaesError::FitnessCount {
                expected: self.lambda,
                found: fitness.len(),
            });
        }
        if let Some(index) = fitness.iter().position(|f| f.is_nan()) {
            return Err(CmaesError::NanFitness { index });
        }
        let mut order: Vec<usize> = (0..self.lambda).collect();
        order.sort_by(|&a, &b| fitness[a].total_cmp(&fitness[b]).then(a.cmp(&b)));
        let genotypes = std::mem::take(&mut self.pending);
        let ys: Vec<DVector<f64>> = order[..self.weights.len()]
            .iter()
            .map(|&i| (&genotypes[i] - &self.mean) / self.sigma)
            .collect();
        let y_w = ys
            .iter()
            .zip(&self.weights)
            .fold(DVector::zeros(self.n), |acc, (y, w)| acc + *w * y);
        self.mean += self.sigma * &y_w;

        // C^{-1/2} y_w = B D⁻¹ Bᵀ y_w.
        let inv_sqrt_y = &self.basis
            * DVector::from_fn(self.n, |i, _| {
                self.basis.column(i).dot(&y_w) / self.scales[i]
            });
        let cs = self.c_sigma;
        self.p_sigma =
            (1.0 - cs) * &self.p_sigma + (cs * (2.0 - cs) * self.mu_eff).sqrt() * inv_sqrt_y;
        let gen_factor = 1.0 - (1.0 - cs).powi(2 * (self.generation as i32 + 1));
        let h_sigma = self.p_sigma.norm() / gen_factor.sqrt()
            < (1.4 + 2.0 / (self.n as f64 + 1.0)) * self.chi_n;
        let cc = self.c_c;
        let h = if h_sigma { 1.0 } else { 0.0 };
        self.p_c = (1.0 - cc) * &self.p_c + h * (cc * (2.0 - cc) * self.mu_eff).sqrt() * &y_w;

        let rank_mu = ys
            .iter()
            .zip(&self.weights)
            .fold(DMatrix::zeros(self.n, self.n), |acc, (y, w)| {
                acc + *w * (y * y.transpose())
            });
        let decay = 1.0 - self.c_1 - self.c_mu + (1.0 - h) * self.c_1 * cc * (2.0 - cc);
        self.cov =
            decay * &self.cov + self.c_1 * (&self.p_c * self.p_c.transpose()) + self.c_mu * rank_mu;
        self.cov = (&self.cov + self.cov.transpose()) * 0.5;

        self.sigma *= ((cs / self.d_sigma) * (self.p_sigma.norm() / self.chi_n - 1.0)).exp();
        self.sigma = self.sigma.min(MAX_SIGMA);
        self.decompose();
        self.generation += 1;
        Ok(())
    }

    /// B and D from C; eigenvalues are kept ≥ 1e-300 (round-off), and a non-finite C
    /// (impossible with finite fitness, kept as a guard) restarts C at the identity.
    fn decompose(&mut self) {
        if !self.cov.iter().all(|x| x.is_finite()) {
            self.cov = DMatrix::identity(self.n, self.n);
        }
        let eig = SymmetricEigen::new(self.cov.clone());
        self.basis = eig.eigenvectors;
        self.scales = eig.eigenvalues.map(|l| l.max(1e-300).sqrt());
    }

    /// Whether the strategy has converged: every σ·√C_ii below `tolerance` (box units),
    /// or C numerically degenerate.
    pub fn convergence(&self, tolerance: f64) -> Option<Convergence> {
        let largest_std = (0..self.n)
            .map(|i| self.sigma * self.cov[(i, i)].sqrt())
            .fold(0.0, f64::max);
        if largest_std < tolerance {
            return Some(Convergence::StepBelowTolerance { largest_std });
        }
        let (lo, hi) = self
            .scales
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| {
                (lo.min(d * d), hi.max(d * d))
            });
        let condition = hi / lo;
        (condition > MAX_CONDITION).then_some(Convergence::IllConditioned { condition })
    }
}

/// Mirrors a coordinate into \[0, 1\]: identity inside, reflected at 0 and 1 (a triangle
/// wave of period 2).
pub fn reflect(g: f64) -> f64 {
    let t = g.rem_euclid(2.0);
    if t <= 1.0 { t } else { 2.0 - t }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs CMA-ES on `f` until `f` < `target` or `max_evals`; returns (best f, evals).
    fn minimize(
        f: impl Fn(&[f64]) -> f64,
        x0: Vec<f64>,
        sigma: f64,
        seed: u64,
        target: f64,
        max_evals: usize,
    ) -> (f64, usize, Vec<f64>) {
        let n = x0.len();
        let settings = CmaesSettings::new(x0, sigma, default_population(n)).unwrap();
        let mut es = CmaEs::new(&settings, seed);
        let (mut best, mut best_x, mut evals) = (f64::INFINITY, vec![], 0);
        while evals < max_evals && best >= target {
            let xs = es.ask();
            for x in &xs {
                assert!(
                    x.iter().all(|v| (0.0..=1.0).contains(v)),
                    "out of the box: {x:?}"
                );
            }
            let fs: Vec<f64> = xs.iter().map(|x| f(x)).collect();
            evals += xs.len();
            for (x, &v) in xs.iter().zip(&fs) {
                if v < best {
                    best = v;
                    best_x = x.clone();
                }
            }
            es.tell(&fs).unwrap();
        }
        (best, evals, best_x)
    }

    #[test]
    fn sphere_in_7d_converges_within_budget() {
        let opt = [0.3, 0.7, 0.5, 0.2, 0.9, 0.4, 0.6];
        let sphere = |x: &[f64]| {
            x.iter()
                .zip(&opt)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
        };
        let (best, evals, _) = minimize(sphere, vec![0.5; 7], 0.3, 1, 1e-10, 5_000);
        assert!(best < 1e-10, "sphere: {best:e} after {evals} evaluations");
    }

    #[test]
    fn rosenbrock_in_6d_converges_within_budget() {
        // u = 4x − 2 ∈ [−2, 2]; the optimum u = 1 is x = 0.75.
        let rosen = |x: &[f64]| {
            let u: Vec<f64> = x.iter().map(|v| 4.0 * v - 2.0).collect();
            u.windows(2)
                .map(|w| 100.0 * (w[1] - w[0] * w[0]).powi(2) + (1.0 - w[0]).powi(2))
                .sum::<f64>()
        };
        let (best, evals, x) = minimize(rosen, vec![0.5; 6], 0.2, 2, 1e-8, 30_000);
        assert!(
            best < 1e-8,
            "rosenbrock: {best:e} after {evals} evaluations"
        );
        assert!(x.iter().all(|v| (v - 0.75).abs() < 1e-3), "{x:?}");
    }

    #[test]
    fn optimum_outside_the_box_is_found_on_the_bound_and_bounds_hold() {
        // Minimum of the unconstrained sphere at (1.4, −0.3, 0.5): the box optimum is (1, 0, 0.5).
        let f = |x: &[f64]| (x[0] - 1.4).powi(2) + (x[1] + 0.3).powi(2) + (x[2] - 0.5).powi(2);
        let (best, _, x) = minimize(f, vec![0.5; 3], 0.3, 3, 0.16 + 0.09 + 1e-9, 5_000);
        assert!(best < 0.25 + 1e-9, "{best}");
        assert!((x[0] - 1.0).abs() < 1e-4 && x[1].abs() < 1e-4, "{x:?}");
    }

    #[test]
    fn same_seed_same_run_and_different_seed_different_run() {
        let run = |seed| {
            let s = CmaesSettings::new(vec![0.5; 4], 0.3, 8).unwrap();
            let mut es = CmaEs::new(&s, seed);
            let mut all = Vec::new();
            for _ in 0..5 {
                let xs = es.ask();
                let fs: Vec<f64> = xs.iter().map(|x| x.iter().sum()).collect();
                all.extend(xs);
                es.tell(&fs).unwrap();
            }
            all
        };
        assert_eq!(run(9), run(9));
        assert_ne!(run(9), run(10));
    }

    #[test]
    fn ties_and_constant_penalties_do_not_break_the_update() {
        let s = CmaesSettings::new(vec![0.5; 2], 0.3, 6).unwrap();
        let mut es = CmaEs::new(&s, 4);
        for _ in 0..50 {
            let xs = es.ask();
            es.tell(&vec![1e9; xs.len()]).unwrap();
        }
        assert!(es.sigma().is_finite() && es.sigma() > 0.0);
        assert!(es.mean().iter().all(|v| (0.0..=1.0).contains(v)));
    }

    #[test]
    fn misuse_and_bad_settings_are_reported_with_value_and_rule() {
        let cases = [
            (
                CmaesSettings::new(vec![], 0.3, 6).unwrap_err(),
                "initial mean []: expected 1 or more coordinates, each in [0, 1]",
            ),
            (
                CmaesSettings::new(vec![1.5], 0.3, 6).unwrap_err(),
                "initial mean [1.5]: expected 1 or more coordinates, each in [0, 1]",
            ),
            (
                CmaesSettings::new(vec![0.5], 0.0, 6).unwrap_err(),
                "initial step size 0: expected in (0, 1] (a fraction of the box)",
            ),
            (
                CmaesSettings::new(vec![0.5], 0.2, 1).unwrap_err(),
                "population size 1: expected >= 2",
            ),
        ];
        for (e, text) in cases {
            assert_eq!(e.to_string(), text);
        }
        let s = CmaesSettings::new(vec![0.5; 2], 0.3, 6).unwrap();
        let mut es = CmaEs::new(&s, 1);
        assert_eq!(es.tell(&[0.0; 6]).unwrap_err(), CmaesError::NothingAsked);
        es.ask();
        assert_eq!(
            es.tell(&[0.0; 5]).unwrap_err().to_string(),
            "tell got 5 fitness values: expected 6 (one per asked candidate)"
        );
        let mut f = [0.0; 6];
        f[2] = f64::NAN;
        assert_eq!(
            es.tell(&f).unwrap_err().to_string(),
            "fitness of candidate 2 is NaN: expected a number (use a large penalty)"
        );
        assert_eq!(default_population(7), 9);
        assert_eq!(default_population(1), 4);
    }

    #[test]
    fn reflect_is_a_triangle_wave() {
        for (g, x) in [
            (0.3, 0.3),
            (1.2, 0.8),
            (-0.2, 0.2),
            (2.3, 0.3),
            (-1.5, 0.5),
            (1.0, 1.0),
        ] {
            assert!((reflect(g) - x).abs() < 1e-12, "{g} -> {}", reflect(g));
        }
    }
}
