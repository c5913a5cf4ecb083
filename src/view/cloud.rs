//! A workspace map as a point cloud: the reachable cells (at their centres) coloured by
//! a measure chosen in a dropdown (rcond of J_p, J_o, C_p, C_o as the paper, minimum
//! tendon tension), the near-singular (Type I, Type II, leg), colliding and unstable
//! cells as layers toggled in the legend, and the home configuration drawn inside.

use rayon::prelude::*;
use serde_json::{Value, json};

use super::MM;
use super::page::{Figure, round_significant};
use super::robot::{RobotView, robot_traces};
use crate::error::SolveError;
use crate::kinetostatics::RobotState;
use crate::model::Model;
use crate::workspace::{WorkspaceMap, WorkspacePoint};

/// Significant digits of the colour values (the colour scale resolves fewer).
const DIGITS: usize = 3;

/// A measure the reachable cells can be coloured by.
struct Measure {
    /// Dropdown label and colour-bar title.
    label: &'static str,
    /// Its value at a cell.
    value: fn(&WorkspacePoint) -> f64,
}

/// A toggled layer of cells: legend name, colour, which cells, shown at first.
type Layer = (
    &'static str,
    &'static str,
    fn(&WorkspacePoint) -> bool,
    bool,
);

const MEASURES: [Measure; 5] = [
    Measure {
        label: "rcond J_p",
        value: |p| p.metrics.rcond.j_p,
    },
    Measure {
        label: "rcond J_o",
        value: |p| p.metrics.rcond.j_o,
    },
    Measure {
        label: "rcond C_p",
        value: |p| p.metrics.rcond.c_p,
    },
    Measure {
        label: "rcond C_o",
        value: |p| p.metrics.rcond.c_o,
    },
    Measure {
        label: "min tension [N]",
        value: |p| p.metrics.min_tension,
    },
];

/// The workspace page's figure: the cloud of `map` and, if given, the configuration
/// `home` of `model` inside it.
///
/// # Errors
/// [`SolveError::NonFinite`] if a leg of `home` cannot be integrated (not for a solved
/// state).
pub fn workspace_figure(
    map: &WorkspaceMap,
    model: &Model,
    home: Option<&RobotState>,
) -> Result<Figure, SolveError> {
    let s = &map.summary;
    let title = format!(
        "Workspace: {} reachable cells of Δ = {} mm ({:.3} L)",
        s.counts.reachable,
        map.settings.step * MM,
        s.volume.reachable * 1e3
    );
    let mut figure = Figure::new(title);
    // The colour bar stands left of the scene, not over its axis labels.
    figure.inset_left = 0.1;
    let scene = figure.add_scene("workspace");
    let step = map.settings.step;
    let reachable: Vec<&WorkspacePoint> = map.points.iter().filter(|p| p.reachable()).collect();
    let size = if map.points.len() > 20_000 { 2.0 } else { 4.0 };

    // Each measure's colours once, the cells in parallel (a million values rounded for
    // the reference design's Δ = 3 mm map).
    let colours: Vec<Vec<f64>> = MEASURES
        .iter()
        .map(|m| {
            reachable
                .par_iter()
                .map(|p| round_significant((m.value)(p), DIGITS))
                .collect()
        })
        .collect();
    let mut cloud = cell_trace(&reachable, step, "reachable cells", &scene, size);
    cloud["marker"] = json!({
        "size": size, "color": colours[0], "colorscale": "Viridis",
        "showscale": true,
        "colorbar": {"title": {"text": MEASURES[0].label}, "x": 0.0, "xanchor": "left", "len": 0.6},
    });
    cloud["hovertemplate"] =
        "(%{x}, %{y}, %{z}) mm<br>%{marker.color:.3g}<extra>reachable</extra>".into();
    figure.traces.push(cloud);
    figure.menus.push(json!({
        "type": "dropdown", "x": 0.0, "xanchor": "left", "y": 1.0, "yanchor": "top",
        "showactive": true,
        "buttons": MEASURES.iter().zip(&colours).map(|(m, c)| json!({
            "label": format!("colour: {}", m.label), "method": "restyle",
            "args": [{"marker.color": [c], "marker.colorbar.title.text": m.label}, [0]],
        })).collect::<Vec<_>>(),
    }));

    let layers: [Layer; 5] = [
        (
            "near Type I singularity",
            "#ff7f0e",
            |p| p.reachable() && p.metrics.singularity.type_i,
            false,
        ),
        (
            "near Type II singularity",
            "#d62728",
            |p| p.reachable() && p.metrics.singularity.type_ii,
            false,
        ),
        (
            "near leg singularity",
            "#9467bd",
            |p| p.reachable() && p.metrics.singularity.leg,
            false,
        ),
        ("colliding", "#7f7f7f", |p| p.collision, true),
        (
            "unstable",
            "#e377c2",
            |p| !p.collision && !p.metrics.stable,
            true,
        ),
    ];
    for (name, colour, keep, visible) in layers {
        let cells: Vec<&WorkspacePoint> = map.points.iter().filter(|p| keep(p)).collect();
        let mut t = cell_trace(
            &cells,
            step,
            &format!("{name} ({})", cells.len()),
            &scene,
            size,
        );
        t["marker"] = json!({"size": size + 1.0, "color": colour});
        t["visible"] = if visible {
            json!(true)
        } else {
            json!("legendonly")
        };
        figure.traces.push(t);
    }
    if let Some(home) = home {
        let view = RobotView {
            model,
            state: home,
            ellipsoids: &[],
        };
        let mut robot = robot_traces(&view, &scene, true)?;
        for t in &mut robot {
            if let Some(name) = t["name"].as_str() {
                t["name"] = json!(format!("home: {name}"));
            }
        }
        figure.traces.extend(robot);
    }
    Ok(figure)
}

/// A marker trace of `cells` at their centres (i Δ, j Δ, k Δ) in mm.
fn cell_trace(cells: &[&WorkspacePoint], step: f64, name: &str, scene: &str, size: f64) -> Value {
    let axis = |a: usize| -> Vec<f64> {
        cells
            .iter()
            .map(|p| (p.cell[a] as f64 * step * MM * 100.0).round() / 100.0)
            .collect()
    };
    json!({
        "type": "scatter3d", "mode": "markers", "name": name, "scene": scene,
        "x": axis(0), "y": axis(1), "z": axis(2),
        "marker": {"size": size},
        "hovertemplate": "(%{x}, %{y}, %{z}) mm",
    })
}
