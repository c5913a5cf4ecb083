//! The search's own figures (SVG): the Pareto front as pairwise objective scatters, and the
//! composite objective over the evaluations.

use plotters::prelude::*;

use crate::objectives::PARETO_OBJECTIVES;
use crate::search::SearchResult;

const GREY: RGBColor = RGBColor(190, 190, 190);
const FRONT_BLUE: RGBColor = RGBColor(31, 119, 180);
const REFERENCE_RED: RGBColor = RGBColor(214, 39, 40);
const BEST_GREEN: RGBColor = RGBColor(44, 160, 44);

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;
type Plot = Result<(), Box<dyn std::error::Error>>;

/// Renders with `draw` into an SVG string of `size` pixels. Drawing into a string cannot
/// fail for I/O reasons; a drawing error only leaves the figure incomplete.
fn render(size: (u32, u32), draw: impl FnOnce(&Area) -> Plot) -> String {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        let _ = root.fill(&WHITE).map_err(|e| e.to_string());
        let _ = draw(&root);
        let _ = root.present();
    }
    svg
}

/// A range covering `values` with a 5 % margin (a unit range around a single value).
fn padded(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return 0.0..1.0;
    }
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        0.05 * lo.abs().max(1e-9)
    };
    (lo - pad)..(hi + pad)
}

/// `pareto.svg`: the three pairwise scatters of the Pareto objectives; grey every
/// feasible candidate, blue the Pareto front, green the best composite, red the
/// reference.
pub fn pareto_figure(result: &SearchResult) -> String {
    let front_ids: Vec<usize> = result.pareto_front().iter().map(|r| r.id).collect();
    let best_id = result.best_composite().map(|r| r.id);
    // (objectives in display units, is front, is best)
    let points: Vec<([f64; 3], bool, bool)> = result
        .candidates
        .iter()
        .filter_map(|r| {
            r.outcome.measures().map(|m| {
                (
                    scaled(m.pareto()),
                    front_ids.contains(&r.id),
                    Some(r.id) == best_id,
                )
            })
        })
        .collect();
    let reference = result
        .reference
        .outcome
        .measures()
        .map(|m| scaled(m.pareto()));
    let pairs = [(0, 1), (0, 2), (1, 2)];
    render((1260, 450), |root| {
        let (legend, body) = root.split_vertically(24);
        let areas = body.split_evenly((1, 3));
        for ((a, b), area) in pairs.iter().zip(areas.iter()) {
            let all = || points.iter().map(|p| p.0).chain(reference);
            let mut chart = ChartBuilder::on(area)
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(padded(all().map(|p| p[*a])), padded(all().map(|p| p[*b])))?;
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc(PARETO_OBJECTIVES[*a].label())
                .y_desc(PARETO_OBJECTIVES[*b].label())
                .draw()?;
            let layer = |front: bool, best: bool| {
                points
                    .iter()
                    .filter(move |p| p.1 == front && p.2 == best)
                    .map(|p| (p.0[*a], p.0[*b]))
            };
            chart.draw_series(layer(false, false).map(|p| Circle::new(p, 2, GREY.filled())))?;
            chart
                .draw_series(layer(true, false).map(|p| Circle::new(p, 4, FRONT_BLUE.filled())))?;
            chart.draw_series(
                layer(true, true)
                    .chain(layer(false, true))
                    .map(|p| Circle::new(p, 6, BEST_GREEN.filled())),
            )?;
            if let Some(r) = reference {
                chart.draw_series(std::iter::once(Cross::new(
                    (r[*a], r[*b]),
                    7,
                    REFERENCE_RED.stroke_width(3),
                )))?;
            }
        }
        legend.draw(&Text::new(
            "grey: feasible candidates, blue: Pareto front, green: best composite, red cross: reference",
            (14, 6),
            ("sans-serif", 14).into_font(),
        ))?;
        Ok(())
    })
}

/// The Pareto objectives in the units of their labels (volume in cm³).
fn scaled(p: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|k| p[k] * PARETO_OBJECTIVES[k].display_factor())
}

/// `progress.svg`: the composite of every feasible candidate against its id (grey), the
/// best so far (blue) and the reference's value 1 (red).
pub fn progress_figure(result: &SearchResult) -> String {
    let points: Vec<(f64, f64)> = result
        .candidates
        .iter()
        .filter_map(|r| r.composite.map(|c| (r.id as f64, c)))
        .collect();
    let mut best = f64::NEG_INFINITY;
    let best_line: Vec<(f64, f64)> = points
        .iter()
        .map(|&(i, c)| {
            best = best.max(c);
            (i, best)
        })
        .collect();
    let n = result.candidates.last().map_or(1, |r| r.id) as f64;
    render((760, 430), |root| {
        let mut chart = ChartBuilder::on(root)
            .margin(14)
            .caption("composite objective (reference = 1)", ("sans-serif", 16))
            .x_label_area_size(40)
            .y_label_area_size(55)
            .build_cartesian_2d(
                0.0..n.max(1.0),
                padded(points.iter().map(|p| p.1).chain([1.0])),
            )?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("candidate (evaluation order)")
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_desc("composite")
            .draw()?;
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 2, GREY.filled())))?;
        chart.draw_series(std::iter::once(PathElement::new(
            best_line,
            FRONT_BLUE.stroke_width(2),
        )))?;
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(0.0, 1.0), (n.max(1.0), 1.0)],
            REFERENCE_RED.stroke_width(1),
        )))?;
        Ok(())
    })
}
