//! Tension and slack from the unknown γ (MODEL.md eqs. 6–7), both C¹ in γ.

/// Tension τ = γ² for γ ≥ 0, else 0 [N].
#[inline]
pub fn tension(gamma: f64) -> f64 {
    if gamma >= 0.0 { gamma * gamma } else { 0.0 }
}

/// Slack Θ = γ² for γ < 0, else 0 [m].
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
