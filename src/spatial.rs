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
