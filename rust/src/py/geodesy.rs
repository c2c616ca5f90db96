//! Bindings of the WGS84 geodesy core: flat float64 arrays in (each of length n or 1), three
//! arrays out. Broadcasting of shapes, degrees and ellipsoid objects are handled in
//! `usvfast.geodesy`.

use super::{slice, to_py_err};
use crate::error::Error;
use crate::geodesy::{self, Ellipsoid, LocalFrame};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

type Out<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
);

fn ellipsoid(ell: (f64, f64)) -> PyResult<Ellipsoid> {
    Ellipsoid::new(ell.0, ell.1).map_err(to_py_err)
}

fn frame(name: &str) -> PyResult<LocalFrame> {
    match name {
        "ned" => Ok(LocalFrame::Ned),
        "enu" => Ok(LocalFrame::Enu),
        other => Err(to_py_err(Error::param(
            "frame",
            format!("expected \"ned\" or \"enu\", got {other:?}"),
        ))),
    }
}

fn out<'py>(py: Python<'py>, r: crate::Result<[Vec<f64>; 3]>) -> PyResult<Out<'py>> {
    let [a, b, c] = r.map_err(to_py_err)?;
    Ok((
        PyArray1::from_vec(py, a),
        PyArray1::from_vec(py, b),
        PyArray1::from_vec(py, c),
    ))
}

/// Geodetic (lat, lon, h) → ECEF (x, y, z) in metres; `ellipsoid` = (a, b) in metres.
#[pyfunction]
#[pyo3(signature = (lat, lon, h, *, ellipsoid, deg))]
fn geodetic_to_ecef<'py>(
    py: Python<'py>,
    lat: PyReadonlyArray1<'py, f64>,
    lon: PyReadonlyArray1<'py, f64>,
    h: PyReadonlyArray1<'py, f64>,
    ellipsoid: (f64, f64),
    deg: bool,
) -> PyResult<Out<'py>> {
    let ell = self::ellipsoid(ellipsoid)?;
    let (a, b, c) = (slice("lat", &lat)?, slice("lon", &lon)?, slice("h", &h)?);
    let r = py.detach(|| geodesy::geodetic2ecef(&ell, a, b, c, deg));
    out(py, r)
}

/// ECEF (x, y, z) in metres → geodetic (lat, lon, h).
#[pyfunction]
#[pyo3(signature = (x, y, z, *, ellipsoid, deg))]
fn ecef_to_geodetic<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f64>,
    y: PyReadonlyArray1<'py, f64>,
    z: PyReadonlyArray1<'py, f64>,
    ellipsoid: (f64, f64),
    deg: bool,
) -> PyResult<Out<'py>> {
    let ell = self::ellipsoid(ellipsoid)?;
    let (a, b, c) = (slice("x", &x)?, slice("y", &y)?, slice("z", &z)?);
    let r = py.detach(|| geodesy::ecef2geodetic(&ell, a, b, c, deg));
    out(py, r)
}

/// Shared body of the four origin-relative conversions.
macro_rules! local_fn {
    ($name:ident, $core:path, $doc:literal, [$p0:literal, $p1:literal, $p2:literal]) => {
        #[doc = $doc]
        #[pyfunction]
        #[pyo3(signature = (frame, u, v, w, lat0, lon0, h0, *, ellipsoid, deg))]
        #[allow(clippy::too_many_arguments)]
        fn $name<'py>(
            py: Python<'py>,
            frame: &str,
            u: PyReadonlyArray1<'py, f64>,
            v: PyReadonlyArray1<'py, f64>,
            w: PyReadonlyArray1<'py, f64>,
            lat0: PyReadonlyArray1<'py, f64>,
            lon0: PyReadonlyArray1<'py, f64>,
            h0: PyReadonlyArray1<'py, f64>,
            ellipsoid: (f64, f64),
            deg: bool,
        ) -> PyResult<Out<'py>> {
            let ell = self::ellipsoid(ellipsoid)?;
            let frame = self::frame(frame)?;
            let pts = [
                ($p0, slice($p0, &u)?),
                ($p1, slice($p1, &v)?),
                ($p2, slice($p2, &w)?),
            ];
            let org = [
                ("lat0", slice("lat0", &lat0)?),
                ("lon0", slice("lon0", &lon0)?),
                ("h0", slice("h0", &h0)?),
            ];
            let r = py.detach(|| $core(&ell, frame, pts, org, deg));
            out(py, r)
        }
    };
}

local_fn!(
    geodetic_to_local,
    geodesy::geodetic2local,
    "Geodetic points → local NED/ENU (metres) at the origin (lat0, lon0, h0).",
    ["lat", "lon", "h"]
);
local_fn!(
    local_to_geodetic,
    geodesy::local2geodetic,
    "Local NED/ENU (metres) at the origin → geodetic points.",
    ["u", "v", "w"]
);
local_fn!(
    ecef_to_local,
    geodesy::ecef2local,
    "ECEF points (metres) → local NED/ENU (metres) at the origin.",
    ["x", "y", "z"]
);
local_fn!(
    local_to_ecef,
    geodesy::local2ecef,
    "Local NED/ENU (metres) at the origin → ECEF points (metres).",
    ["u", "v", "w"]
);

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(geodetic_to_ecef, m)?)?;
    m.add_function(wrap_pyfunction!(ecef_to_geodetic, m)?)?;
    m.add_function(wrap_pyfunction!(geodetic_to_local, m)?)?;
    m.add_function(wrap_pyfunction!(local_to_geodetic, m)?)?;
    m.add_function(wrap_pyfunction!(ecef_to_local, m)?)?;
    m.add_function(wrap_pyfunction!(local_to_ecef, m)?)?;
    Ok(())
}
