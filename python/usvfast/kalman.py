"""Linear-Gaussian Kalman filtering and RTS smoothing of whole sequences in one Rust call.

Motion models are discretised exactly as Stone Soup's (`ConstantVelocity`, `RandomWalk`,
`ConstantAcceleration`, combined block-diagonally like
`CombinedLinearGaussianTransitionModel`); filter and smoother equal filterpy's
`KalmanFilter` + `rts_smoother` and Stone Soup's `KalmanPredictor`/`KalmanUpdater`/
`RauchTungStriebelSmoother` to rounding.

Example::

    import numpy as np
    from usvfast.kalman import ConstantVelocity, kalman_filter

    t = np.array([0.0, 0.5, 1.3, 1.4])
    z = np.array([[0.1], [0.6], [1.2], [1.5]])
    run = kalman_filter(t, z, motion_model=ConstantVelocity(0.01),
                        measurement_matrix=[[1.0, 0.0]],
                        measurement_noise=[[[0.49]], [[1.0]]], sensor_index=[0, 1, 0, 1],
                        prior_state=[0.0, 0.0], prior_covariance=np.diag([100.0, 1.0]))
    run.smoothed_states[:, 0]
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from usvfast import _core
from usvfast._validate import as_float_array, as_index_array


@dataclass(frozen=True)
class RandomWalk:
    """Position-only random walk: F = [1], Q = [q·dt]; `noise_diff_coeff` = q."""

    noise_diff_coeff: float
    kind = "random_walk"


@dataclass(frozen=True)
class ConstantVelocity:
    """Discretised Wiener velocity on one axis, state [x, ẋ]:
    F = [[1, dt], [0, 1]], Q = q·[[dt³/3, dt²/2], [dt²/2, dt]]; `noise_diff_coeff` = q."""

    noise_diff_coeff: float
    kind = "constant_velocity"


@dataclass(frozen=True)
class ConstantAcceleration:
    """Discretised Wiener acceleration on one axis, state [x, ẋ, ẍ]; `noise_diff_coeff` = q."""

    noise_diff_coeff: float
    kind = "constant_acceleration"


Component = RandomWalk | ConstantVelocity | ConstantAcceleration
MotionModel = Component | Sequence[Component]


def constant_velocity_2d(noise_diff_coeff: float) -> tuple[ConstantVelocity, ConstantVelocity]:
    """The surface-track model: state [n, v_n, e, v_e] (metres, m/s), same q on both axes."""
    return (ConstantVelocity(noise_diff_coeff), ConstantVelocity(noise_diff_coeff))


def model_spec(motion_model: MotionModel) -> list[tuple[str, float]]:
    """The `[(kind, q), ...]` list the Rust core takes for a model or list of components."""
    components = (
        [motion_model]
        if isinstance(motion_model, RandomWalk | ConstantVelocity | ConstantAcceleration)
        else list(motion_model)
    )
    spec = []
    for c in components:
        if not isinstance(c, RandomWalk | ConstantVelocity | ConstantAcceleration):
            raise TypeError(f"motion_model: unsupported component {c!r}")
        spec.append((c.kind, float(c.noise_diff_coeff)))
    return spec


def transition_matrices(motion_model: MotionModel, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition matrix F(dt) and process noise Q(dt), each (ndim, ndim); dt in seconds."""
    return _core.motion_matrices(model_spec(motion_model), float(dt))


@dataclass(frozen=True)
class KalmanResult:
    """Arrays of a batch run over n measurements of an ndim-state model.

    States are (n, ndim), covariances (n, ndim, ndim): `predicted_*` before each update,
    `filtered_*` after it, `smoothed_*` after the RTS pass (None when not smoothed).
    `nis` and `log_likelihood` are (n,), one per update.
    """

    predicted_states: np.ndarray
    predicted_covariances: np.ndarray
    filtered_states: np.ndarray
    filtered_covariances: np.ndarray
    nis: np.ndarray
    log_likelihood: np.ndarray
    smoothed_states: np.ndarray | None = None
    smoothed_covariances: np.ndarray | None = None


def kalman_filter(
    times: Any,
    measurements: Any,
    *,
    motion_model: MotionModel,
    measurement_matrix: Any,
    measurement_noise: Any,
    prior_state: Any,
    prior_covariance: Any,
    sensor_index: Any = None,
    prior_time: float | None = None,
    smooth: bool = True,
) -> KalmanResult:
    """Kalman-filter (and RTS-smooth) a whole sequence in one Rust call.

    times: (n,) seconds, non-decreasing. measurements: (n, m), or (n,) for m = 1.
    measurement_matrix: (m, ndim). measurement_noise: (m, m), or a stack (k, m, m) chosen per
    measurement by `sensor_index` ((n,) integers in [0, k)). prior_state (ndim,) and
    prior_covariance (ndim, ndim) hold at `prior_time` (default: times[0]).
    Raises ValueError subclasses naming the argument on bad shapes, non-finite values,
    non-positive-definite noise, or times going backwards.
    """
    t = as_float_array("times", times, ndim=1)
    z = as_float_array("measurements", measurements)
    if z.ndim == 1:
        z = z.reshape(-1, 1)
    if z.ndim != 2:
        raise _core.DimensionError(f"measurements: expected (n, m) or (n,), got shape {z.shape}")
    r = as_float_array("measurement_noise", measurement_noise)
    if r.ndim == 2:
        r = r[np.newaxis]
    if r.ndim != 3:
        raise _core.DimensionError(
            f"measurement_noise: expected (m, m) or (k, m, m), got shape {r.shape}"
        )
    idx = None if sensor_index is None else as_index_array("sensor_index", sensor_index, len(t))
    out = _core.kalman_batch(
        model_spec(motion_model),
        t,
        z,
        as_float_array("measurement_matrix", measurement_matrix, ndim=2),
        r,
        as_float_array("prior_state", prior_state, ndim=1),
        as_float_array("prior_covariance", prior_covariance, ndim=2),
        sensor_index=idx,
        prior_time=None if prior_time is None else float(prior_time),
        smooth=smooth,
    )
    return KalmanResult(**out)
