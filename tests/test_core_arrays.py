"""The one contiguity check of the pyo3 layer (rust/src/py/mod.rs `slice`): a strided array
that reaches `_core` directly is a ValueError naming the argument, in every binding area."""

from __future__ import annotations

import numpy as np
import pytest

from usvfast import _core


def strided(a):
    """A non-C-contiguous view with the values and shape of `a`."""
    b = np.repeat(np.asarray(a, dtype=np.float64)[..., None], 2, axis=-1)[..., 0]
    assert not b.flags.c_contiguous
    return b


WGS84 = (6378137.0, 6356752.314245)  # semi-axes a, b (m)
Z2, Z3 = np.zeros(2), np.zeros((2, 3))
ONE = np.zeros(1)


@pytest.mark.parametrize(
    ("name", "call"),
    [
        ("lat", lambda: _core.geodetic_to_ecef(strided(Z2), Z2, Z2, ellipsoid=WGS84, deg=True)),
        ("points", lambda: _core.sensor_to_ned(strided(Z3), np.eye(3), Z3[0], ONE, ONE, ONE, Z3)),
        ("points", lambda: _core.line_of_sight_filter(strided(np.zeros((2, 2))), np.zeros((1, 4)))),
        ("boxes", lambda: _core.nms_indices(strided(np.zeros((2, 4))), np.zeros(2), 0.5)),
    ],
)  # fmt: skip
def test_strided_arrays_are_rejected_by_name(name, call):
    with pytest.raises(ValueError, match=f"{name}: must be a C-contiguous array"):
        call()


def _order(a):
    return "F" if a.flags.f_contiguous and not a.flags.c_contiguous else "C"


@pytest.mark.parametrize(
    ("name", "call"),
    [
        ("cost", lambda a: _core.linear_sum_assignment(a.T.copy(order=_order(a)))),
        ("likelihoods", lambda a: _core.jpda_marginals(a)),
        ("points", lambda a: _core.mean_shift(a, bandwidth=2.0)),
    ],
)
def test_fortran_order_arrays_are_refused_not_misread(name, call):
    # A Fortran-order array is contiguous too: it used to be read as C order (wrong answers,
    # e.g. mean-shift centres 5 m off). The C-order copy is accepted and gives the answer.
    a = np.array([[4.0, 1.0, 3.0], [2.0, 0.5, 5.0], [3.0, 2.0, 2.5], [9.0, 7.0, 1.5]])
    fortran = np.asfortranarray(a)
    assert fortran.flags.f_contiguous and not fortran.flags.c_contiguous
    with pytest.raises(ValueError, match=f"{name}: must be a C-contiguous array"):
        call(fortran)
    call(np.ascontiguousarray(fortran))
