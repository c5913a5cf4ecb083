//! A [`Figure`] (plotly traces, 3D scenes, menus) and the self-contained HTML page that
//! shows it: plotly.js inlined, the figure as JSON, nothing fetched.

use std::fmt::{self, Write as _};
use std::path::Path;

use serde_json::{Value, json};

use crate::output::{WriteError, write_atomically};

/// plotly.js-dist-min 3.3.0, minified, unmodified (`vendor/plotly.js-dist-min`).
const PLOTLY_JS: &str = include_str!("../../vendor/plotly.js-dist-min/plotly.min.js");

/// A plotly figure: traces, and the layout with one 3D scene per view.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Title above the views.
    pub title: String,
    /// plotly traces (each names its scene: `scene`, `scene2`, ...).
    pub traces: Vec<Value>,
    /// One entry per scene: its id and its title.
    pub scenes: Vec<(String, String)>,
    /// plotly `updatemenus` (dropdowns), empty if none.
    pub menus: Vec<Value>,
    /// Fraction of the page's width left of the scenes (room for a colour bar; 0 if none).
    pub inset_left: f64,
}

impl Figure {
    /// An empty figure with a title.
    pub fn new(title: impl Into<String>) -> Self {
        Self {
            title: title.into(),
            traces: Vec::new(),
            scenes: Vec::new(),
            menus: Vec::new(),
            inset_left: 0.0,
        }
    }

    /// Adds a 3D scene (axes in mm, equal aspect) and returns its id (`scene`, `scene2`, ...).
    pub fn add_scene(&mut self, title: impl Into<String>) -> String {
        let id = match self.scenes.len() {
            0 => "scene".to_owned(),
            n => format!("scene{}", n + 1),
        };
        self.scenes.push((id.clone(), title.into()));
        id
    }

    /// The plotly layout: the scenes side by side, a legend, the menus.
    pub fn layout(&self) -> Value {
        let mut layout = json!({
            "title": {"text": self.title},
            "showlegend": true,
            "legend": {"itemsizing": "constant", "bgcolor": "rgba(255,255,255,0.7)"},
            "margin": {"l": 0, "r": 0, "t": 48, "b": 0},
            "paper_bgcolor": "white",
            "updatemenus": self.menus,
        });
        let n = self.scenes.len().max(1) as f64;
        let mut annotations = Vec::new();
        for (k, (id, title)) in self.scenes.iter().enumerate() {
            let width = 1.0 - self.inset_left;
            let domain = [
                self.inset_left + width * k as f64 / n,
                self.inset_left + width * (k + 1) as f64 / n,
            ];
            let axis = |name: &str| json!({"title": {"text": format!("{name} [mm]")}});
            layout[id] = json!({
                "domain": {"x": domain, "y": [0.0, 1.0]},
                "aspectmode": "data",
                "xaxis": axis("x"),
                "yaxis": axis("y"),
                "zaxis": axis("z"),
            });
            if self.scenes.len() > 1 {
                annotations.push(json!({
                    "text": title, "showarrow": false, "xref": "paper", "yref": "paper",
                    "x": (domain[0] + domain[1]) / 2.0, "y": 1.0, "xanchor": "center",
                    "yanchor": "bottom", "font": {"size": 14},
                }));
            }
        }
        layout["annotations"] = Value::Array(annotations);
        layout
    }
}

/// The HTML page of `figure`: plotly.js inlined, then the figure, drawn full-window.
pub fn html_page(figure: &Figure) -> String {
    let spec = json!({"data": figure.traces, "layout": figure.layout()});
    // "</" cannot end the script element early: JSON has it only inside strings, where
    // "<\/" reads back the same.
    let spec = spec.to_string().replace("</", "<\\/");
    let title = escape_html(&figure.title);
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{title}</title>\n\
         <style>html, body {{ margin: 0; height: 100%; }} #view {{ width: 100%; height: 100%; }}</style>\n\
         <!-- plotly.js-dist-min 3.3.0 (MIT licence, Copyright 2012-2025 Plotly, Inc.) -->\n\
         <script>{PLOTLY_JS}</script>\n</head>\n<body>\n<div id=\"view\"></div>\n\
         <script>\nconst figure = {spec};\n\
         Plotly.newPlot('view', figure.data, figure.layout, {{responsive: true, displaylogo: false}})\n\
         .then(() => {{ document.body.dataset.rendered = 'yes'; }});\n</script>\n</body>\n</html>\n"
    )
}

