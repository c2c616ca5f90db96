"""WGS84 geodesy in Rust under pymap3d's names: switch by changing one import.

    from usvfast import geodesy as pm   # instead of: import pymap3d as pm

Geodetic ↔ ECEF ↔ local NED/ENU at a geodetic origin, with exact formulas (ECEF → geodetic by
Vermeille's closed form, sub-nanometre round trips, poles included). Every function takes
scalars or arrays that broadcast together (numpy rules, including the origin), returns a
tuple of three arrays of the broadcast shape (numpy float64 scalars for scalar input), and
equals pymap3d to well under a millimetre.

Conventions as pymap3d: angles in degrees unless `deg=False` (then radians), lengths in
metres, heights above the ellipsoid, `ell` an ellipsoid object with `semimajor_axis` and
`semiminor_axis` in metres (for example `pymap3d.Ellipsoid`), WGS84 when None.
NED = (north, east, down), ENU = (east, north, up), both at (lat0, lon0, h0).

Failure contract (stricter than pymap3d): ValueError naming the argument when |lat| > 90°,
`usvfast.NonFiniteError` on NaN/inf, `usvfast.DimensionError` when shapes do not broadcast,
TypeError for non-numeric input.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike

from usvfast import _core
from usvfast._validate import as_float_array, broadcast_shape, finite_result

__all__ = [
    "WGS84",
    "ecef2enu",
    "ecef2geodetic",
    "ecef2ned",
    "enu2ecef",
    "enu2geodetic",
    "geodetic2ecef",
    "geodetic2enu",
    "geodetic2ned",
    "ned2ecef",
    "ned2geodetic",
]

#: WGS84 semi-axes (a, b) in metres.
WGS84 = (6378137.0, 6378137.0 * (1.0 - 1.0 / 298.257223563))

Triple = tuple[Any, Any, Any]


class EllipsoidLike(Protocol):
    """An ellipsoid as pymap3d's `Ellipsoid`: semi-axes in metres."""

    semimajor_axis: float
    semiminor_axis: float


def _semi_axes(ell: EllipsoidLike | None) -> tuple[float, float]:
    if ell is None:
        return WGS84
    try:
        return float(ell.semimajor_axis), float(ell.semiminor_axis)
    except AttributeError as exc:
        raise TypeError(
            "ell: expected None or an ellipsoid with semimajor_axis and semiminor_axis, "
            f"got {type(ell).__name__}"
        ) from exc


def _flat(args: dict[str, Any]) -> tuple[tuple[int, ...], list[np.ndarray]]:
    """Broadcast the named arguments; return the common shape and one flat float64 column per
    argument (length 1 when the argument is a single value, so nothing is materialised)."""
    arrays = [as_float_array(name, value) for name, value in args.items()]
    # as_float_array makes scalars 1-D; keep them 0-D so scalar in gives scalar out.
    arrays = [
        a.reshape(()) if np.ndim(v) == 0 else a for a, v in zip(arrays, args.values(), strict=True)
    ]
    shape = broadcast_shape(dict(zip(args, arrays, strict=True)))
    cols = []
    for a in arrays:
        if a.size == 1:
            cols.append(a.reshape(1))
        elif a.shape == shape:
            cols.append(a.reshape(-1))
        else:
            cols.append(np.ascontiguousarray(np.broadcast_to(a, shape)).reshape(-1))
    return shape, cols


def _shaped(shape: tuple[int, ...], out: Triple) -> Triple:
    # finite inputs (checked by _flat) that over- or underflow are an error, never a NaN
    for a in out:
        finite_result("a coordinate", np.asarray(a), "inputs")
    if shape == ():
        return out[0][0], out[1][0], out[2][0]
    return out[0].reshape(shape), out[1].reshape(shape), out[2].reshape(shape)


def _empty(shape: tuple[int, ...]) -> Triple:
    return np.empty(shape), np.empty(shape), np.empty(shape)


def geodetic2ecef(
    lat: ArrayLike,
    lon: ArrayLike,
    alt: ArrayLike,
    ell: EllipsoidLike | None = None,
    deg: bool = True,
) -> Triple:
    """Geodetic (lat, lon, alt) → ECEF (x, y, z) in metres."""
    shape, cols = _flat({"lat": lat, "lon": lon, "alt": alt})
    if 0 in shape:
        return _empty(shape)
    return _shaped(shape, _core.geodetic_to_ecef(*cols, ellipsoid=_semi_axes(ell), deg=deg))


def ecef2geodetic(
    x: ArrayLike, y: ArrayLike, z: ArrayLike, ell: EllipsoidLike | None = None, deg: bool = True
) -> Triple:
    """ECEF (x, y, z) in metres → geodetic (lat, lon, alt); longitude in (-180°, 180°]."""
    shape, cols = _flat({"x": x, "y": y, "z": z})
    if 0 in shape:
        return _empty(shape)
    return _shaped(shape, _core.ecef_to_geodetic(*cols, ellipsoid=_semi_axes(ell), deg=deg))


