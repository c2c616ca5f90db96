"""Angle wrapping, the one home for every module: radians and degrees, any array shape.

NaN stays NaN; every function returns float64 of the input's shape. `np.mod` of a tiny negative
number rounds up to the period itself, so the half-open intervals are enforced explicitly.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["wrap_2pi", "wrap_180_deg", "wrap_360_deg", "wrap_deg", "wrap_pi"]

TWO_PI = 2.0 * np.pi


def _wrap_period(a: Any, period: float) -> np.ndarray:
    """`a` modulo `period` in [0, period)."""
    w = np.mod(np.asarray(a, dtype=np.float64), period)
    return np.where(w >= period, 0.0, w)


def wrap_2pi(a: Any) -> np.ndarray:
    """Angles (radians) into [0, 2π), e.g. headings and bearings clockwise from north."""
    return _wrap_period(a, TWO_PI)


def wrap_pi(a: Any) -> np.ndarray:
    """Angles (radians) into [-π, π), e.g. relative bearings and shortest-arc differences."""
    return _wrap_period(np.asarray(a, dtype=np.float64) + np.pi, TWO_PI) - np.pi


def wrap_360_deg(a_deg: Any) -> np.ndarray:
    """Angles (degrees) into [0°, 360°)."""
    return _wrap_period(a_deg, 360.0)


def wrap_180_deg(a_deg: Any) -> np.ndarray:
    """Angles (degrees) into [-180°, 180°), the degree twin of `wrap_pi` (longitudes,
    shortest-arc differences)."""
    return _wrap_period(np.asarray(a_deg, dtype=np.float64) + 180.0, 360.0) - 180.0


def wrap_deg(a_deg: Any) -> np.ndarray:
    """Angles (degrees) into (-180°, 180°]: +180° stays +180°, -180° becomes +180° (the
    bearing convention of `usvfast.bearing`)."""
    # 180 - ((180 - a) mod 360) lies in (-180, 180]: the mod is in [0, 360).
    return 180.0 - _wrap_period(180.0 - np.asarray(a_deg, dtype=np.float64), 360.0)
