//! One leg: the tendon-driven Cosserat rod (MODEL.md §2) and its exact sensitivities (§5).

pub mod cold_guess;
pub mod integrate;
pub mod lanes;
pub mod ldlt6;
pub mod leg_model;
pub mod rhs;
pub mod slots;
pub mod tableau;
pub mod tangents;
pub mod tendon;

pub use crate::spatial::{Frame, Wrench};
pub use integrate::{
    LegEnd, LegScratch, LegSensitivities, LegShape, LegStart, LegsScratch, MAX_DIRECTIONS,
    MAX_LEGS, ShapeDetail, integrate_leg, integrate_leg_with_sensitivities, integrate_legs,
};
pub use leg_model::LegModel;
