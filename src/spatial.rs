//! The value types every layer shares: a rigid [`Frame`] (and the platform [`Pose`],
//! the same type) and a [`Wrench`], in SI units and the world frame.

use nalgebra::{Matrix3, Vector3};

/// A rigid frame: position \[m\] and rotation (columns = frame axes in the world frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Origin in the world frame \[m\].
    pub position: Vector3<f64>,
    /// Orientation, body-to-world.
    pub rotation: Matrix3<f64>,
}

impl Frame {
    /// The world frame itself.
    pub fn identity() -> Self {
        Self {
            position: Vector3::zeros(),
            rotation: Matrix3::identity(),
        }
    }
}

/// Longest rotation vector accepted from users \[rad\]: 1000 rad is about 160 turns (a
/// rotation vector of a turn or less names every rotation); beyond about 1e154 rad per
/// component the vector's length overflows and the rotation became NaN.
pub const MAX_ROTVEC_NORM: f64 = 1e3;

/// The rule [`is_rotation_vector`] checks, for error messages.
pub const ROTVEC_RULE: &str = "finite numbers of length <= 1000 rad (a rotation vector)";

/// Whether `r` is a rotation vector to accept \[rad\]: finite, of length at most
/// [`MAX_ROTVEC_NORM`].
pub fn is_rotation_vector(r: &Vector3<f64>) -> bool {
    r.iter().all(|x| x.is_finite()) && r.norm() <= MAX_ROTVEC_NORM
}

/// A wrench (force \[N\], moment \[N·m\]), world frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Wrench {
    /// Force \[N\].
    pub force: Vector3<f64>,
    /// Moment \[N·m\].
    pub moment: Vector3<f64>,
}

/// A platform pose: position \[m\] and rotation (platform to world).
pub type Pose = Frame;

#[cfg(test)]
mod tests {
    use super::*;

    /// The rule's text states the bound, and the bound holds at its edge.
    #[test]
    fn rotation_vectors_up_to_the_bound_are_accepted() {
        assert!(ROTVEC_RULE.contains(&format!("<= {MAX_ROTVEC_NORM} rad")));
        assert!(is_rotation_vector(&Vector3::new(0.0, 0.0, MAX_ROTVEC_NORM)));
        assert!(!is_rotation_vector(&Vector3::new(
            0.0,
            0.0,
            1.001 * MAX_ROTVEC_NORM
        )));
        // Finite components whose length overflows.
        assert!(!is_rotation_vector(&Vector3::new(1e200, 0.0, 0.0)));
        assert!(!is_rotation_vector(&Vector3::new(f64::NAN, 0.0, 0.0)));
    }
}
