//! One solved configuration as plotly traces: each leg as a tube along its computed
//! backbone (cubic Hermite through the disk frames) with its disks, the tendons through
//! their disk holes (taut solid, slack dashed), the bases on their actuation rails, the
//! rigid links to the platform, the platform and its frame, the gravity direction and,
//! optionally, ellipsoids at the platform. Lengths in mm.

use nalgebra::{Matrix3, Vector3};
use serde_json::{Value, json};

use super::MM;
use super::page::Figure;
use crate::analysis::Ellipsoid;
use crate::boundary::leg_start;
use crate::error::SolveError;
use crate::kinetostatics::RobotState;
use crate::model::Model;
use crate::rod::tendon::{TendonUnknown, tension};
use crate::rod::{LegEnd, LegScratch, LegShape, integrate_leg};

/// Points of a polyline per Hermite segment between two disk frames.
const SUBDIVISIONS: usize = 8;
/// Points of a disk outline.
const CIRCLE_POINTS: usize = 25;

/// An ellipsoid to draw at the platform centre, scaled to the robot's size.
#[derive(Debug, Clone, PartialEq)]
pub struct EllipsoidView {
    /// Legend name, e.g. "J_p".
    pub name: String,
    /// Unit of the semi-axes, e.g. "m/m".
    pub unit: String,
    /// The ellipsoid.
    pub ellipsoid: Ellipsoid,
    /// Colour (CSS).
    pub color: String,
}

/// What to draw of one configuration.
#[derive(Debug, Clone, Copy)]
pub struct RobotView<'a> {
    /// The robot.
    pub model: &'a Model,
    /// The solved configuration.
    pub state: &'a RobotState,
    /// Ellipsoids at the platform (may be empty).
    pub ellipsoids: &'a [EllipsoidView],
}

/// A figure with one scene showing `view`.
///
/// # Errors
/// [`SolveError::NonFinite`] if a leg integration blows up (not for a solved state).
pub fn robot_figure(title: &str, view: &RobotView) -> Result<Figure, SolveError> {
    robots_figure(title, &[(title, *view)])
}

/// A figure with one scene per (scene title, view), side by side, sharing one legend
/// (toggling a layer toggles it in every scene).
///
/// # Errors
/// As [`robot_figure`].
pub fn robots_figure(title: &str, views: &[(&str, RobotView)]) -> Result<Figure, SolveError> {
    let mut figure = Figure::new(title);
    for (k, (scene_title, view)) in views.iter().enumerate() {
        let scene = figure.add_scene(*scene_title);
        figure.traces.extend(robot_traces(view, &scene, k == 0)?);
    }
    Ok(figure)
}

