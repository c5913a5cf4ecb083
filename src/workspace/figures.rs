//! Slice figures of a workspace map (SVG, plotters), at the planes nearest to
//! z = −0.06, 0 and 0.06 m (the paper's slices) that hold cells:
//!
//! - `reach_z<z>.svg`: reachable (grey), near a leg singularity (orange: the lines of
//!   Fig. 9 where a tendon pair changes its taut side), near a Type II singularity (red),
//!   collision (blue), unstable with the actuators held (black), like the paper's Fig. 7;
//! - `rcond_z<z>.svg`: heat maps of rcond of J_p, J_o, C_p, C_o (linear) and of
//!   \[B_q B_u\], \[B_x B_u\], B_u (log10, raw SI), like Fig. 9 (top, middle);
//! - `tension_z<z>.svg`: the tendon tensions of leg 1, one panel per tendon, like Fig. 9
//!   (bottom left).
//!
//! `<z>` is the plane's z in metres with sign and three decimals, e.g. `reach_z-0.060.svg`.
//! Every panel shows the cells of the slice as Δ × Δ squares; axes in mm.

use plotters::prelude::*;

use crate::workspace::{Rconds, WorkspaceMap, WorkspacePoint};

/// The paper's slice heights \[m\].
pub const SLICE_HEIGHTS: [f64; 3] = [-0.06, 0.0, 0.06];

const PANEL: u32 = 360;
const GREY: RGBColor = RGBColor(176, 176, 176);
const TYPE_II_RED: RGBColor = RGBColor(214, 39, 40);
const COLLISION_BLUE: RGBColor = RGBColor(31, 119, 180);
const LEG_ORANGE: RGBColor = RGBColor(255, 127, 14);
const UNSTABLE_BLACK: RGBColor = RGBColor(0, 0, 0);

/// (file name, SVG text) of every figure, for each slice of [`SLICE_HEIGHTS`] with cells.
pub fn slice_figures(map: &WorkspaceMap) -> Vec<(String, String)> {
    let step = map.settings.step;
    let extent = map
        .points
        .iter()
        .flat_map(|p| [p.position[0].abs(), p.position[1].abs()])
        .fold(0.0f64, f64::max)
        * 1e3
        + step * 1e3;
    let mut out = Vec::new();
    let mut done = Vec::new();
    for z in SLICE_HEIGHTS {
        let k = (z / step).round() as i64;
        if done.contains(&k) {
            continue;
        }
        done.push(k);
        let cells: Vec<&WorkspacePoint> = map.plane(k).collect();
        if cells.is_empty() {
            continue;
        }
        let tag = format!("z{:+.3}", k as f64 * step);
        let frame = Frame {
            extent,
            step: step * 1e3,
        };
        out.push((
            format!("reach_{tag}.svg"),
            reach_figure(&cells, &frame, &tag),
        ));
        out.push((
            format!("rcond_{tag}.svg"),
            rcond_figure(&cells, &frame, &tag),
        ));
        out.push((
            format!("tension_{tag}.svg"),
            tension_figure(&cells, &frame, &tag, map.tendons_per_leg),
        ));
    }
    out
}

/// Common axes of all panels: ±extent \[mm\], cell side \[mm\].
struct Frame {
    extent: f64,
    step: f64,
}

/// One panel: title, and a colour per cell (None: not drawn).
type Panel<'a> = (String, Vec<(&'a WorkspacePoint, RGBColor)>);

/// Renders panels in a grid of `cols` columns with an optional footer line.
fn render(panels: &[Panel], cols: usize, frame: &Frame, footer: &str) -> String {
    let rows = panels.len().div_ceil(cols);
    let footer_h = if footer.is_empty() { 0 } else { 30 };
    let size = (PANEL * cols as u32, PANEL * rows as u32 + footer_h);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        // Drawing into a String cannot fail for I/O reasons; an error only loses a figure.
        let _ = draw(&root, panels, rows, cols, frame, footer, footer_h);
        let _ = root.present();
    }
    svg
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

fn draw(
    root: &Area,
    panels: &[Panel],
    rows: usize,
    cols: usize,
    frame: &Frame,
    footer: &str,
    footer_h: u32,
) -> Result<(), Box<dyn std::error::Error>> {
    root.fill(&WHITE)?;
    let (body, foot) = root.split_vertically(root.dim_in_pixel().1 - footer_h);
    if footer_h > 0 {
        foot.draw(&Text::new(
            footer.to_string(),
            (10, 8),
            ("sans-serif", 14).into_font(),
        ))?;
    }
    let areas = body.split_evenly((rows, cols));
    let (e, h) = (frame.extent, frame.step / 2.0);
    for ((title, cells), area) in panels.iter().zip(areas.iter()) {
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 15))
            .margin(6)
            .x_label_area_size(32)
            .y_label_area_size(44)
            .build_cartesian_2d(-e..e, -e..e)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x [mm]")
            .y_desc("y [mm]")
            .x_labels(5)
            .y_labels(5)
            .draw()?;
        chart.draw_series(cells.iter().map(|(p, c)| {
            let (x, y) = (p.cell[0] as f64 * frame.step, p.cell[1] as f64 * frame.step);
            Rectangle::new([(x - h, y - h), (x + h, y + h)], c.filled())
        }))?;
    }
    Ok(())
}

