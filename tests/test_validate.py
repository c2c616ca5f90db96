"""Argument broadcasting shared by geodesy and bearing.camera, against numpy's own rules."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis.extra import numpy as hnp

from usvfast import DimensionError
from usvfast._validate import broadcast, broadcast_shape


@given(hnp.mutually_broadcastable_shapes(num_shapes=3))
def test_same_shapes_as_numpy(shapes):
    arrays = {name: np.ones(s) for name, s in zip("abc", shapes.input_shapes, strict=True)}
    assert broadcast_shape(arrays) == shapes.result_shape
    for ours, ref in zip(broadcast(arrays), np.broadcast_arrays(*arrays.values()), strict=True):
        assert ours.shape == ref.shape


def test_error_names_every_argument():
    with pytest.raises(DimensionError, match=r"^x_px, y_px, zoom: shapes do not broadcast") as e:
        broadcast({"x_px": np.zeros(3), "y_px": np.zeros(2), "zoom": np.float64(1.0)})
    assert "x_px (3,), y_px (2,), zoom ()" in str(e.value)
