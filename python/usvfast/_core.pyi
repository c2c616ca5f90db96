# Type stubs of the native module usvfast._core (rust/src/py/). tests/test_stubs.py checks
# that every runtime name has a stub here with the same parameter names, and vice versa.
import numpy as np
import numpy.typing as npt

__version__: str

class DimensionError(ValueError): ...
class NonFiniteError(ValueError): ...
class NotPositiveDefiniteError(ValueError): ...
class TimeOrderError(ValueError): ...

# --- kalman (rust/src/py/kalman.rs) ---
def motion_matrices(
    motion_model: list[tuple[str, float]], dt: float
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def kalman_batch(
    motion_model: list[tuple[str, float]],
    times: npt.NDArray[np.float64],
    measurements: npt.NDArray[np.float64],
    measurement_matrix: npt.NDArray[np.float64],
    measurement_noise: npt.NDArray[np.float64],
    prior_state: npt.NDArray[np.float64],
    prior_covariance: npt.NDArray[np.float64],
    *,
    sensor_index: npt.NDArray[np.int64] | None = None,
    prior_time: float | None = None,
    smooth: bool = True,
) -> dict[str, npt.NDArray[np.float64]]: ...

# --- camera (rust/src/py/camera.rs) ---
def nms_indices(
    boxes: npt.NDArray[np.float64],
    scores: npt.NDArray[np.float64],
    iou_threshold: float,
    classes: npt.NDArray[np.int64] | None = None,
) -> npt.NDArray[np.int64]: ...
def georeference_rays(
    normalized: npt.NDArray[np.float64],
    jacobian: npt.NDArray[np.float64],
    roll: npt.NDArray[np.float64],
    pitch: npt.NDArray[np.float64],
    height: npt.NDArray[np.float64],
    r_body_cam: npt.NDArray[np.float64],
    cam_position: tuple[float, float, float],
    *,
    heading: npt.NDArray[np.float64] | None = None,
    vessel_ne: npt.NDArray[np.float64] | None = None,
    min_depression: float = 0.0,
    sigma_px: tuple[float, float] = (0.0, 0.0),
    sigma_roll_pitch: tuple[float, float] = (0.0, 0.0),
    sigma_height: float = 0.0,
    sigma_heading: float = 0.0,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.uint8]]: ...
