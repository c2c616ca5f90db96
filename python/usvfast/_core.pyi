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

# --- tracker (rust/src/py/tracker.rs) ---
class TrackerCore:
    def __init__(
        self,
        motion_model: list[tuple[str, float]],
        sensors: list[tuple[npt.NDArray[np.float64], ...]],
        association: dict[str, object],
        deleter_spec: tuple[object, ...],
        initiator: dict[str, object],
        *,
        use_joseph_cov: bool = False,
        delete_last_prediction: bool = False,
        out_of_order: str = "raise",
        initiate_in_gates: bool = True,
    ) -> None: ...
    def step(
        self, t: float, measurements: npt.NDArray[np.float64], sensor_ids: npt.NDArray[np.int64]
    ) -> bool: ...
    def run(
        self,
        times: npt.NDArray[np.float64],
        measurements: npt.NDArray[np.float64],
        sensor_ids: npt.NDArray[np.int64],
        scan_index: npt.NDArray[np.int64],
    ) -> dict[str, npt.NDArray[np.generic]]: ...
    def add_track(
        self, state: npt.NDArray[np.float64], covariance: npt.NDArray[np.float64], time: float
    ) -> int: ...
    def snapshot(self, tentative: bool = False) -> dict[str, npt.NDArray[np.generic]]: ...
    def track_ids(self) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]: ...
    def history(self, track_id: int) -> dict[str, object]: ...
    @property
    def dropped_scans(self) -> int: ...
    @property
    def last_time(self) -> float | None: ...

def linear_sum_assignment(cost: npt.NDArray[np.float64]) -> npt.NDArray[np.int64]: ...
def jpda_marginals(
    likelihoods: npt.NDArray[np.float64], method: str = "ehm"
) -> npt.NDArray[np.float64]: ...
def chi2_gate(prob_gate: float, dof: int) -> float: ...
