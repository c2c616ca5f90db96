"""Angle wrapping (usvfast._angles): intervals, equivalence modulo the period (against
math.remainder as the peer), NaN passthrough and the tiny-negative edge of np.mod."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from usvfast._angles import wrap_2pi, wrap_180_deg, wrap_360_deg, wrap_deg, wrap_pi

angles = st.floats(-1e4, 1e4)
CASES = [
    # function, period, low, high, low included
    (wrap_2pi, 2 * math.pi, 0.0, 2 * math.pi, True),
    (wrap_pi, 2 * math.pi, -math.pi, math.pi, True),
    (wrap_360_deg, 360.0, 0.0, 360.0, True),
    (wrap_180_deg, 360.0, -180.0, 180.0, True),
    (wrap_deg, 360.0, -180.0, 180.0, False),
]


@pytest.mark.parametrize(("wrap", "period", "low", "high", "low_closed"), CASES)
@given(a=angles)
def test_interval_and_same_angle(wrap, period, low, high, low_closed, a):
    w = float(wrap(a))
    assert (low <= w < high) if low_closed else (low < w <= high)
    # Same angle: the difference is a multiple of the period (math.remainder is exact).
    assert abs(math.remainder(w - a, period)) < 1e-9


@pytest.mark.parametrize(("wrap", "period", "low", "high", "low_closed"), CASES)
def test_edges_shapes_and_nan(wrap, period, low, high, low_closed):
    # np.mod(-1e-17, period) rounds to the period itself; the wraps stay in their interval.
    for a in (-1e-17, low - 1e-15, high + 1e-15, low, high):
        w = float(wrap(a))
        assert (low <= w < high) if low_closed else (low < w <= high), (a, w)
    x = np.array([[0.5, np.nan], [3 * period, -period]])
    w = wrap(x)
    assert w.shape == (2, 2) and w.dtype == np.float64 and np.isnan(w[0, 1])
    assert np.ndim(wrap(0.25)) == 0


def test_conventions():
    assert wrap_deg(-180.0) == 180.0 and wrap_deg(180.0) == 180.0
    assert wrap_180_deg(180.0) == -180.0 and wrap_pi(math.pi) == -math.pi
    assert wrap_2pi(-math.pi / 2) == pytest.approx(1.5 * math.pi)
    assert wrap_360_deg(-90.0) == 270.0
