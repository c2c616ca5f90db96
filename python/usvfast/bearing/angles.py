"""Angle helpers in degrees: wrap to (-180°, 180°] and unwrap a sequence."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast._angles import wrap_deg as _wrap_deg
from usvfast._validate import as_float_array

__all__ = ["float_array", "unwrap_deg", "wrap_deg"]


def float_array(name: str, value: Any) -> np.ndarray:
    """`as_float_array` that keeps the shape of scalars (0-D in, 0-D out)."""
    return as_float_array(name, value).reshape(np.shape(value))


def wrap_deg(angle_deg: ArrayLike) -> np.ndarray:
    """Angles (degrees, any shape) into (-180°, 180°] (+180° stays, -180° becomes +180°).
    Raises NonFiniteError / TypeError naming `angle_deg` on NaN, inf or non-numbers."""
    return _wrap_deg(float_array("angle_deg", angle_deg))


def unwrap_deg(angle_deg: ArrayLike) -> np.ndarray:
    """Unwrap a 1-D sequence of angles (degrees): each value moves by a multiple of 360° to
    lie within 180° of the previous unwrapped value, so the sequence has no ±360° jumps.

    The first value is kept as given. Returns float64 (n,). Raises NonFiniteError /
    TypeError naming `angle_deg` on NaN, inf or non-numbers.
    """
    return unwrap_raw_deg(float_array("angle_deg", angle_deg))


def unwrap_raw_deg(angle_deg: ArrayLike) -> np.ndarray:
    """`unwrap_deg` without the input check, for the package's own arrays (NaN marks a gap)."""
    a = np.asarray(angle_deg, dtype=np.float64)
    if a.size == 0:
        return a.copy()
    return np.unwrap(a, period=360.0)