/// The traces of `view` in scene `scene`; `legend`: list them in the legend (false for
/// a second view of the same kinds, which shares the first one's legend groups).
///
/// # Errors
/// As [`robot_figure`].
pub fn robot_traces(view: &RobotView, scene: &str, legend: bool) -> Result<Vec<Value>, SolveError> {
    let model = view.model;
    let state = view.state;
    let shapes = leg_shapes(model, state)?;
    let pose = state.pose();
    let platform = platform_corners(model, state);
    let size = platform_size(model);
    let mut traces = Vec::new();
    let mut add = |t: Value, group: &str| traces.push(placed(t, scene, group, legend));

    let mut backbone = Polyline::default();
    let mut disks = Polyline::default();
    let mut links = Polyline::default();
    for (i, shape) in shapes.iter().enumerate() {
        backbone.extend(hermite(shape));
        for (p, r) in shape.positions.iter().zip(&shape.rotations).skip(1) {
            disks.extend(circle(p, r, model.leg.disk_radius));
        }
        let tip = shape.positions.last().copied().unwrap_or_default();
        links.extend([tip, platform[i]]);
    }
    add(backbone.trace("legs (backbone)", "#1f4e99", 9.0), "legs");
    add(disks.trace("disks", "#555555", 3.0), "disks");
    add(links.trace("rigid links L_c", "#1f4e99", 4.0), "links");

    let (taut, slack) = tendon_traces(model, state, &shapes);
    add(taut, "taut");
    add(slack, "slack");

    let mut rails = Polyline::default();
    let mut bases = Vec::new();
    let mut base_text = Vec::new();
    let limit = model.limits.base_translation;
    for i in 0..3 {
        let q_t = model.translation(i, &state.q);
        let (lo, hi) = (model.base_frame(i, -limit), model.base_frame(i, limit));
        rails.extend([lo.position, hi.position]);
        bases.push(model.base_frame(i, q_t).position);
        let per_leg = model.pairs + 1;
        let q: Vec<String> = state.q[i * per_leg..(i + 1) * per_leg]
            .iter()
            .map(|x| format!("{:.2}", x * MM))
            .collect();
        base_text.push(format!(
            "leg {}: q = [{}] mm (bending pairs, translation)",
            i + 1,
            q.join(", ")
        ));
    }
    add(
        rails.trace("actuation rails (±limit)", "#999999", 3.0),
        "rails",
    );
    add(
        markers(&bases, "bases (actuated)", "#d62728", &base_text),
        "bases",
    );

    add(
        json!({
            "type": "mesh3d", "name": "platform",
            "x": coords(&platform, 0), "y": coords(&platform, 1), "z": coords(&platform, 2),
            "i": [0], "j": [1], "k": [2], "color": "#7fb3d5", "opacity": 0.7,
            "hovertext": format!("platform at ({:.2}, {:.2}, {:.2}) mm",
                pose.position.x * MM, pose.position.y * MM, pose.position.z * MM),
            "hoverinfo": "text",
        }),
        "platform",
    );
    for (k, (axis, color)) in ["x", "y", "z"]
        .iter()
        .zip(["#d62728", "#2ca02c", "#1f77b4"])
        .enumerate()
    {
        let tip = pose.position + pose.rotation.column(k) * (0.6 * size);
        let mut t = Polyline::default();
        t.extend([pose.position, tip]);
        let name = match k {
            0 => "platform frame (x red, y green, z blue)".to_owned(),
            _ => format!("platform frame {axis}"),
        };
        // One legend entry for the three axes.
        add(
            placed(t.trace(&name, color, 6.0), scene, "frame", legend && k == 0),
            "frame",
        );
    }

    if let Some(g) = gravity_direction(model) {
        let start = gravity_anchor(&shapes, &platform) - g * size;
        let end = start + g * size;
        let mut line = Polyline::default();
        line.extend([start, end]);
        add(line.trace("gravity", "#000000", 5.0), "gravity");
        traces.push(json!({
            "type": "cone", "scene": scene, "legendgroup": "gravity", "showlegend": false,
            "name": "gravity", "x": [end.x * MM], "y": [end.y * MM], "z": [end.z * MM],
            "u": [g.x], "v": [g.y], "w": [g.z], "anchor": "tip", "sizemode": "absolute",
            "sizeref": 0.25 * size * MM, "showscale": false,
            "colorscale": [[0, "#000000"], [1, "#000000"]], "hoverinfo": "name",
        }));
    }

    for e in view.ellipsoids {
        traces.push(placed(
            ellipsoid_trace(e, &pose.position, size),
            scene,
            &e.name,
            legend,
        ));
    }
    Ok(traces)
}

/// `trace` in scene `scene`, legend group `group`, listed in the legend or not.
fn placed(mut trace: Value, scene: &str, group: &str, legend: bool) -> Value {
    if trace.get("showlegend").is_none() {
        trace["showlegend"] = json!(legend);
    }
    trace["scene"] = json!(scene);
    trace["legendgroup"] = json!(group);
    trace
}