def _local(
    core_fn: Any, frame: str, args: dict[str, Any], ell: EllipsoidLike | None, deg: bool
) -> Triple:
    """Origin-relative conversion; local triples are (n, e, d) for NED, (e, n, u) for ENU."""
    shape, cols = _flat(args)
    if 0 in shape:
        return _empty(shape)
    out = core_fn(frame, *cols, ellipsoid=_semi_axes(ell), deg=deg)
    return _shaped(shape, out)


def geodetic2ned(
    lat: ArrayLike,
    lon: ArrayLike,
    h: ArrayLike,
    lat0: ArrayLike,
    lon0: ArrayLike,
    h0: ArrayLike,
    ell: EllipsoidLike | None = None,
    deg: bool = True,
) -> Triple:
    """Geodetic points → (north, east, down) in metres at the origin (lat0, lon0, h0)."""
    args = {"lat": lat, "lon": lon, "h": h, "lat0": lat0, "lon0": lon0, "h0": h0}
    return _local(_core.geodetic_to_local, "ned", args, ell, deg)


def ned2geodetic(
    n: ArrayLike,
    e: ArrayLike,
    d: ArrayLike,
    lat0: ArrayLike,
    lon0: ArrayLike,
    h0: ArrayLike,
    ell: EllipsoidLike | None = None,
    deg: bool = True,
) -> Triple:
    """(north, east, down) in metres at the origin → geodetic (lat, lon, h)."""
    args = {"n": n, "e": e, "d": d, "lat0": lat0, "lon0": lon0, "h0": h0}
    return _local(_core.local_to_geodetic, "ned", args, ell, deg)


def geodetic2enu(
    lat: ArrayLike,
    lon: ArrayLike,
    h: ArrayLike,
    lat0: ArrayLike,
    lon0: ArrayLike,
    h0: ArrayLike,
    ell: EllipsoidLike | None = None,
    deg: bool = True,
) -> Triple:
    """Geodetic points → (east, north, up) in metres at the origin (lat0, lon0, h0)."""
    args = {"lat": lat, "lon": lon, "h": h, "lat0": lat0, "lon0": lon0, "h0": h0}
    return _local(_core.geodetic_to_local, "enu", args, ell, deg)


def enu2geodetic(
    e: ArrayLike,
    n: ArrayLike,
    u: ArrayLike,
    lat0: ArrayLike,
    lon0: ArrayLike,
    h0: ArrayLike,
    ell: EllipsoidLike | None = None,
    deg: bool = True,
) -> Triple:
    """(east, north, up) in metres at the origin → geodetic (lat, lon, h)."""
    args = {"e": e, "n": n, "u": u, "lat0": lat0, "lon0": lon0, "h0": h0}
    return _local(_core.local_to_geodetic, "enu", args, ell, deg)


def ecef2ned(
    x: ArrayLike,
    y: ArrayLike,
    z: ArrayLike,
    lat0: ArrayLike,
    lon0: ArrayLike,
    h0: ArrayLike,
    ell: EllipsoidLike | None = None,
    deg: bool = True,
) -> Triple:
    """ECEF points (metres) → (north, east, down) in metres at the origin."""
    args = {"x": x, "y": y, "z": z, "lat0": lat0, "lon0": lon0, "h0": h0}
    return _local(_core.ecef_to_local, "ned", args, ell, deg)


def ned2ecef(
    n: ArrayLike,
    e: ArrayLike,
    d: ArrayLike,
    lat0: ArrayLike,
    lon0: ArrayLike,
    h0: ArrayLike,
    ell: EllipsoidLike | None = None,
    deg: bool = True,
) -> Triple:
    """(north, east, down) in metres at the origin → ECEF (x, y, z) in metres."""
    args = {"n": n, "e": e, "d": d, "lat0": lat0, "lon0": lon0, "h0": h0}
    return _local(_core.local_to_ecef, "ned", args, ell, deg)


def ecef2enu(
    x: ArrayLike,
    y: ArrayLike,
    z: ArrayLike,
    lat0: ArrayLike,
    lon0: ArrayLike,
    h0: ArrayLike,
    ell: EllipsoidLike | None = None,
    deg: bool = True,
) -> Triple:
    """ECEF points (metres) → (east, north, up) in metres at the origin."""
    args = {"x": x, "y": y, "z": z, "lat0": lat0, "lon0": lon0, "h0": h0}
    return _local(_core.ecef_to_local, "enu", args, ell, deg)


def enu2ecef(
    e1: ArrayLike,
    n1: ArrayLike,
    u1: ArrayLike,
    lat0: ArrayLike,
    lon0: ArrayLike,
    h0: ArrayLike,
    ell: EllipsoidLike | None = None,
    deg: bool = True,
) -> Triple:
    """(east, north, up) in metres at the origin → ECEF (x, y, z) in metres."""
    args = {"e1": e1, "n1": n1, "u1": u1, "lat0": lat0, "lon0": lon0, "h0": h0}
    return _local(_core.local_to_ecef, "enu", args, ell, deg)
