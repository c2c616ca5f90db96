"""Argument checks shared by the Python layer: every failure names the argument."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from usvfast._core import DimensionError, NonFiniteError


def as_float_array(
    name: str, value: Any, ndim: int | None = None, *, finite: bool = True
) -> np.ndarray:
    """Return `value` as a C-contiguous float64 array, or raise naming `name`.

    Raises TypeError when it is not numeric, DimensionError when `ndim` is given and differs,
    NonFiniteError when it holds NaN or inf (unless `finite` is False: missing values allowed).
    """
    try:
        arr = np.ascontiguousarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TypeError(
            f"{name}: expected an array of numbers, got {type(value).__name__}"
        ) from exc
    if ndim is not None and arr.ndim != ndim:
        raise DimensionError(f"{name}: expected a {ndim}-D array, got shape {arr.shape}")
    if finite and not np.all(np.isfinite(arr)):
        raise NonFiniteError(f"{name}: contains a non-finite value (NaN or inf)")
    return arr


def as_index_array(name: str, value: Any, length: int) -> np.ndarray:
    """Return `value` as a 1-D C-contiguous int64 array of `length` non-negative integers."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "iu":
        raise TypeError(f"{name}: expected integers, got dtype {arr.dtype}")
    arr = np.ascontiguousarray(arr, dtype=np.int64)
    if arr.shape != (length,):
        raise DimensionError(f"{name}: expected shape ({length},), got {arr.shape}")
    return arr


def broadcast_shape(arrays: Mapping[str, np.ndarray]) -> tuple[int, ...]:
    """The common broadcast shape of the named arrays, or DimensionError naming them all with
    their shapes."""
    try:
        return np.broadcast_shapes(*(np.shape(a) for a in arrays.values()))
    except ValueError as exc:
        shapes = ", ".join(f"{name} {np.shape(a)}" for name, a in arrays.items())
        raise DimensionError(f"{', '.join(arrays)}: shapes do not broadcast ({shapes})") from exc


def broadcast(arrays: Mapping[str, np.ndarray]) -> list[np.ndarray]:
    """The named arrays broadcast to their common shape (read-only views, in order), or
    DimensionError as `broadcast_shape`."""
    shape = broadcast_shape(arrays)
    return [np.broadcast_to(a, shape) for a in arrays.values()]