/// The backbone frames at the base and every disk of each leg.
pub(super) fn leg_shapes(model: &Model, state: &RobotState) -> Result<[LegShape; 3], SolveError> {
    let mut scratch = LegScratch::new();
    let mut end = LegEnd::zeros();
    let mut shapes: [LegShape; 3] = Default::default();
    for (i, shape) in shapes.iter_mut().enumerate() {
        let start = leg_start(model, i, &state.q, &state.y_u, TendonUnknown::Gamma);
        integrate_leg(&model.leg, &start, &mut scratch, &mut end, Some(shape))?;
    }
    Ok(shapes)
}

/// The path of every tendon through its disk holes (base hole first) and whether it is
/// taut (tension > 0), legs in order, then tendons, with its hover label.
#[cfg_attr(not(feature = "plots"), allow(dead_code))]
pub(super) fn tendon_paths(
    model: &Model,
    state: &RobotState,
    shapes: &[LegShape; 3],
) -> Vec<(Vec<Vector3<f64>>, bool)> {
    tendon_paths_labelled(model, state, shapes)
        .into_iter()
        .map(|(path, taut, _)| (path, taut))
        .collect()
}

/// As [`tendon_paths`], each with its hover label.
fn tendon_paths_labelled(
    model: &Model,
    state: &RobotState,
    shapes: &[LegShape; 3],
) -> Vec<(Vec<Vector3<f64>>, bool, String)> {
    let nu = model.n_leg_unknowns();
    let mut out = Vec::new();
    for (i, shape) in shapes.iter().enumerate() {
        for k in 0..model.n_tendons() {
            let tau = tension(state.y_u[i * nu + k]);
            let offset = model.leg.tendon_offsets[k];
            let end = model.leg.tendon_ends[k];
            let path: Vec<Vector3<f64>> = shape
                .arcs
                .iter()
                .zip(shape.positions.iter().zip(&shape.rotations))
                .take_while(|(s, _)| **s <= end * (1.0 + 1e-9) + 1e-12)
                .map(|(_, (p, r))| p + r * offset)
                .collect();
            let label = format!("leg {} tendon {}: τ = {:.3} N", i + 1, k + 1, tau);
            out.push((path, tau > 0.0, label));
        }
    }
    out
}

/// The tendons of the three legs through their disk holes: one trace of the taut ones
/// (tension > 0, solid) and one of the slack ones (dashed), hover text with the tension.
fn tendon_traces(model: &Model, state: &RobotState, shapes: &[LegShape; 3]) -> (Value, Value) {
    let (mut taut, mut slack) = (Polyline::default(), Polyline::default());
    let (mut taut_text, mut slack_text) = (Vec::new(), Vec::new());
    for (path, is_taut, label) in tendon_paths_labelled(model, state, shapes) {
        let (line, text) = if is_taut {
            (&mut taut, &mut taut_text)
        } else {
            (&mut slack, &mut slack_text)
        };
        text.extend(std::iter::repeat_n(json!(label), path.len()));
        text.push(Value::Null);
        line.extend(path);
    }
    let mut t = taut.trace("tendons, taut (τ > 0)", "#e6550d", 4.0);
    t["text"] = Value::Array(taut_text);
    t["hoverinfo"] = json!("text");
    let mut s = slack.trace("tendons, slack (τ = 0)", "#9e9e9e", 3.0);
    s["line"]["dash"] = json!("dash");
    s["text"] = Value::Array(slack_text);
    s["hoverinfo"] = json!("text");
    (t, s)
}

/// The platform's circumradius \[m\] (at least 1 mm): the scale of arrows and ellipsoids.
/// The platform's coupling points in the world frame at `state` \[m\].
pub(super) fn platform_corners(model: &Model, state: &RobotState) -> Vec<Vector3<f64>> {
    let pose = state.pose();
    model
        .coupling_points
        .iter()
        .map(|c| pose.position + pose.rotation * c)
        .collect()
}

