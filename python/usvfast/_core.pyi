# Type stubs of the native module usvfast._core (rust/src/py/). tests/test_stubs.py checks
# that every runtime name has a stub here with the same parameter names, and vice versa.
from typing import Any, TypedDict

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
def kalman_batch_linear(
    transition_matrices: npt.NDArray[np.float64],
    process_noises: npt.NDArray[np.float64],
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
def kalman_predict(
    states: npt.NDArray[np.float64],
    covariances: npt.NDArray[np.float64],
    transition_matrix: npt.NDArray[np.float64],
    process_noise: npt.NDArray[np.float64],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def kalman_update(
    states: npt.NDArray[np.float64],
    covariances: npt.NDArray[np.float64],
    measurements: npt.NDArray[np.float64],
    measurement_matrix: npt.NDArray[np.float64],
    measurement_noise: npt.NDArray[np.float64],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...

# --- lidar (rust/src/py/lidar.rs) ---
def line_of_sight_filter(
    points: npt.NDArray[np.float64],
    segments: npt.NDArray[np.float64],
    *,
    sensor: tuple[float, float] = (0.0, 0.0),
    tolerance: float = 0.1,
) -> npt.NDArray[np.bool_]: ...
def line_of_sight_filter_naive(
    points: npt.NDArray[np.float64],
    segments: npt.NDArray[np.float64],
    *,
    sensor: tuple[float, float] = (0.0, 0.0),
    tolerance: float = 0.1,
) -> npt.NDArray[np.bool_]: ...
def mean_shift(
    points: npt.NDArray[np.float64],
    *,
    bandwidth: float = 2.0,
    seeds: npt.NDArray[np.float64] | None = None,
    bin_seeding: bool = False,
    min_bin_freq: int = 1,
    cluster_all: bool = True,
    max_iter: int = 300,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64], int, bool]: ...

# --- velodyne (rust/src/py/velodyne.rs) ---
def decode_velodyne_scan(
    payloads: npt.NDArray[np.uint8],
    packet_times: npt.NDArray[np.float64],
    model: str,
) -> tuple[tuple[float, float], npt.NDArray[np.float32]]: ...
def velodyne_packet_check(
    data: bytes | npt.NDArray[np.uint8],
    offsets: npt.NDArray[np.int64],
) -> tuple[npt.NDArray[np.bool_], list[tuple[int, str]]]:
    """Checks a stream of Velodyne data packets, `data[o:o + 1206]` for each offset (bytes).

    data : bytes or a C-contiguous 1-D uint8 array; offsets : (k,) int64, non-negative.
    Returns (passed, problems): per packet whether it passed
    `usvfast.lidar.packets.velodyne_packet_problem` against the model id of the last packet
    that passed (none before the first), and (index, label) of each refused one ("packet
    length" for a packet running past the end of `data`, "block flag", "azimuth", "factory
    bytes", "model id"). Raises TypeError for another type of `data`, ValueError for bad
    `offsets` or a non-contiguous array.
    """

# --- pcap (rust/src/py/pcap.rs) ---
# The dict pcap_udp_datagrams returns (a stub-only name: the functional form keeps it out of
# tests/test_stubs.py's comparison of classes with the runtime module).
_PcapDatagrams = TypedDict(  # noqa: UP013
    "_PcapDatagrams",
    {
        "times": npt.NDArray[np.float64],
        "ports": npt.NDArray[np.uint16],
        "offsets": npt.NDArray[np.int64],
        "lengths": npt.NDArray[np.int64],
        "record_counts": npt.NDArray[np.int64],
        "records": int,
        "damage": list[tuple[int, str]],
    },
)

def pcap_udp_datagrams(data: bytes | npt.NDArray[np.uint8]) -> _PcapDatagrams:
    """Every UDP/IPv4 datagram of a libpcap capture, in one pass.

    data : the whole file, `bytes` or a C-contiguous 1-D uint8 array (`np.frombuffer` of an
    mmap). Returns, per datagram in capture order: `times`, its record's capture time (UNIX s);
    `ports`, its destination port; `offsets` and `lengths`, its payload's place in `data`
    (bytes); `record_counts`, the records seen up to its record. `records`: the records seen;
    `damage`: (datagrams before it, label) of each record or frame skipped as damaged, in
    capture order, labels "record header", "truncated record", "record timestamp", "link/IP
    header", "IP checksum", "UDP length". Reads what dpkt reads (Ethernet with 802.1Q/QinQ,
    MPLS, ISL; raw IP, link types 101 and 12; Linux SLL, 113); other frames are left out.
    Raises TypeError for another type of `data`, ValueError when it is not a libpcap file
    (pcapng is not supported) or not C-contiguous.
    """

# --- geodesy (rust/src/py/geodesy.rs) ---
_F = npt.NDArray[np.float64]

def geodetic_to_ecef(
    lat: _F, lon: _F, h: _F, *, ellipsoid: tuple[float, float], deg: bool
) -> tuple[_F, _F, _F]: ...
def ecef_to_geodetic(
    x: _F, y: _F, z: _F, *, ellipsoid: tuple[float, float], deg: bool
) -> tuple[_F, _F, _F]: ...
def geodetic_to_local(
    frame: str,
    u: _F,
    v: _F,
    w: _F,
    lat0: _F,
    lon0: _F,
    h0: _F,
    *,
    ellipsoid: tuple[float, float],
    deg: bool,
) -> tuple[_F, _F, _F]: ...
def local_to_geodetic(
    frame: str,
    u: _F,
    v: _F,
    w: _F,
    lat0: _F,
    lon0: _F,
    h0: _F,
    *,
    ellipsoid: tuple[float, float],
    deg: bool,
) -> tuple[_F, _F, _F]: ...
def ecef_to_local(
    frame: str,
    u: _F,
    v: _F,
    w: _F,
    lat0: _F,
    lon0: _F,
    h0: _F,
    *,
    ellipsoid: tuple[float, float],
    deg: bool,
) -> tuple[_F, _F, _F]: ...
def local_to_ecef(
    frame: str,
    u: _F,
    v: _F,
    w: _F,
    lat0: _F,
    lon0: _F,
    h0: _F,
    *,
    ellipsoid: tuple[float, float],
    deg: bool,
) -> tuple[_F, _F, _F]: ...

# --- frames (rust/src/py/frames.rs) ---
def sensor_to_ned(
    points: _F,
    mount_rotation: _F,
    mount_translation: _F,
    roll: _F,
    pitch: _F,
    yaw: _F,
    position: _F,
) -> _F: ...
def map_sharpness(
    xy: _F,
    north: _F,
    east: _F,
    heading: _F,
    offsets: _F,
    cell: float,
) -> _F: ...

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

# --- tracker (rust/src/py/tracker.rs) ---
# The configuration objects are read by attribute (rust/src/py/tracker_config.rs): `imm` is a
# usvfast.tracking.IMM whose modes are usvfast.kalman models, KnownTurnRate (q, omega) or
# ConstantTurn (q, q_turn, predictor "ekf"/"ukf", alpha, beta, kappa; 5-D state);
# `initiator` a usvfast.tracking.MultiMeasurementInitiator (prior_state, prior_covariance,
# min_points, deleter, missed_distance, measure, include_all, updates_only, diag_load, m_of_n,
# motion_model, use_joseph_cov, symmetric_covariance, max_new_tentative, imm: bool — the
# `imm` bank on tentative tracks too).
class TrackerCore:
    def __init__(
        self,
        motion_model: object,
        sensors: list[object],
        association: object,
        deleter: object,
        initiator: object,
        *,
        use_joseph_cov: bool = False,
        delete_last_prediction: bool = False,
        out_of_order: str = "raise",
        initiate_in_gates: bool = True,
        symmetric_covariance: bool = False,
        imm: object | None = None,
        existence: object | None = None,
        max_deleted: int | None = None,
    ) -> None: ...
    def step(
        self,
        t: float,
        measurements: npt.NDArray[np.float64],
        sensor_ids: npt.NDArray[np.int64],
        covariances: npt.NDArray[np.float64] | None = None,
        origins: npt.NDArray[np.float64] | None = None,
    ) -> tuple[bool, int, int, int]: ...
    def run(
        self,
        times: npt.NDArray[np.float64],
        measurements: npt.NDArray[np.float64],
        sensor_ids: npt.NDArray[np.int64],
        scan_index: npt.NDArray[np.int64],
        covariances: npt.NDArray[np.float64] | None = None,
        origins: npt.NDArray[np.float64] | None = None,
    ) -> dict[str, npt.NDArray[np.generic]]: ...
    def add_sensor(self, sensor: object) -> int: ...
    def add_track(
        self,
        state: npt.NDArray[np.float64],
        covariance: npt.NDArray[np.float64],
        time: float,
        existence: tuple[float, float] | None = None,
    ) -> int: ...
    def snapshot(self, tentative: bool = False) -> dict[str, npt.NDArray[np.generic]]: ...
    def track_ids(self) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]: ...
    def history(self, track_id: int, start: int = 0) -> dict[str, Any]: ...
    def drain_deleted(self) -> list[dict[str, Any]]: ...
    def copy(self) -> TrackerCore: ...
    def to_bytes(self) -> bytes: ...
    @staticmethod
    def from_bytes(state: bytes) -> TrackerCore: ...
    @property
    def measurement_dim(self) -> int: ...
    @property
    def capped_detections(self) -> int: ...
    @property
    def dropped_scans(self) -> int: ...
    @property
    def last_time(self) -> float | None: ...

def confirmed_ids(core: TrackerCore) -> list[int]: ...
def tentative_first_scan(core: TrackerCore) -> int | None: ...
def stonesoup_step(
    core: TrackerCore,
    t: float,
    detections: list[Any],
    timestamp: Any,
    known: dict[int, tuple[Any, ...]],
    plain: set[type] | frozenset[type],
    noises: list[npt.NDArray[np.float64]],
    m: int,
) -> tuple[list[int], npt.NDArray[np.float64], list[Any], bool] | None: ...

class StoneSoupKit:
    def __init__(
        self,
        builders: list[tuple[Any, Any, tuple[str, ...], dict[str, Any] | None]],
        arrays: tuple[Any, Any, Any],
        linear_model: Any,
        measure: int,
    ) -> None: ...
    def make(self, index: int, values: list[Any]) -> Any: ...
    def newest(
        self,
        core: TrackerCore,
        scan: int,
        ids: list[int],
        priors: list[Any],
        dt: float,
        transition: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]],
        detections: list[Any],
        models: list[Any],
        z: npt.NDArray[np.float64],
        timestamp: Any,
        transition_model: Any,
        mixture: bool,
        hypotheses: bool,
        has_metadata: bool | None = None,
    ) -> tuple[bool, list[Any]]: ...
    def entries(
        self,
        core: TrackerCore,
        track_id: int,
        first: int,
        prior: Any,
        dts: list[float],
        transitions: list[tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]],
        detections: list[list[Any]],
        models: list[list[Any]],
        zs: list[npt.NDArray[np.float64]],
        timestamps: list[Any],
        transition_model: Any,
        mixture: bool,
        hypotheses: bool,
    ) -> list[Any]: ...

