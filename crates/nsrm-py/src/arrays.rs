//! numpy arrays in and out: shapes, dtypes and sizes checked before anything is allocated.

use crate::errors;
use numpy::{
    PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyReadwriteArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;

/// The most patches a training set from arrays may have (a fit's design is patches × terms).
pub(crate) const MAX_PATCHES: usize = 1 << 20;

/// `obj` as a numpy array: an `ndarray` as it is, anything else through `numpy.asarray(obj,
/// dtype=float64)` (lists, tuples).
fn ndarray<'py>(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Bound<'py, PyUntypedArray>> {
    if let Ok(a) = obj.cast::<PyUntypedArray>() {
        return Ok(a.clone());
    }
    let np = obj.py().import("numpy")?;
    let a = np
        .getattr("asarray")?
        .call1((obj, "float64"))
        .map_err(|e| errors::input(format!("{what}: not an array of numbers ({e})")))?;
    Ok(a.cast_into::<PyUntypedArray>()?)
}

/// The dtype's name (`float32`, `int64`, …).
fn dtype_name(a: &Bound<'_, PyUntypedArray>) -> String {
    a.dtype().to_string()
}

/// A checked pixel array: `(…, 3)` RGB or `(…, 4)` RGBA, float32 or float64, at most
/// `max_pixels` pixels (checked before anything is allocated).
pub(crate) struct Pixels<'py> {
    array: Bound<'py, PyUntypedArray>,
    /// The array's shape (the output has it too).
    pub(crate) shape: Vec<usize>,
    /// 3 or 4.
    pub(crate) channels: usize,
}

impl<'py> Pixels<'py> {
    /// Number of pixels.
    pub(crate) fn pixels(&self) -> usize {
        self.shape[..self.shape.len() - 1].iter().product()
    }

    /// A width and height for the frame the library corrects: the array's last two axes
    /// before the channels when it has them (rows × columns), else one row.
    pub(crate) fn size(&self) -> (usize, usize) {
        let n = self.shape.len();
        if n >= 3 {
            (self.shape[n - 2], self.shape[..n - 2].iter().product())
        } else {
            (self.pixels(), 1)
        }
    }

    /// The frame's layout.
    pub(crate) fn layout(&self) -> nsrm::Layout {
        if self.channels == 4 {
            nsrm::Layout::Rgba
        } else {
            nsrm::Layout::Rgb
        }
    }

    /// The array itself when it is C-contiguous float32: the library reads it in place.
    pub(crate) fn contiguous_f32(&self) -> Option<PyReadonlyArrayDyn<'py, f32>> {
        let f = self.array.cast::<PyArrayDyn<f32>>().ok()?;
        f.is_c_contiguous().then(|| f.readonly())
    }

    /// The pixels as packed f32 in C order: one copy (a C-contiguous float32 array as a block,
    /// anything else converted element by element).
    pub(crate) fn to_vec(&self) -> Vec<f32> {
        if let Ok(f) = self.array.cast::<PyArrayDyn<f32>>() {
            let r = f.readonly();
            // `as_slice` also takes a Fortran-ordered array: only C order is copied as a block.
            match r.as_slice() {
                Ok(s) if f.is_c_contiguous() => s.to_vec(),
                _ => r.as_array().iter().copied().collect(),
            }
        } else {
            let f = self
                .array
                .cast::<PyArrayDyn<f64>>()
                .expect("checked: float32 or float64");
            let r = f.readonly();
            match r.as_slice() {
                Ok(s) if f.is_c_contiguous() => s.iter().map(|&v| v as f32).collect(),
                _ => r.as_array().iter().map(|&v| v as f32).collect(),
            }
        }
    }
}

/// Checks a pixel array (NaN and ±Inf are allowed: the pixel policy propagates them).
pub(crate) fn pixels<'py>(
    obj: &Bound<'py, PyAny>,
    what: &str,
    max_pixels: u64,
) -> PyResult<Pixels<'py>> {
    let a = ndarray(obj, what)?;
    let shape = a.shape().to_vec();
    let channels = match shape.last() {
        Some(&c @ (3 | 4)) => c,
        _ => {
            return Err(errors::input(format!(
                "{what}: shape {shape:?}: expected (..., 3) RGB or (..., 4) RGBA"
            )))
        }
    };
    let px: u128 = shape[..shape.len() - 1]
        .iter()
        .map(|&d| d as u128)
        .product();
    if px > u128::from(max_pixels) {
        return Err(errors::input(format!(
            "{what}: {px} pixels, more than max_pixels = {max_pixels}"
        )));
    }
    if a.cast::<PyArrayDyn<f32>>().is_err() && a.cast::<PyArrayDyn<f64>>().is_err() {
        return Err(errors::input(format!(
            "{what}: dtype {}: expected float32 or float64",
            dtype_name(&a)
        )));
    }
    Ok(Pixels {
        array: a,
        shape,
        channels,
    })
}