fn platform_size(model: &Model) -> f64 {
    model
        .coupling_points
        .iter()
        .map(|c| c.norm())
        .fold(1e-3, f64::max)
}

/// Unit gravity direction, if the robot has weight.
fn gravity_direction(model: &Model) -> Option<Vector3<f64>> {
    let g = if model.platform_weight.norm() > 0.0 {
        model.platform_weight
    } else {
        model.leg.weight_per_length
    };
    g.try_normalize(0.0)
}

/// The smallest and the largest coordinates of `points` (±∞ for none).
pub(super) fn bounding_box<'a>(
    points: impl IntoIterator<Item = &'a Vector3<f64>>,
) -> (Vector3<f64>, Vector3<f64>) {
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (lo, hi)
}

/// Where the gravity arrow ends: beside the robot, level with the platform.
fn gravity_anchor(shapes: &[LegShape; 3], platform: &[Vector3<f64>]) -> Vector3<f64> {
    let (lo, hi) = bounding_box(shapes.iter().flat_map(|s| &s.positions).chain(platform));
    Vector3::new(
        hi.x + 0.1 * (hi.x - lo.x),
        (lo.y + hi.y) / 2.0,
        (lo.z + hi.z) / 2.0,
    )
}

/// A mesh of `e` centred at `centre` \[m\], its largest semi-axis drawn as 0.5 × `size`;
/// the scale is in the legend name.
fn ellipsoid_trace(e: &EllipsoidView, centre: &Vector3<f64>, size: f64) -> Value {
    let el = &e.ellipsoid;
    let largest = el.semi_axes[0];
    let scale = if largest > 0.0 && largest.is_finite() {
        0.5 * size / largest
    } else {
        0.0
    };
    let a = Matrix3::from_columns(
        &[0, 1, 2].map(|k| Vector3::from(el.directions[k]) * el.semi_axes[k] * scale),
    );
    let (rings, around) = (12usize, 24usize);
    let mut vertices = Vec::new();
    for r in 0..=rings {
        let theta = std::f64::consts::PI * r as f64 / rings as f64;
        for s in 0..around {
            let phi = std::f64::consts::TAU * s as f64 / around as f64;
            let u = Vector3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            vertices.push(centre + a * u);
        }
    }
    let (mut i, mut j, mut k) = (Vec::new(), Vec::new(), Vec::new());
    for r in 0..rings {
        for s in 0..around {
            let v = |r: usize, s: usize| r * around + s % around;
            i.extend([v(r, s), v(r, s)]);
            j.extend([v(r + 1, s), v(r + 1, s + 1)]);
            k.extend([v(r + 1, s + 1), v(r, s + 1)]);
        }
    }
    let axes: Vec<String> = el.semi_axes.iter().map(|x| format!("{:.3e}", x)).collect();
    let mm_per_unit = if scale > 0.0 { scale * MM } else { 0.0 };
    json!({
        "type": "mesh3d",
        "name": format!("{} ellipsoid (1 {} drawn as {:.3e} mm)", e.name, e.unit, mm_per_unit),
        "x": coords(&vertices, 0), "y": coords(&vertices, 1), "z": coords(&vertices, 2),
        "i": i, "j": j, "k": k, "color": e.color, "opacity": 0.35,
        "hovertext": format!("{}: semi-axes {} {}", e.name, axes.join(", "), e.unit),
        "hoverinfo": "text",
    })
}

/// Points of a line trace; a `None` gap separates pieces.
#[derive(Default)]
struct Polyline(Vec<Option<Vector3<f64>>>);

impl Polyline {
    /// Appends one piece.
    fn extend(&mut self, piece: impl IntoIterator<Item = Vector3<f64>>) {
        self.0.extend(piece.into_iter().map(Some));
        self.0.push(None);
    }

