//! numpy in and out. Input arrays are read through their strides (any
//! layout, no copy on the Python side) and copied once into the library;
//! output arrays are new numpy arrays the caller owns.

use crate::error::bad;
use glam::{DMat4, Vec3};
use numpy::ndarray::{Array2, ArrayView2, ArrayViewD};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2, PyReadonlyArrayDyn};
use pyo3::prelude::*;

/// Mesh positions: an `(n, 3)` array of float32 or float64, any strides.
pub(crate) fn positions(a: &Bound<'_, PyAny>) -> PyResult<Vec<Vec3>> {
    fn rows<T: Copy + Into<f64>>(v: ArrayView2<'_, T>) -> PyResult<Vec<Vec3>> {
        if v.ncols() != 3 {
            return Err(bad(format!(
                "positions: shape ({}, {}) is not (n, 3)",
                v.nrows(),
                v.ncols()
            )));
        }
        Ok(v.rows()
            .into_iter()
            .map(|r| Vec3::new(r[0].into() as f32, r[1].into() as f32, r[2].into() as f32))
            .collect())
    }
    if let Ok(v) = a.extract::<PyReadonlyArray2<'_, f32>>() {
        rows(v.as_array())
    } else if let Ok(v) = a.extract::<PyReadonlyArray2<'_, f64>>() {
        rows(v.as_array())
    } else {
        Err(bad(format!(
            "positions: expected a 2-d float32 or float64 numpy array of shape (n, 3), got {}",
            describe(a)
        )))
    }
}

/// Triangle indices: an `(m, 3)` or flat `(3m,)` array of any integer type.
pub(crate) fn triangles(a: &Bound<'_, PyAny>) -> PyResult<Vec<[u32; 3]>> {
    fn tris<T: Copy + TryInto<u32> + std::fmt::Display>(
        v: ArrayViewD<'_, T>,
    ) -> PyResult<Vec<[u32; 3]>> {
        let flat_ok = v.ndim() == 1 && v.len().is_multiple_of(3);
        let rows_ok = v.ndim() == 2 && v.shape()[1] == 3;
        if !(flat_ok || rows_ok) {
            return Err(bad(format!(
                "indices: shape {:?} is neither (m, 3) nor (3m,)",
                v.shape()
            )));
        }
        let flat: Vec<u32> = v
            .iter()
            .map(|&i| {
                i.try_into()
                    .map_err(|_| bad(format!("indices: {i} is not a vertex index (0 to 2³²−1)")))
            })
            .collect::<PyResult<_>>()?;
        Ok(flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect())
    }
    macro_rules! try_types {
        ($($t:ty),*) => {
            $(if let Ok(v) = a.extract::<PyReadonlyArrayDyn<'_, $t>>() {
                return tris(v.as_array());
            })*
        };
    }
    try_types!(u32, i32, i64, u64, u16, i16, u8, i8);
    Err(bad(format!(
        "indices: expected an integer numpy array of shape (m, 3) or (3m,), got {}",
        describe(a)
    )))
}

/// A 4×4 float64 matrix as numpy prints it (row i, column j), applied to
/// column vectors: `world = M @ [x, y, z, 1]`.
pub(crate) fn matrix(name: &str, a: PyReadonlyArray2<'_, f64>) -> PyResult<DMat4> {
    let v = a.as_array();
    if v.shape() != [4, 4] {
        return Err(bad(format!("{name}: shape {:?} is not (4, 4)", v.shape())));
    }
    Ok(DMat4::from_cols_array_2d(&std::array::from_fn(|c| {
        std::array::from_fn(|r| v[[r, c]])
    })))
}

/// A matrix back to numpy's layout (row i, column j).
pub(crate) fn matrix_out<'py>(py: Python<'py>, m: &DMat4) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((4, 4), |(r, c)| m.col(c)[r]).into_pyarray(py)
}

/// A flat vector as a 1-d array.
pub(crate) fn vec1<'py, T: numpy::Element>(py: Python<'py>, v: Vec<T>) -> Bound<'py, PyArray1<T>> {
    v.into_pyarray(py)
}

/// A row-major vector as a `rows × cols` array.
pub(crate) fn vec2<'py, T: numpy::Element>(
    py: Python<'py>,
    v: Vec<T>,
    rows: usize,
    cols: usize,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let a = Array2::from_shape_vec((rows, cols), v).map_err(|e| bad(e.to_string()))?;
    Ok(a.into_pyarray(py))
}

/// What an argument is, for error messages.
fn describe(a: &Bound<'_, PyAny>) -> String {
    let dtype = a
        .getattr("dtype")
        .map(|d| d.to_string())
        .unwrap_or_default();
    let shape = a
        .getattr("shape")
        .map(|s| s.to_string())
        .unwrap_or_default();
    match a.get_type().name() {
        Ok(t) if !dtype.is_empty() => format!("{t} of dtype {dtype} and shape {shape}"),
        Ok(t) => t.to_string(),
        Err(_) => "an object of unknown type".into(),
    }
}