/// Rows of an `(N, 3)` array as f64 (float32 or float64; lists too), every value finite.
pub(crate) fn rows3(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f64; 3]>> {
    let (v, shape) = floats(obj, what, true)?;
    if shape.len() != 2 || shape[1] != 3 {
        return Err(errors::input(format!(
            "{what}: shape {shape:?}: expected (N, 3)"
        )));
    }
    Ok(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// Values of a `(…, 3)` array as f64 with its shape (NaN allowed).
pub(crate) fn triples(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<(Vec<f64>, Vec<usize>)> {
    let (v, shape) = floats(obj, what, false)?;
    if shape.last() != Some(&3) {
        return Err(errors::input(format!(
            "{what}: shape {shape:?}: expected (..., 3)"
        )));
    }
    Ok((v, shape))
}

/// A float32 / float64 array as f64 in C order, at most [`MAX_PATCHES`] × 3 values; `finite`:
/// NaN and ±Inf refused.
fn floats(obj: &Bound<'_, PyAny>, what: &str, finite: bool) -> PyResult<(Vec<f64>, Vec<usize>)> {
    let a = ndarray(obj, what)?;
    let shape = a.shape().to_vec();
    let n: u128 = shape.iter().map(|&d| d as u128).product();
    let limit = if finite { MAX_PATCHES * 3 } else { 1 << 31 };
    if n > limit as u128 {
        return Err(errors::input(format!(
            "{what}: {n} values, more than {limit}"
        )));
    }
    let v: Vec<f64> = if let Ok(f) = a.cast::<PyArrayDyn<f64>>() {
        f.readonly().as_array().iter().copied().collect()
    } else if let Ok(f) = a.cast::<PyArrayDyn<f32>>() {
        f.readonly()
            .as_array()
            .iter()
            .map(|&x| f64::from(x))
            .collect()
    } else {
        return Err(errors::input(format!(
            "{what}: dtype {}: expected float32 or float64",
            dtype_name(&a)
        )));
    };
    if finite {
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(errors::input(format!(
                "{what}: value {} at flat index {i} is not finite",
                v[i]
            )));
        }
    }
    Ok((v, shape))
}

/// `out=`: a C-contiguous, writable float32 array of `shape`.
pub(crate) fn out_array<'py>(
    obj: &Bound<'py, PyAny>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let a = obj
        .cast::<PyArrayDyn<f32>>()
        .map_err(|_| errors::input("out: expected a float32 numpy array"))?;
    if a.shape() != shape || !a.is_c_contiguous() {
        return Err(errors::input(format!(
            "out: shape {:?}{}: expected a C-contiguous array of shape {shape:?}",
            a.shape(),
            if a.is_c_contiguous() {
                ""
            } else {
                ", not C-contiguous"
            }
        )));
    }
    Ok(a.clone())
}

/// Borrows `out` for writing (refused while it is also read: `out` must not be the input).
pub(crate) fn writable<'py>(
    a: &Bound<'py, PyArrayDyn<f32>>,
) -> PyResult<PyReadwriteArrayDyn<'py, f32>> {
    a.try_readwrite()
        .map_err(|e| errors::input(format!("out: {e} (it must be writable and not the input)")))
}

/// A float32 array of `shape` holding `data` (no copy: numpy takes the buffer).
pub(crate) fn out_f32<'py>(
    py: Python<'py>,
    data: Vec<f32>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    PyArray1::from_vec(py, data).reshape(shape.to_vec())
}

/// A float64 array of `shape` holding `data` (no copy).
pub(crate) fn out_f64<'py>(
    py: Python<'py>,
    data: Vec<f64>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    PyArray1::from_vec(py, data).reshape(shape.to_vec())
}
