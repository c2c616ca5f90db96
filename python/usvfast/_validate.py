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

    Raises TypeError when it is not real numbers (strings and complex values included: never
    silently cut to their real part), DimensionError when `ndim` is given and differs,
    NonFiniteError when it holds NaN or inf (unless `finite` is False: missing values allowed).
    Any memory layout is accepted (Fortran-order input is copied to C order).
    """
    if isinstance(value, str | bytes) or np.iscomplexobj(value):
        raise TypeError(f"{name}: expected real numbers, got {type(value).__name__}")
    try:
        arr = np.ascontiguousarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError) as exc:
        raise TypeError(
            f"{name}: expected an array of numbers, got {type(value).__name__}"
        ) from exc
    if ndim is not None and arr.ndim != ndim:
        raise DimensionError(f"{name}: expected a {ndim}-D array, got shape {arr.shape}")
    if finite and not np.all(np.isfinite(arr)):
        raise NonFiniteError(f"{name}: contains a non-finite value (NaN or inf)")
    return arr


def as_index_array(name: str, value: Any, length: int) -> np.ndarray:
    """Return `value` as a 1-D C-contiguous int64 array of `length` integers (an empty input of
    any dtype is an empty int64 array; the sign is the caller's to check)."""
    arr = np.asarray(value)
    if arr.size == 0:
        arr = arr.astype(np.int64)
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


def real(name: str, value: Any, *, low: float | None = None, positive: bool = False) -> float:
    """`value` as a finite Python float, or raise naming `name`: TypeError for a non-number
    (bool, str, complex, None, arrays of more than one value), NonFiniteError for NaN/inf,
    ValueError when below `low` or, with `positive`, not > 0."""
    if isinstance(value, bool) or value is None:
        raise TypeError(f"{name}: expected a real number, got {type(value).__name__}")
    arr = as_float_array(name, value)
    if arr.size != 1 or arr.ndim > 1:
        raise TypeError(f"{name}: expected one real number, got shape {arr.shape}")
    x = float(arr.reshape(()))
    if positive and not x > 0.0:
        raise ValueError(f"{name}: must be > 0, got {x}")
    if low is not None and x < low:
        raise ValueError(f"{name}: must be >= {low}, got {x}")
    return x


def integer(name: str, value: Any, *, low: int | None = None, high: int | None = None) -> int:
    """`value` as a Python int, or raise naming `name`: TypeError for a non-integer (bool and
    floats included), ValueError outside [`low`, `high`] (so no OverflowError reaches the
    native code)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise TypeError(f"{name}: expected an integer, got {type(value).__name__}")
    v = int(value)
    if (low is not None and v < low) or (high is not None and v > high):
        raise ValueError(f"{name}: must be in [{low}, {high}], got {v}")
    return v


def instance(name: str, value: Any, *types: type) -> Any:
    """`value` when it is an instance of one of `types`, else TypeError naming `name`, the
    expected type(s) and what was given (instead of an AttributeError deeper down)."""
    if not isinstance(value, types):
        want = " or ".join(t.__name__ for t in types)
        raise TypeError(f"{name}: expected {want}, got {type(value).__name__}")
    return value


def with_methods(name: str, value: Any, expected: str, *methods: str) -> Any:
    """`value` when it has every callable in `methods` (a duck-typed camera, say), else
    TypeError naming `name` and the `expected` kind, instead of an AttributeError later."""
    missing = [m for m in methods if not callable(getattr(value, m, None))]
    if missing:
        raise TypeError(
            f"{name}: expected {expected} (with {', '.join(methods)}), got {type(value).__name__}"
        )
    return value


def finite_result(name: str, value: np.ndarray, inputs: str) -> np.ndarray:
    """`value` when every entry is finite, else ValueError: a result that over- or
    underflowed from finite `inputs` (named in the message) is an error, never a NaN."""
    if not np.all(np.isfinite(value)):
        raise ValueError(f"{inputs}: out of the representable range ({name} is not finite)")
    return value


def image(name: str, value: Any) -> np.ndarray:
    """`value` when it is an 8- or 16-bit image array (h, w) or (h, w, c), c in 1, 3, 4, with
    pixels, else TypeError (not an image) or ValueError (no pixel) naming `name`."""
    if not isinstance(value, np.ndarray) or value.dtype not in (np.uint8, np.uint16):
        got = value.dtype if isinstance(value, np.ndarray) else type(value).__name__
        raise TypeError(f"{name}: expected a uint8 or uint16 image array, got {got}")
    if not (value.ndim == 2 or (value.ndim == 3 and value.shape[2] in (1, 3, 4))):
        raise TypeError(f"{name}: expected an (h, w) or (h, w, 3) image, got shape {value.shape}")
    if value.size == 0:
        raise ValueError(f"{name}: the image has no pixel (shape {value.shape})")
    return value
