//! A static SVG of one configuration for papers (feature `plots`): three orthographic
//! views side by side (top xy, front xz, side yz) of the backbones, the taut and slack
//! tendons, the rigid links, the platform and the bases, on one scale in mm.

use nalgebra::Vector3;
use plotters::prelude::*;

use super::MM;
use super::robot::{bounding_box, leg_shapes, platform_corners, tendon_paths};
use crate::error::{PlotError, SolveError};
use crate::kinetostatics::RobotState;
use crate::model::Model;

/// One view: title, the world axes drawn horizontally and vertically, their names.
type View = (&'static str, (usize, usize), (&'static str, &'static str));

/// The three views.
const VIEWS: [View; 3] = [
    ("top", (0, 1), ("x", "y")),
    ("front", (0, 2), ("x", "z")),
    ("side", (1, 2), ("y", "z")),
];

/// The SVG document of `state`.
///
/// # Errors
/// [`PlotError::Draw`] if plotters fails; a leg that cannot be integrated (not for a
/// solved state) is reported the same way.
pub fn configuration_svg(model: &Model, state: &RobotState) -> Result<String, PlotError> {
    let draw = |e: &dyn std::fmt::Display| PlotError::Draw {
        name: "configuration",
        message: e.to_string(),
    };
    let shapes = leg_shapes(model, state).map_err(|e: SolveError| draw(&e))?;
    let platform = platform_corners(model, state);
    let backbones: Vec<Vec<Vector3<f64>>> = shapes.iter().map(super::robot::hermite).collect();
    let tendons = tendon_paths(model, state, &shapes);
    let bases: Vec<Vector3<f64>> = (0..3)
        .map(|i| model.base_frame(i, model.translation(i, &state.q)).position)
        .collect();
    // One scale for the three views: the cube around everything drawn.
    let (lo, hi) = bounding_box(backbones.iter().flatten().chain(&platform).chain(&bases));
    let centre = (lo + hi) / 2.0 * MM;
    let half = ((hi - lo).max() / 2.0 * MM * 1.1).max(1.0);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1500, 540)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| draw(&e))?;
        let p = state.position;
        let caption = format!(
            "platform at ({:.2}, {:.2}, {:.2}) mm; tendons: taut orange, slack grey",
            p[0] * MM,
            p[1] * MM,
            p[2] * MM
        );
        let root = root
            .titled(&caption, ("sans-serif", 18))
            .map_err(|e| draw(&e))?;
        let areas = root.split_evenly((1, 3));
        for (area, (title, (a, b), (na, nb))) in areas.iter().zip(VIEWS) {
            let mut chart = ChartBuilder::on(area)
                .caption(format!("{title} ({na}{nb})"), ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(48)
                .build_cartesian_2d(
                    centre[a] - half..centre[a] + half,
                    centre[b] - half..centre[b] + half,
                )
                .map_err(|e| draw(&e))?;
            chart
                .configure_mesh()
                .x_desc(format!("{na} [mm]"))
                .y_desc(format!("{nb} [mm]"))
                .draw()
                .map_err(|e| draw(&e))?;
            let project = |pts: &[Vector3<f64>]| -> Vec<(f64, f64)> {
                pts.iter().map(|p| (p[a] * MM, p[b] * MM)).collect()
            };
            let orange = RGBColor(230, 85, 13);
            for (path, taut) in &tendons {
                let style = if *taut {
                    orange.stroke_width(1)
                } else {
                    RGBColor(158, 158, 158).stroke_width(1)
                };
                chart
                    .draw_series(LineSeries::new(project(path), style))
                    .map_err(|e| draw(&e))?;
            }
            let blue = RGBColor(31, 78, 153);
            for (i, backbone) in backbones.iter().enumerate() {
                chart
                    .draw_series(LineSeries::new(project(backbone), blue.stroke_width(3)))
                    .map_err(|e| draw(&e))?;
                let tip = backbone.last().copied().unwrap_or_default();
                chart
                    .draw_series(LineSeries::new(
                        project(&[tip, platform[i]]),
                        blue.stroke_width(2),
                    ))
                    .map_err(|e| draw(&e))?;
            }
            let mut triangle = platform.clone();
            triangle.push(platform[0]);
            chart
                .draw_series(LineSeries::new(project(&triangle), BLACK.stroke_width(2)))
                .map_err(|e| draw(&e))?;
            chart
                .draw_series(project(&bases).into_iter().map(|c| {
                    Rectangle::new(
                        [(c.0 - 3.0, c.1 - 3.0), (c.0 + 3.0, c.1 + 3.0)],
                        RED.filled(),
                    )
                }))
                .map_err(|e| draw(&e))?;
        }
        root.present().map_err(|e| draw(&e))?;
    }
    Ok(svg)
}