def linear_sum_assignment(cost: npt.NDArray[np.float64]) -> npt.NDArray[np.int64]: ...
def jpda_marginals(
    likelihoods: npt.NDArray[np.float64], method: str = "ehm", k_best: int = 1000
) -> npt.NDArray[np.float64]: ...
def chi2_gate(prob_gate: float, dof: int) -> float: ...

# --- cascade (rust/src/py/cascade.rs) ---
class HaarCascade:
    @staticmethod
    def train(
        positives: npt.NDArray[np.uint8],
        negative_pool: npt.NDArray[np.uint8],
        *,
        min_hit_rate: float = 0.995,
        max_false_alarm: float = 0.5,
        max_weak: int = 50,
        max_stages: int = 12,
        negatives_per_stage: int = 1000,
        feature_step: int = 4,
        target_false_alarm: float = 1e-4,
    ) -> HaarCascade: ...
    def add_stage(
        self,
        positives: npt.NDArray[np.uint8],
        negatives: npt.NDArray[np.uint8],
        *,
        max_false_alarm: float | None = None,
        max_weak: int | None = None,
    ) -> dict[str, float]: ...
    @property
    def stage_reports(self) -> list[dict[str, float]]: ...
    @property
    def num_stages(self) -> int: ...
    @property
    def window_size(self) -> tuple[int, int]: ...
    def accepts(self, windows: npt.NDArray[np.uint8]) -> npt.NDArray[np.bool_]: ...
    def scan(self, image: npt.NDArray[np.uint8], step: int = 2) -> npt.NDArray[np.int64]: ...
    @staticmethod
    def from_opencv_xml(text: str) -> HaarCascade: ...
    def to_opencv_xml(self) -> str: ...

