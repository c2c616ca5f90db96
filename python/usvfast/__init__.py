"""usvfast: fast maritime multi-sensor detection and tracking with a Rust core.

The public API is re-exported here; submodules group it by concern
(`usvfast.kalman`, `usvfast.bearing`, ...). Units are SI, angles radians unless a name
ends in `_deg`, times float seconds since the UNIX epoch.
"""

from usvfast._core import (
    DimensionError,
    NonFiniteError,
    NotPositiveDefiniteError,
    TimeOrderError,
    __version__,
)
from usvfast.kalman import (
    ConstantAcceleration,
    ConstantVelocity,
    KalmanResult,
    LinearModel,
    RandomWalk,
    constant_velocity_2d,
    kalman_filter,
    transition_matrices,
)

__all__ = [
    "ConstantAcceleration",
    "ConstantVelocity",
    "DimensionError",
    "KalmanResult",
    "LinearModel",
    "NonFiniteError",
    "NotPositiveDefiniteError",
    "RandomWalk",
    "TimeOrderError",
    "__version__",
    "constant_velocity_2d",
    "kalman_filter",
    "transition_matrices",
]
