//! float64 arrays in and out. Inputs may be any array-like (lists, int arrays,
//! non-contiguous views): they are read as float64, their shape and finiteness checked,
//! and a `ValueError` names the argument.

use numpy::ndarray::{Array2, ArrayViewD, Dimension};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;

/// The elements of `obj` as a float64 array (converted by `numpy.asarray` if needed).
/// Real numbers only: complex values (numpy dropped their imaginary part with a
/// warning), strings (numpy parsed them) and dates are refused. An exception that is
/// not a conversion's (KeyboardInterrupt during a long conversion) passes unchanged.
fn readonly<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    let a = converted(obj, name)?;
    if in_place(&a) {
        return Ok(a);
    }
    // A copy in C order, aligned: read in place, such an array gave other numbers.
    let numpy = obj.py().import("numpy")?;
    numpy
        .call_method1("ascontiguousarray", (a.as_any(),))?
        .extract::<PyReadonlyArrayDyn<'py, f64>>()
}

/// Whether a float64 array can be read where it is: its data aligned for f64 and its
/// strides whole elements. A field of a packed structured array (a record of a float and
/// a byte: strides of 9 bytes) is neither, and rust-numpy's view rounded its strides
/// down to whole elements: `z_range` [-0.05, 0.05] was read as [-0.05, -2.7e-108].
fn in_place(a: &PyReadonlyArrayDyn<'_, f64>) -> bool {
    let size = std::mem::size_of::<f64>() as isize;
    (a.data() as usize).is_multiple_of(std::mem::align_of::<f64>())
        && a.strides().iter().all(|s| s % size == 0)
}

/// [`readonly`]'s conversion: `obj` as a float64 array, laid out as numpy has it.
fn converted<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    // A masked array is an ndarray: read as one, its masked entries' values were used.
    // (A plain ndarray skips the attribute lookup: its miss raises and catches an
    // AttributeError, about 0.3 µs of a 17 µs warm IK step.)
    if !obj.is_exact_instance_of::<PyUntypedArray>() && obj.hasattr("mask")? {
        let numpy_ma = obj.py().import("numpy.ma")?;
        if numpy_ma.call_method1("is_masked", (obj,))?.is_truthy()? {
            return Err(PyValueError::new_err(format!(
                "{name}: a masked array with masked entries: expected plain numbers (fill or \
                 compress it first)"
            )));
        }
    }
    if let Ok(a) = obj.extract::<PyReadonlyArrayDyn<'py, f64>>() {
        return Ok(a);
    }
    let not_numbers = |e: PyErr| {
        if e.is_instance_of::<PyException>(obj.py()) {
            PyValueError::new_err(format!("{name}: not an array of numbers ({e})"))
        } else {
            e
        }
    };
    let numpy = obj.py().import("numpy")?;
    let plain = numpy.call_method1("asarray", (obj,)).map_err(not_numbers)?;
    let kind: String = plain
        .getattr("dtype")
        .and_then(|d| d.getattr("kind"))
        .and_then(|k| k.extract())
        .map_err(not_numbers)?;
    let what = match kind.as_str() {
        "c" => Some("complex numbers"),
        "U" | "S" => Some("strings"),
        "M" | "m" => Some("dates or time spans"),
        "V" => Some("structured records"),
        _ => None,
    };
    // An object array's elements may be strings (a pandas column of text, a list mixed
    // with numbers): numpy would parse them.
    let what = match what {
        None if kind == "O" => {
            let mut elements = plain
                .call_method0("ravel")
                .map_err(not_numbers)?
                .try_iter()?;
            elements
                .try_fold(false, |found, x| {
                    x.map(|x| {
                        found
                            || x.is_instance_of::<pyo3::types::PyString>()
                            || x.is_instance_of::<pyo3::types::PyBytes>()
                    })
                })?
                .then_some("strings")
        }
        what => what,
    };
    if let Some(what) = what {
        return Err(PyValueError::new_err(format!(
            "{name}: {what} (dtype {}): expected real numbers",
            plain
                .getattr("dtype")
                .map_or_else(|_| kind.clone(), |d| d.to_string())
        )));
    }
    numpy
        .call_method1("asarray", (plain, "float64"))
        .and_then(|a| a.extract::<PyReadonlyArrayDyn<'py, f64>>())
        .map_err(not_numbers)
}

/// Checks every element is finite; the first that is not is named by its index (row and
/// column in a matrix).
fn check_finite(a: &ArrayViewD<'_, f64>, name: &str) -> PyResult<()> {
    match a.indexed_iter().find(|(_, x)| !x.is_finite()) {
        None => Ok(()),
        Some((at, x)) => {
            let at = match at.slice() {
                [i] => format!("element {i}"),
                [r, c] => format!("row {r}, column {c}"),
                more => format!("element {more:?}"),
            };
            Err(PyValueError::new_err(format!(
                "{name}: {at} is {x}: expected finite numbers"
            )))
        }
    }
}

/// A vector argument of `len` elements (any length if `None`), finite.
pub fn vector(obj: &Bound<'_, PyAny>, name: &str, len: Option<usize>) -> PyResult<Vec<f64>> {
    let a = readonly(obj, name)?;
    let a = a.as_array();
    let ok = a.ndim() == 1 && len.is_none_or(|n| a.len() == n);
    if !ok {
        let expected = len.map_or("a 1-d array".to_string(), |n| format!("shape ({n},)"));
        return Err(PyValueError::new_err(format!(
            "{name}: shape {:?}: expected {expected}",
            a.shape()
        )));
    }
    check_finite(&a, name)?;
    Ok(a.iter().copied().collect())
}

/// A matrix argument with `cols` columns (any number of rows), finite; row-major rows.
pub fn rows(obj: &Bound<'_, PyAny>, name: &str, cols: usize) -> PyResult<Vec<Vec<f64>>> {
    let a = readonly(obj, name)?;
    let a = a.as_array();
    if a.ndim() != 2 || a.shape()[1] != cols {
        return Err(PyValueError::new_err(format!(
            "{name}: shape {:?}: expected (m, {cols})",
            a.shape()
        )));
    }
    check_finite(&a, name)?;
    Ok(a.outer_iter()
        .map(|r| r.iter().copied().collect())
        .collect())
}

/// A vector as a 1-d array.
pub fn array1<'py>(py: Python<'py>, v: &[f64]) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, v)
}

/// `rows × cols` elements from `at(i, j)` as a 2-d array.
pub fn array2<'py>(
    py: Python<'py>,
    shape: (usize, usize),
    at: impl Fn(usize, usize) -> f64,
) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn(shape, |(i, j)| at(i, j)).into_pyarray(py)
}

/// A nalgebra matrix as a 2-d array.
pub fn matrix<'py>(py: Python<'py>, m: &nalgebra::DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    array2(py, m.shape(), |i, j| m[(i, j)])
}
