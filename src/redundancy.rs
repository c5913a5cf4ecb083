//! How the IK of the redundant (9-DoF) design chooses among its solutions: the old path
//! of [`Redundancy`] and [`Objective`], which live in [`crate::kinetostatics`] with the
//! step rules that use them.

pub use crate::kinetostatics::{Objective, Redundancy};