fn reach_figure(cells: &[&WorkspacePoint], frame: &Frame, tag: &str) -> String {
    let colour = |p: &WorkspacePoint| {
        if !p.metrics.stable {
            UNSTABLE_BLACK
        } else if p.collision {
            COLLISION_BLUE
        } else if p.metrics.singularity.type_ii {
            TYPE_II_RED
        } else if p.metrics.singularity.leg {
            LEG_ORANGE
        } else {
            GREY
        }
    };
    let n = |f: &dyn Fn(&WorkspacePoint) -> bool| cells.iter().filter(|p| f(p)).count();
    let title = format!(
        "{tag}: reachable {} / near Type II {} / leg {} / collision {} / unstable {}",
        n(&|p| p.reachable()),
        n(&|p| p.reachable() && p.metrics.singularity.type_ii),
        n(&|p| p.reachable() && p.metrics.singularity.leg),
        n(&|p| p.collision && p.metrics.stable),
        n(&|p| !p.metrics.stable)
    );
    let panel = (title, cells.iter().map(|p| (*p, colour(p))).collect());
    render(
        &[panel],
        1,
        frame,
        "grey: reachable, orange: near a leg singularity, red: near Type II, blue: collision, black: unstable",
    )
}

fn rcond_figure(cells: &[&WorkspacePoint], frame: &Frame, tag: &str) -> String {
    type Pick = fn(&Rconds) -> f64;
    let measures: [(&str, Pick, bool); 7] = [
        ("J_p", |r| r.j_p, false),
        ("J_o", |r| r.j_o, false),
        ("C_p", |r| r.c_p, false),
        ("C_o", |r| r.c_o, false),
        ("[B_q B_u]", |r| r.b_qu, true),
        ("[B_x B_u]", |r| r.b_xu, true),
        ("B_u", |r| r.b_u, true),
    ];
    let reachable: Vec<&WorkspacePoint> = cells.iter().copied().filter(|p| p.reachable()).collect();
    let panels: Vec<Panel> = measures
        .iter()
        .map(|(name, pick, log)| {
            let value = |p: &WorkspacePoint| {
                let v = pick(&p.metrics.rcond);
                if *log { v.max(1e-300).log10() } else { v }
            };
            let label = if *log {
                format!("log10 rcond({name})")
            } else {
                format!("rcond({name})")
            };
            heat_panel(&reachable, &label, tag, &value)
        })
        .collect();
    render(
        &panels,
        4,
        frame,
        "colour: viridis from the panel's minimum (dark) to its maximum (yellow); reachable cells",
    )
}

fn tension_figure(cells: &[&WorkspacePoint], frame: &Frame, tag: &str, n_t: usize) -> String {
    let reachable: Vec<&WorkspacePoint> = cells.iter().copied().filter(|p| p.reachable()).collect();
    let panels: Vec<Panel> = (0..n_t)
        .map(|k| {
            let label = format!("leg 1, tendon {} tension [N]", k + 1);
            heat_panel(&reachable, &label, tag, &|p: &WorkspacePoint| p.tensions[k])
        })
        .collect();
    render(
        &panels,
        n_t.min(4),
        frame,
        "colour: viridis from the panel's minimum (dark) to its maximum (yellow)",
    )
}

/// A heat-map panel; the title carries the value range.
fn heat_panel<'a>(
    cells: &[&'a WorkspacePoint],
    label: &str,
    tag: &str,
    value: &dyn Fn(&WorkspacePoint) -> f64,
) -> Panel<'a> {
    let values: Vec<f64> = cells.iter().map(|p| value(p)).collect();
    let (lo, hi) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    let title = if values.is_empty() {
        format!("{label}, {tag}")
    } else {
        format!("{label} [{lo:.3}, {hi:.3}]")
    };
    let span = if hi > lo { hi - lo } else { 1.0 };
    let coloured = cells
        .iter()
        .zip(&values)
        .map(|(p, v)| (*p, viridis((v - lo) / span)))
        .collect();
    (title, coloured)
}

/// The viridis colour map at t ∈ \[0, 1\] (piecewise linear through 5 of its colours).
pub fn viridis(t: f64) -> RGBColor {
    const STOPS: [(f64, f64, f64); 5] = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    } * 4.0;
    let i = (t.floor() as usize).min(3);
    let f = t - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let mix = |x: f64, y: f64| (x + (y - x) * f).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_ends_and_clamps() {
        assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
        assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(f64::NAN), viridis(0.0));
        assert_eq!(viridis(0.5), RGBColor(33, 145, 140));
    }
}
