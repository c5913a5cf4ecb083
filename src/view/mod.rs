//! Interactive 3D views as one self-contained HTML page each (feature `views`): the
//! plotly.js library (vendored, pinned: `vendor/plotly.js-dist-min`, MIT) is inlined, so
//! a page opens offline. Lengths are drawn in millimetres.
//!
//! Layout: [`page`] (a [`Figure`] of plotly traces and scenes, and the HTML around it),
//! [`robot`] (one solved configuration: legs, disks, tendons, bases, platform, gravity,
//! ellipsoids), [`cloud`] (a workspace map as a point cloud with the home
//! configuration inside) and `sketch` (feature `plots`: a static SVG of a configuration
//! in three orthographic views).

pub mod cloud;
pub mod page;
pub mod robot;
#[cfg(feature = "plots")]
pub mod sketch;

pub use cloud::workspace_figure;
pub use page::{Figure, html_page, write_page};
pub use robot::{RobotView, robot_figure, robots_figure};

/// Millimetres per metre: every length is drawn in mm.
pub const MM: f64 = 1000.0;
