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

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

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


@dataclass(frozen=True)
class LinearModel:
    """A general linear-Gaussian transition, filterpy's `F` and `Q` given by the user.

    Either fixed matrices, used at every prediction whatever the time step (a discrete-time
    model such as a pixel tracker's `dt = 1` per frame), or a function `of_dt(dt) -> (F, Q)`
    evaluated at each prediction's time step `dt` (seconds). F and Q are (ndim, ndim); Q must
    be symmetric positive semi-definite (checked in Rust).

    Example: the constant-velocity pixel model of Kim, Chung and Lee (eq. 11), state
    [x, y, v_x, v_y] in pixels and pixels per frame::

        F = np.eye(4); F[0, 2] = F[1, 3] = 1.0
        LinearModel(F, np.eye(4))
    """

    transition_matrix: Any = None
    process_noise: Any = None
    of_dt: Callable[[float], tuple[Any, Any]] | None = None

    def __post_init__(self) -> None:
        fixed = self.transition_matrix is not None or self.process_noise is not None
        if fixed == (self.of_dt is not None):
            raise TypeError(
                "LinearModel: give transition_matrix and process_noise, or of_dt, not both"
            )
        if fixed and (self.transition_matrix is None or self.process_noise is None):
            raise TypeError("LinearModel: give both transition_matrix and process_noise")
        if self.of_dt is not None and not callable(self.of_dt):
            raise TypeError(f"of_dt: expected a callable dt -> (F, Q), got {self.of_dt!r}")

    def matrices(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """F and Q, each (ndim, ndim), of a prediction over `dt` seconds."""
        if self.of_dt is None:
            f, q = self.transition_matrix, self.process_noise
        else:
            f, q = self.of_dt(float(dt))
        return (
            as_float_array("transition_matrix", f, ndim=2),
            as_float_array("process_noise", q, ndim=2),
        )

    def stacks(self, steps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(k, ndim, ndim) stacks of F and Q for the Rust core: one pair when fixed, else one
        pair per time step in `steps` (seconds)."""
        if self.of_dt is None:
            f, q = self.matrices(1.0)
            return np.ascontiguousarray(f[np.newaxis]), np.ascontiguousarray(q[np.newaxis])
        pairs = [self.matrices(dt) for dt in steps]
        if not pairs:
            raise ValueError("times: at least one measurement is needed with of_dt")
        shapes = {(f.shape, q.shape) for f, q in pairs}
        if len(shapes) != 1:
            raise _core.DimensionError(f"of_dt: returned matrices of several shapes {shapes}")
        return (
            np.ascontiguousarray(np.stack([f for f, _ in pairs])),
            np.ascontiguousarray(np.stack([q for _, q in pairs])),
        )


Component = RandomWalk | ConstantVelocity | ConstantAcceleration
MotionModel = Component | Sequence[Component] | LinearModel


def constant_velocity_2d(noise_diff_coeff: float) -> tuple[ConstantVelocity, ConstantVelocity]:
    """The surface-track model: state [n, v_n, e, v_e] (metres, m/s), same q on both axes."""
    return (ConstantVelocity(noise_diff_coeff), ConstantVelocity(noise_diff_coeff))


def model_spec(motion_model: MotionModel) -> list[tuple[str, float]]:
    """The `[(kind, q), ...]` list the Rust core takes for a model or list of components."""
    if isinstance(motion_model, LinearModel):
        raise TypeError("motion_model: a LinearModel has no component spec")
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
    if isinstance(motion_model, LinearModel):
        return motion_model.matrices(dt)
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
    times: ArrayLike,
    measurements: ArrayLike,
    *,
    motion_model: MotionModel,
    measurement_matrix: ArrayLike,
    measurement_noise: ArrayLike,
    prior_state: ArrayLike,
    prior_covariance: ArrayLike,
    sensor_index: ArrayLike | None = None,
    prior_time: float | None = None,
    smooth: bool = True,
) -> KalmanResult:
    """Kalman-filter (and RTS-smooth) a whole sequence in one Rust call.

    times: (n,) seconds, non-decreasing. measurements: (n, m), or (n,) for m = 1.
    measurement_matrix: (m, ndim). measurement_noise: (m, m), or a stack (k, m, m) chosen per
    measurement by `sensor_index` ((n,) integers in [0, k)). prior_state (ndim,) and
    prior_covariance (ndim, ndim) hold at `prior_time` (default: times[0]).
    motion_model: components (discretised at each dt) or a `LinearModel`; a fixed
    LinearModel predicts with its F, Q before every measurement, the first included (put the
    prior one step before times[0] for a per-frame model), while an `of_dt` one is evaluated at
    each dt (dt = 0 before the first measurement when prior_time is not given).
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
    args = (
        t,
        z,
        as_float_array("measurement_matrix", measurement_matrix, ndim=2),
        r,
        as_float_array("prior_state", prior_state, ndim=1),
        as_float_array("prior_covariance", prior_covariance, ndim=2),
    )
    kwargs = {
        "sensor_index": idx,
        "prior_time": None if prior_time is None else float(prior_time),
        "smooth": smooth,
    }
    if isinstance(motion_model, LinearModel):
        start = t[0] if prior_time is None or len(t) == 0 else float(prior_time)
        f, q = motion_model.stacks(np.diff(t, prepend=start))
        out = _core.kalman_batch_linear(f, q, *args, **kwargs)
    else:
        out = _core.kalman_batch(model_spec(motion_model), *args, **kwargs)
    return KalmanResult(**out)


def predict_states(
    states: ArrayLike,
    covariances: ArrayLike,
    *,
    transition_matrix: ArrayLike,
    process_noise: ArrayLike,
) -> tuple[np.ndarray, np.ndarray]:
    """Predict k independent states with one F and Q in one Rust call (a tracker's step).

    states: (k, ndim); covariances: (k, ndim, ndim); transition_matrix and process_noise:
    (ndim, ndim). Returns the predicted (states, covariances), same shapes: x = F x,
    P = F P Fᵀ + Q. Raises ValueError subclasses naming the argument on bad input.
    """
    x = as_float_array("states", states, ndim=2)
    p = as_float_array("covariances", covariances, ndim=3)
    return _core.kalman_predict(
        x,
        p,
        as_float_array("transition_matrix", transition_matrix, ndim=2),
        as_float_array("process_noise", process_noise, ndim=2),
    )


def update_states(
    states: ArrayLike,
    covariances: ArrayLike,
    measurements: ArrayLike,
    *,
    measurement_matrix: ArrayLike,
    measurement_noise: ArrayLike,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Update state i of a stack with measurement row i in one Rust call (Joseph form).

    states: (k, ndim); covariances: (k, ndim, ndim); measurements: (k, m);
    measurement_matrix: (m, ndim); measurement_noise: (m, m) positive definite.
    Returns (states, covariances, nis) with nis (k,) the normalised innovation squared.
    """
    x = as_float_array("states", states, ndim=2)
    p = as_float_array("covariances", covariances, ndim=3)
    return _core.kalman_update(
        x,
        p,
        as_float_array("measurements", measurements, ndim=2),
        as_float_array("measurement_matrix", measurement_matrix, ndim=2),
        as_float_array("measurement_noise", measurement_noise, ndim=2),
    )
