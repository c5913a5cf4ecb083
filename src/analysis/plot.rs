//! SVG views of the manipulability and compliance ellipsoids, as in the paper's Fig. 8:
//! one file per ellipsoid, its outline projected on the xy and the xz plane side by side,
//! with its principal axes and their lengths.
//!
//! The projection of an ellipsoid {A u : ‖u‖ ≤ 1} (A = \[σ₁d₁ σ₂d₂ σ₃d₃\]) on a plane
//! with projector P (2 × 3) is the ellipse {P A u}, whose outline is G^½ (cos t, sin t)
//! with G = (P A)(P A)ᵀ. Files are written atomically (a temporary file in the same
//! directory, then renamed).

use std::path::{Path, PathBuf};

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use plotters::prelude::*;

use super::{Ellipsoid, Ellipsoids};
pub use crate::error::PlotError;
use crate::output::{WriteError, write_atomically};

/// Writes `j_p.svg`, `j_o.svg`, `c_p.svg` and `c_o.svg` into `dir` (created if missing)
/// and returns their paths.
///
/// # Errors
/// [`PlotError::Io`] if the directory or a file cannot be written; [`PlotError::Draw`]
/// if plotters fails.
pub fn write_ellipsoid_plots(dir: &Path, e: &Ellipsoids) -> Result<Vec<PathBuf>, PlotError> {
    std::fs::create_dir_all(dir).map_err(|source| PlotError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut written = Vec::new();
    for (name, title, unit, ellipsoid) in [
        ("j_p", "position manipulability J_p", "m/m", &e.j_p),
        ("j_o", "orientation manipulability J_o", "rad/m", &e.j_o),
        ("c_p", "position compliance C_p", "m/N", &e.c_p),
        ("c_o", "orientation compliance C_o", "rad/(N m)", &e.c_o),
    ] {
        let svg = render(name, title, unit, ellipsoid)?;
        let path = dir.join(format!("{name}.svg"));
        write_atomically(&path, svg.as_bytes())?;
        written.push(path);
    }
    Ok(written)
}

impl From<WriteError> for PlotError {
    fn from(e: WriteError) -> Self {
        Self::Io {
            path: e.path,
            source: e.source,
        }
    }
}

/// Outline of the projection on the plane of world axes (a, b), 121 points.
fn outline(ellipsoid: &Ellipsoid, (a, b): (usize, usize)) -> Vec<(f64, f64)> {
    let m = axes_matrix(ellipsoid);
    let pa = nalgebra::Matrix2x3::from_rows(&[m.row(a), m.row(b)]);
    let g: Matrix2<f64> = pa * pa.transpose();
    let eig = g.symmetric_eigen();
    let root = eig.eigenvectors
        * Matrix2::from_diagonal(&eig.eigenvalues.map(|l| l.max(0.0).sqrt()))
        * eig.eigenvectors.transpose();
    (0..=120)
        .map(|k| {
            let t = k as f64 / 120.0 * std::f64::consts::TAU;
            let p = root * Vector2::new(t.cos(), t.sin());
            (p.x, p.y)
        })
        .collect()
}

/// A = \[σ₁d₁ σ₂d₂ σ₃d₃\].
fn axes_matrix(e: &Ellipsoid) -> Matrix3<f64> {
    Matrix3::from_columns(&[0, 1, 2].map(|k| Vector3::from(e.directions[k]) * e.semi_axes[k]))
}

/// One ellipsoid's two views as an SVG document.
fn render(name: &'static str, title: &str, unit: &str, e: &Ellipsoid) -> Result<String, PlotError> {
    let draw = |err: &dyn std::fmt::Display| PlotError::Draw {
        name,
        message: err.to_string(),
    };
    let scale = e.semi_axes[0];
    let range = if scale > 0.0 && scale.is_finite() {
        1.15 * scale
    } else {
        1.0
    };
    let colors = [RED, GREEN, BLUE];
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (960, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| draw(&e))?;
        let caption = format!(
            "{title}: semi-axes {:.4e}, {:.4e}, {:.4e} {unit}",
            e.semi_axes[0], e.semi_axes[1], e.semi_axes[2]
        );
        let root = root
            .titled(&caption, ("sans-serif", 18))
            .map_err(|e| draw(&e))?;
        let (left, right) = root.split_horizontally(480);
        for (area, (a, b), labels) in [(left, (0, 1), ("x", "y")), (right, (0, 2), ("x", "z"))] {
            let mut chart = ChartBuilder::on(&area)
                .caption(
                    format!("{} view", labels.0.to_owned() + labels.1),
                    ("sans-serif", 16),
                )
                .margin(12)
                .x_label_area_size(36)
                .y_label_area_size(64)
                .build_cartesian_2d(-range..range, -range..range)
                .map_err(|e| draw(&e))?;
            chart
                .configure_mesh()
                .x_desc(format!("{} [{unit}]", labels.0))
                .y_desc(format!("{} [{unit}]", labels.1))
                .x_label_formatter(&|v| format!("{v:.2e}"))
                .y_label_formatter(&|v| format!("{v:.2e}"))
                .draw()
                .map_err(|e| draw(&e))?;
            chart
                .draw_series(LineSeries::new(outline(e, (a, b)), BLACK.stroke_width(2)))
                .map_err(|e| draw(&e))?;
            for (k, color) in colors.iter().enumerate() {
                let d = Vector3::from(e.directions[k]) * e.semi_axes[k];
                chart
                    .draw_series(LineSeries::new(
                        [(-d[a], -d[b]), (d[a], d[b])],
                        color.stroke_width(1),
                    ))
                    .map_err(|e| draw(&e))?;
            }
        }
        root.present().map_err(|e| draw(&e))?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_projected_outline_of_an_axis_aligned_ellipsoid_has_its_semi_axes() {
        let e = Ellipsoid {
            semi_axes: [3.0, 2.0, 1.0],
            directions: [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        };
        // xy view: x extent 2 (σ₂ along x), y extent 1; xz view: z extent 3.
        let xy = outline(&e, (0, 1));
        let max = |pts: &[(f64, f64)], f: fn(&(f64, f64)) -> f64| {
            pts.iter().map(f).fold(0.0f64, f64::max)
        };
        assert!((max(&xy, |p| p.0) - 2.0).abs() < 1e-12);
        assert!((max(&xy, |p| p.1) - 1.0).abs() < 1e-3);
        let xz = outline(&e, (0, 2));
        assert!((max(&xz, |p| p.1) - 3.0).abs() < 1e-3);
    }

    #[test]
    fn an_unwritable_directory_is_an_io_error_naming_it() {
        let e = Ellipsoid {
            semi_axes: [1.0, 1.0, 1.0],
            directions: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        };
        let all = Ellipsoids {
            j_p: e,
            j_o: e,
            c_p: e,
            c_o: e,
        };
        let file = std::env::temp_dir().join(format!("tdpcr-plot-file-{}", std::process::id()));
        std::fs::write(&file, b"not a directory").unwrap();
        let err = write_ellipsoid_plots(&file.join("sub"), &all).unwrap_err();
        assert!(
            err.to_string()
                .starts_with(&format!("cannot write {}", file.join("sub").display())),
            "{err}"
        );
        std::fs::remove_file(&file).unwrap();
        let err = PlotError::Draw {
            name: "j_p",
            message: "boom".into(),
        };
        assert_eq!(err.to_string(), "cannot draw j_p: boom");
    }
}