    /// A scatter3d line trace, coordinates in mm (0.01 mm resolution).
    fn trace(&self, name: &str, color: &str, width: f64) -> Value {
        let axis = |a: usize| -> Vec<Value> {
            self.0
                .iter()
                .map(|p| match p {
                    Some(p) => json!(mm(p[a])),
                    None => Value::Null,
                })
                .collect()
        };
        json!({
            "type": "scatter3d", "mode": "lines", "name": name,
            "x": axis(0), "y": axis(1), "z": axis(2),
            "line": {"color": color, "width": width}, "connectgaps": false,
            "hoverinfo": "name",
        })
    }
}

/// Marker trace with hover texts.
fn markers(points: &[Vector3<f64>], name: &str, color: &str, text: &[String]) -> Value {
    json!({
        "type": "scatter3d", "mode": "markers", "name": name,
        "x": coords(points, 0), "y": coords(points, 1), "z": coords(points, 2),
        "marker": {"color": color, "size": 7, "symbol": "square"},
        "text": text, "hoverinfo": "text",
    })
}

/// Coordinate `a` of `points` in mm.
fn coords(points: &[Vector3<f64>], a: usize) -> Vec<f64> {
    points.iter().map(|p| mm(p[a])).collect()
}

/// Metres to mm, 0.01 mm resolution (sub-micrometre digits only lengthen the page).
fn mm(x: f64) -> f64 {
    if x.is_finite() {
        (x * MM * 100.0).round() / 100.0
    } else {
        0.0
    }
}

/// The backbone through the frames of `shape`: cubic Hermite segments whose end tangents
/// are the frames' z-axes (the rod is inextensible enough for unit-speed tangents).
pub(super) fn hermite(shape: &LegShape) -> Vec<Vector3<f64>> {
    let mut out = Vec::new();
    let frames = shape.positions.iter().zip(&shape.rotations);
    let pairs = frames
        .clone()
        .zip(frames.skip(1))
        .zip(shape.arcs.windows(2));
    for (((p0, r0), (p1, r1)), arcs) in pairs {
        let h = arcs[1] - arcs[0];
        let (t0, t1) = (r0.column(2) * h, r1.column(2) * h);
        for s in 0..SUBDIVISIONS {
            let t = s as f64 / SUBDIVISIONS as f64;
            let (t2, t3) = (t * t, t * t * t);
            out.push(
                p0 * (2.0 * t3 - 3.0 * t2 + 1.0)
                    + t0 * (t3 - 2.0 * t2 + t)
                    + p1 * (-2.0 * t3 + 3.0 * t2)
                    + t1 * (t3 - t2),
            );
        }
    }
    if let Some(last) = shape.positions.last() {
        out.push(*last);
    }
    out
}

