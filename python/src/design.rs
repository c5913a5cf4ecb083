//! `Design`: a validated parallel-robot design (the RON design files of `designs/`).

use pyo3::prelude::*;

use crate::errors::design_error;

/// A parallel-robot design, validated when loaded.
#[pyclass(module = "tdpcr", frozen, from_py_object)]
#[derive(Clone)]
pub struct Design {
    pub(crate) design: tdpcr::Tdpcr,
}

#[pymethods]
impl Design {
    /// Loads and validates a RON design file; `DesignError` lists every bad field.
    #[staticmethod]
    fn load(path: std::path::PathBuf) -> PyResult<Self> {
        let design = tdpcr::Tdpcr::from_ron_file(&path).map_err(design_error)?;
        Ok(Self { design })
    }

    /// Parses and validates RON text; `DesignError` lists every bad field.
    #[staticmethod]
    #[pyo3(signature = (text, source = "<string>"))]
    fn from_ron(text: &str, source: &str) -> PyResult<Self> {
        let design = tdpcr::Tdpcr::from_ron_str(text, source).map_err(design_error)?;
        Ok(Self { design })
    }

    /// Length of q: 6 (6-DoF design) or 9 (9-DoF design).
    #[getter]
    fn n_actuators(&self) -> usize {
        self.design.n_actuators()
    }

    fn __repr__(&self) -> String {
        format!("Design(n_actuators={})", self.design.n_actuators())
    }
}
