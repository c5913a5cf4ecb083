//! Tension and slack from the unknown γ (MODEL.md eqs. 6–7), both C¹ in γ.

/// Tension τ = γ² for γ ≥ 0, else 0 \[N\].
#[inline]
pub fn tension(gamma: f64) -> f64 {
    if gamma >= 0.0 { gamma * gamma } else { 0.0 }
}

/// Slack Θ = γ² for γ < 0, else 0 \[m\].
#[inline]
pub fn slack(gamma: f64) -> f64 {
    if gamma < 0.0 { gamma * gamma } else { 0.0 }
}

/// dτ/dγ.
#[inline]
pub fn tension_derivative(gamma: f64) -> f64 {
    if gamma >= 0.0 { 2.0 * gamma } else { 0.0 }
}

/// dΘ/dγ.
#[inline]
pub fn slack_derivative(gamma: f64) -> f64 {
    if gamma < 0.0 { 2.0 * gamma } else { 0.0 }
}

/// The γ that represents tension `tau` ≥ 0 (if positive) or else slack `theta` ≥ 0.
/// Both zero maps to a small positive γ: at γ = 0 the exact Jacobian column vanishes
/// (MODEL.md §9), so a start there would never move.
pub fn gamma_from(tau: f64, theta: f64) -> f64 {
    const GAMMA_FLOOR: f64 = 1e-3;
    if tau > 0.0 {
        tau.sqrt().max(GAMMA_FLOOR)
    } else if theta > 0.0 {
        -theta.sqrt().max(GAMMA_FLOOR)
    } else {
        GAMMA_FLOOR
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_match_finite_differences_on_both_sides() {
        for g in [-0.7, -0.01, 0.02, 1.3] {
            let h = 1e-6;
            let fd_t = (tension(g + h) - tension(g - h)) / (2.0 * h);
            let fd_s = (slack(g + h) - slack(g - h)) / (2.0 * h);
            assert!((fd_t - tension_derivative(g)).abs() < 1e-8);
            assert!((fd_s - slack_derivative(g)).abs() < 1e-8);
        }
    }

    #[test]
    fn gamma_round_trips() {
        assert!((tension(gamma_from(3.2, 0.0)) - 3.2).abs() < 1e-12);
        assert!((slack(gamma_from(0.0, 4.9e-4)) - 4.9e-4).abs() < 1e-15);
        assert!(gamma_from(0.0, 0.0) > 0.0);
    }
}

/// The variable a solver uses for each tendon's tension-or-slack.
///
/// - [`TendonUnknown::Gamma`]: the paper's γ (eqs. 6–7): τ = γ², Θ = γ² on either side;
///   C¹, but flat at γ = 0, so Newton converges slowly when a tendon is near the
///   taut/slack boundary (MODEL.md §9).
/// - [`TendonUnknown::Linear`]: ζ = γ|γ|, i.e. τ = max(ζ, 0), Θ = max(−ζ, 0). The same
///   solutions, piecewise linear: a semismooth Newton step moves a tendon across the
///   boundary in one step. Solvers use it internally and report γ.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TendonUnknown {
    /// γ of the paper.
    #[default]
    Gamma,
    /// ζ = γ|γ| \[N or m\].
    Linear,
}

impl TendonUnknown {
    /// Tension τ \[N\] for unknown `x`.
    #[inline]
    pub fn tension(self, x: f64) -> f64 {
        match self {
            Self::Gamma => tension(x),
            Self::Linear => x.max(0.0),
        }
    }

    /// Slack Θ \[m\] for unknown `x`.
    #[inline]
    pub fn slack(self, x: f64) -> f64 {
        match self {
            Self::Gamma => slack(x),
            Self::Linear => (-x).max(0.0),
        }
    }

    /// dτ/dx.
    #[inline]
    pub fn tension_derivative(self, x: f64) -> f64 {
        match self {
            Self::Gamma => tension_derivative(x),
            Self::Linear => {
                if x >= 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }

    /// dΘ/dx.
    #[inline]
    pub fn slack_derivative(self, x: f64) -> f64 {
        match self {
            Self::Gamma => slack_derivative(x),
            Self::Linear => {
                if x < 0.0 {
                    -1.0
                } else {
                    0.0
                }
            }
        }
    }

    /// This variable's value for the paper's γ.
    #[inline]
    pub fn from_gamma(self, gamma: f64) -> f64 {
        match self {
            Self::Gamma => gamma,
            Self::Linear => gamma * gamma.abs(),
        }
    }

    /// The paper's γ for this variable's value.
    #[inline]
    pub fn to_gamma(self, x: f64) -> f64 {
        match self {
            Self::Gamma => x,
            Self::Linear => x.signum() * x.abs().sqrt(),
        }
    }
}

#[cfg(test)]
mod unknown_tests {
    use super::*;

    #[test]
    fn both_variables_describe_the_same_tension_and_slack() {
        for g in [-0.3, -0.01, 0.0, 0.02, 1.7] {
            let z = TendonUnknown::Linear.from_gamma(g);
            assert!((TendonUnknown::Linear.tension(z) - tension(g)).abs() < 1e-15);
            assert!((TendonUnknown::Linear.slack(z) - slack(g)).abs() < 1e-15);
            assert!((TendonUnknown::Linear.to_gamma(z) - g).abs() < 1e-15);
        }
    }

    #[test]
    fn linear_derivatives_match_finite_differences_off_the_kink() {
        let u = TendonUnknown::Linear;
        for x in [-2.0, -0.1, 0.1, 3.0] {
            let h = 1e-6;
            assert!(
                ((u.tension(x + h) - u.tension(x - h)) / (2.0 * h) - u.tension_derivative(x)).abs()
                    < 1e-9
            );
            assert!(
                ((u.slack(x + h) - u.slack(x - h)) / (2.0 * h) - u.slack_derivative(x)).abs()
                    < 1e-9
            );
        }
    }
}