# two-tier multi-clustered particle filter (Bloisi et al. §V)
def particle_uniforms(seed: int, start: int, n: int) -> npt.NDArray[np.float64]: ...
def particle_resample(
    weights: npt.NDArray[np.float64], count: int, *, seed: int, counter: int = 0
) -> npt.NDArray[np.int64]: ...
def particle_kclusterize(
    particles: npt.NDArray[np.float64],
    weights: npt.NDArray[np.float64],
    *,
    delta: float,
    min_size: int = 8,
    min_kurtosis: float = 1.9,
    max_depth: int = 3,
) -> tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.int64],
]: ...
def particle_local_step(
    particles: npt.NDArray[np.float64],
    obs: npt.NDArray[np.float64],
    velocities: npt.NDArray[np.float64],
    *,
    count: int,
    dt: float,
    accel_std: float,
    vel_std: float,
    clutter: float,
    n_out: int,
    delta: float,
    seed: int,
    min_size: int = 8,
    min_kurtosis: float = 1.9,
    max_depth: int = 3,
) -> tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.int64],
]: ...
def particle_fuse(
    times: npt.NDArray[np.float64],
    weights: npt.NDArray[np.float64],
    means: npt.NDArray[np.float64],
    stds: npt.NDArray[np.float64],
    *,
    now: float,
    window: float,
    count: int,
    delta: float,
    seed: int,
    min_size: int = 8,
    min_kurtosis: float = 1.9,
    max_depth: int = 3,
) -> tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.int64],
    npt.NDArray[np.float64],
]: ...