/// Writes the page of `figure` to `path` atomically (temporary file, then rename).
///
/// # Errors
/// [`WriteError`] naming the file.
pub fn write_page(path: &Path, figure: &Figure) -> Result<(), WriteError> {
    write_atomically(path, html_page(figure).as_bytes())
}

/// `&`, `<`, `>` and `"` as entities.
fn escape_html(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// `x` rounded to `digits` significant digits (0 for a non-finite value: no NaN in a
/// page), so the JSON of large clouds stays short. The decimal text goes through a
/// buffer on the stack: `format!` allocated once per value, about a million times for
/// the reference design's Δ = 3 mm cloud.
pub fn round_significant(x: f64, digits: usize) -> f64 {
    if !x.is_finite() {
        return 0.0;
    }
    let mut text = StackText::default();
    if write!(text, "{x:.*e}", digits.saturating_sub(1)).is_ok() {
        text.as_str().parse().unwrap_or(0.0)
    } else {
        // More digits than the buffer holds.
        format!("{x:.*e}", digits.saturating_sub(1))
            .parse()
            .unwrap_or(0.0)
    }
}

/// A short text written on the stack ([`fmt::Write`] fails where it would overflow).
struct StackText {
    bytes: [u8; 40],
    len: usize,
}

impl Default for StackText {
    fn default() -> Self {
        Self {
            bytes: [0; 40],
            len: 0,
        }
    }
}

impl StackText {
    fn as_str(&self) -> &str {
        std::str::from_utf8(&self.bytes[..self.len]).expect("written from str")
    }
}

impl fmt::Write for StackText {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let end = self.len + s.len();
        let to = self.bytes.get_mut(self.len..end).ok_or(fmt::Error)?;
        to.copy_from_slice(s.as_bytes());
        self.len = end;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_inlines_plotly_and_cannot_close_its_script_early() {
        assert!(
            !PLOTLY_JS.contains("</script"),
            "vendored file unsafe to inline"
        );
        let mut f = Figure::new("a <b> & \"c\"");
        let scene = f.add_scene("left");
        f.traces
            .push(json!({"type": "scatter3d", "scene": scene, "name": "</script>"}));
        let page = html_page(&f);
        assert_eq!(
            page.matches("</script>").count(),
            2,
            "only the two script ends"
        );
        assert!(page.contains("<title>a &lt;b&gt; &amp; &quot;c&quot;</title>"));
        assert!(page.contains("plotly.js v3.3.0"));
        assert!(!page.contains("<script src"), "nothing fetched");
        let start = page.find("const figure = ").unwrap() + "const figure = ".len();
        let end = page[start..].find(";\nPlotly").unwrap() + start;
        let spec: Value = serde_json::from_str(&page[start..end]).unwrap();
        assert_eq!(spec["data"][0]["name"], "</script>");
        assert_eq!(spec["layout"]["scene"]["xaxis"]["title"]["text"], "x [mm]");
    }

    #[test]
    fn scenes_sit_side_by_side() {
        let mut f = Figure::new("t");
        assert_eq!(f.add_scene("a"), "scene");
        assert_eq!(f.add_scene("b"), "scene2");
        let l = f.layout();
        assert_eq!(l["scene2"]["domain"]["x"], json!([0.5, 1.0]));
        assert_eq!(l["annotations"][1]["text"], "b");
    }

    #[test]
    fn rounding_keeps_significant_digits_and_drops_nan() {
        assert_eq!(round_significant(0.0123456, 3), 0.0123);
        assert_eq!(round_significant(-98765.0, 2), -99000.0);
        assert_eq!(round_significant(f64::NAN, 3), 0.0);
        assert_eq!(round_significant(f64::INFINITY, 3), 0.0);
        // Beyond the stack buffer: the same through a String.
        assert_eq!(round_significant(1.0 / 3.0, 60), 1.0 / 3.0);
    }
}