/// The outline of a disk of `radius` centred at `p` in the xy-plane of frame `r`.
fn circle(p: &Vector3<f64>, r: &Matrix3<f64>, radius: f64) -> Vec<Vector3<f64>> {
    (0..CIRCLE_POINTS)
        .map(|k| {
            let phi = std::f64::consts::TAU * k as f64 / (CIRCLE_POINTS - 1) as f64;
            p + (r.column(0) * phi.cos() + r.column(1) * phi.sin()) * radius
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinetostatics::Solver;
    use crate::rod::Wrench;

    fn solved(q: &[f64]) -> (Solver, RobotState) {
        let design = crate::Tdpcr::from_ron_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/designs/lilge2022.ron"
        ))
        .unwrap();
        let mut solver = Solver::new(&design).unwrap();
        let sol = solver.solve_fk(q, &Wrench::default(), None).unwrap();
        (solver, sol.state)
    }

    /// The points of a line trace, pieces split at the gaps, in mm.
    fn pieces(t: &Value) -> Vec<Vec<[f64; 3]>> {
        let (x, y, z) = (t["x"].as_array().unwrap(), &t["y"], &t["z"]);
        let mut out = vec![Vec::new()];
        for (i, xi) in x.iter().enumerate() {
            match xi.as_f64() {
                Some(xv) => out.last_mut().unwrap().push([
                    xv,
                    y[i].as_f64().unwrap(),
                    z[i].as_f64().unwrap(),
                ]),
                None => out.push(Vec::new()),
            }
        }
        out.retain(|p| !p.is_empty());
        out
    }

    fn named<'a>(traces: &'a [Value], prefix: &str) -> &'a Value {
        traces
            .iter()
            .find(|t| t["name"].as_str().unwrap_or("").starts_with(prefix))
            .unwrap_or_else(|| panic!("no trace {prefix}"))
    }

    #[test]
    fn legs_run_from_their_bases_to_the_platform_and_tendons_split_by_tension() {
        let (solver, state) = solved(&[0.004, 0.02, -0.003, -0.01, 0.002, 0.03]);
        let model = solver.model();
        let view = RobotView {
            model,
            state: &state,
            ellipsoids: &[],
        };
        let traces = robot_traces(&view, "scene", true).unwrap();
        let legs = pieces(named(&traces, "legs"));
        assert_eq!(legs.len(), 3);
        let links = pieces(named(&traces, "rigid links"));
        let pose = state.pose();
        for i in 0..3 {
            let base = model.base_frame(i, model.translation(i, &state.q)).position * MM;
            let start = Vector3::from(legs[i][0]);
            assert!((start - base).norm() < 0.02, "leg {i} starts at its base");
            // The backbone ends where the rigid link starts; the link ends at the platform.
            assert_eq!(legs[i].last(), links[i].first());
            let c = (pose.position + pose.rotation * model.coupling_points[i]) * MM;
            assert!((Vector3::from(links[i][1]) - c).norm() < 0.02);
            // Backbone length ≈ L (inextensible enough): the polyline is no shorter.
            let len: f64 = legs[i]
                .windows(2)
                .map(|w| (Vector3::from(w[1]) - Vector3::from(w[0])).norm())
                .sum();
            let l = model.leg.length * MM;
            assert!((len - l).abs() < 0.01 * l, "leg {i}: {len} mm vs {l} mm");
        }
        let taut = pieces(named(&traces, "tendons, taut"));
        let slack = pieces(named(&traces, "tendons, slack"));
        let tensions: Vec<f64> = model
            .tendon_unknown_indices()
            .map(|k| tension(state.y_u[k]))
            .collect();
        assert_eq!(taut.len(), tensions.iter().filter(|t| **t > 0.0).count());
        assert_eq!(taut.len() + slack.len(), 3 * model.n_tendons());
        // Every tendon piece runs through the base hole and one hole per disk it passes.
        for p in taut.iter().chain(&slack) {
            assert!(
                p.len() >= 2 && p.len() <= model.leg.n_disks + 1,
                "{}",
                p.len()
            );
        }
        assert_eq!(pieces(named(&traces, "disks")).len(), 3 * model.leg.n_disks);
    }

    #[test]
    fn an_ellipsoid_mesh_has_its_semi_axes_in_proportion() {
        let e = EllipsoidView {
            name: "J_p".into(),
            unit: "m/m".into(),
            ellipsoid: Ellipsoid {
                semi_axes: [2.0, 1.0, 0.5],
                directions: [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            },
            color: "green".into(),
        };
        let t = ellipsoid_trace(&e, &Vector3::zeros(), 0.01);
        let max = |a: &str| {
            t[a].as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap().abs())
                .fold(0.0, f64::max)
        };
        // Largest semi-axis (along z) drawn as 0.5 × 10 mm; the others in proportion.
        assert!((max("z") - 5.0).abs() < 0.01, "{}", max("z"));
        assert!((max("x") - 2.5).abs() < 0.05, "{}", max("x"));
        assert!((max("y") - 1.25).abs() < 0.05, "{}", max("y"));
        let name = t["name"].as_str().unwrap();
        assert!(name.contains("1 m/m drawn as 2.500e0 mm"), "{name}");
    }
}