class ParticleTracker:
    def __init__(
        self,
        *,
        seed: int = 0,
        particles: int = 64,
        accel_std: float = 0.01,
        meas_scale: float = 0.15,
        birth_vel_std: float = 1.0,
        track_vel_std: float = 0.3,
        vel_gain: float = 0.5,
        clutter: float = 1e-9,
        delta: float = 20.0,
        min_cluster: int = 8,
        min_kurtosis: float = 1.9,
        max_depth: int = 3,
        gate: float = 1.0,
        max_angle_deg: float = 10.0,
        min_speed: float = 0.5,
        speed_abs: float = 1.0,
        speed_rel: float = 0.5,
        appearance_weight: float = 0.3,
        confirm_hits: int = 2,
        confirm_window: int = 3,
        max_age: int = 3,
        group_iou: float = 0.05,
        reid_distance: float = 0.35,
        reid_radius: float = 1.5,
        size_gain: float = 0.6,
    ) -> None: ...
    def step(
        self,
        boxes: npt.NDArray[np.float64],
        scores: npt.NDArray[np.float64],
        hists: npt.NDArray[np.float64] | None = None,
        dt: float = 1.0,
    ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    def tracks(
        self,
    ) -> tuple[
        npt.NDArray[np.int64],
        npt.NDArray[np.float64],
        npt.NDArray[np.float64],
        npt.NDArray[np.float64],
        npt.NDArray[np.bool_],
        npt.NDArray[np.int64],
        npt.NDArray[np.float64],
    ]: ...
    def mixture(
        self,
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    @property
    def steps(self) -> int: ...
