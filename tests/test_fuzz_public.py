"""Fuzz every public numeric callable with hypothesis: wrong types, shapes, layouts, NaN/inf,
complex values, huge and zero numbers. A call may only return or raise ValueError/TypeError
(their subclasses: DimensionError, NonFiniteError, ...); it fails the suite on a Rust panic
(PanicException), any other exception type, or a NaN/inf result out of finite input.

The callables are found by walking the modules below (everything public that is a function or
a class, minus file/CLI entry points, which the reader fuzz and the CLI tests cover). Set
USVFAST_FUZZ_EXAMPLES (default 40 per callable) and USVFAST_FUZZ_RANDOM=1 for a longer,
exploratory run (CI runs the same derandomised cases every time). `pytest -s` prints the
case counts.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import math
import os
import warnings
from collections import Counter

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from usvfast._extras import MissingExtraError

MODULES = [
    "usvfast.frames",
    "usvfast.geodesy",
    "usvfast.kalman",
    "usvfast.metrics",
    "usvfast.bearing.ais",
    "usvfast.bearing.angles",
    "usvfast.bearing.camera",
    "usvfast.bearing.fusion",
    "usvfast.camera.agc",
    "usvfast.camera.georef",
    "usvfast.camera.calibration",
    "usvfast.camera.nms",
    "usvfast.lidar.clustering",
    "usvfast.lidar.frame",
    "usvfast.lidar.geometry",
    "usvfast.lidar.line_of_sight",
    "usvfast.lidar.lines",
    "usvfast.lidar.pipeline",
    "usvfast.lidar.evaluation",
    "usvfast.lidar.simulator",
    "usvfast.lidar.vessels",
    "usvfast.nav.ais",
    "usvfast.nav.ais_stream",
    "usvfast.nav.linetime",
    "usvfast.nav.pose",
    "usvfast.tracking",
    "usvfast.stonesoup",
    "usvfast.sim.motion",
    "usvfast.sim.scene",
    "usvfast.sim.gnss",
    "usvfast.sim.velodyne",
    "usvfast.shore.boxes",
    "usvfast.shore.horizon",
    "usvfast.shore.bayes",
    "usvfast.shore.sort",
    "usvfast.shore.pixel_kalman",
    "usvfast.shore.appearance",
    "usvfast.shore.daynight",
    "usvfast.shore.scores",
    "usvfast.shore.mot",
    "usvfast.shore.annotate",
    "usvfast.shore.contrast",
    "usvfast.shore.fused",
    "usvfast.shore.register",
    "usvfast.shore.change",
    "usvfast.shore.suppress",
    "usvfast.fusion.associate",
    "usvfast.fusion.rotation",
    "usvfast.fusion.visual",
    "usvfast.fusion.picture",
    "usvfast.fusion.pipeline",
    "usvfast.fusion.ais_feed",
    "usvfast.radar.readers",
    "usvfast.radar.alignment",
    "usvfast.radar.calibration",
    "usvfast.pipeline.config",
    "usvfast.pipeline.timing",
    "usvfast.sweep.spec",
    "usvfast.sweep.summary",
    "usvfast.report.figures",
    "usvfast.report.table",
]
# Entry points that read or write files, run commands or take no data (the reader fuzz below
# and the CLI tests cover the readers), and internal helpers re-exported for other modules.
SKIP = {
    "calibrate",  # images on disk
    "find_board",
    "read_ais",  # reader: fuzzed on its real file below
    "open_ais_stream",
    "evaluate_scene",  # a whole simulated run (seconds per call)
    "harbour_scene",
    "VLP16Simulator",
    "LidarDetector",
    "read_ais_feed",  # readers and writers of files: the reader fuzz, the TOML fuzz below
    "read_radar_csv",
    "read_radar_nmea",
    "load_config",
    "load_spec",
    "read_mot",
    "read_motchallenge",  # FileNotFoundError for a path that does not exist, as documented
    "write_mot",
    "save",
    "situation_picture",
    "write_plots",
    "print_summary",  # prints to the console
    "float_array",  # internal helpers: the public callables above use them
    "unwrap_raw_deg",
}
# Results documented to hold NaN for finite input ("not covered", "above the horizon", ...).
NAN_DOCUMENTED = {
    "reference_bearing_deg",  # NaN where a track does not cover the time
    "georeference",  # NaN position for rays above the horizon / beyond max_range
    "georeference_fov",
    "sensitivity",
    "water_geometry",  # NaN spacing for the first ray
    "dead_reckon",  # NaN for times before the first report
    "line_time",  # NaN when a line has no receive time
    "clock_time",  # NaN for a line that is not a ZDA/RMC sentence
    "VesselCandidate",  # speed NaN until its ends could be compared with an earlier cycle
    "VesselTrack",  # `at()` NaN outside the track; the object holds NaN headings if given
    "clear_mot",  # MOTP is NaN with no match
    "track_quality",
    "rmse_deg",
    "bearing_rmse_table",
    "fuse_bearings",
    "line_of_sight_filter_naive",
    "mount_rotation",
    "LineMemory",
    "plots_from_ned",  # RadarPlots: the fields that do not apply (range, lat, ...) are NaN
    "RadarPlots",
    "GNN",  # tracker configurations: the default gate distance is inf (no gate)
    "JPDA",
    "MultiMeasurementInitiator",
}

SPECIAL = [math.nan, math.inf, -math.inf, 1e300, -1e300, 0.0, -0.0, 5e-324]
SHAPES = [(), (0,), (1,), (2,), (3,), (4,), (2, 2), (3, 2), (3, 3), (4, 4), (2, 4), (5, 2)]
SHAPES += [(0, 2), (0, 4), (3, 2, 2), (6, 3)]

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
anyfloat = st.one_of(finite, st.sampled_from(SPECIAL))


@st.composite
def arrays(draw):
    shape = draw(st.sampled_from(SHAPES))
    size = int(np.prod(shape))
    values = draw(
        st.lists(st.one_of(finite, finite, finite, anyfloat), min_size=size, max_size=size)
    )
    a = np.array(values, dtype=np.float64).reshape(shape)
    kind = draw(st.sampled_from(["c", "c", "c", "f", "int", "complex", "strided"]))
    if kind == "f" and a.ndim == 2:
        return np.asfortranarray(a)
    if kind == "int":
        return np.clip(np.nan_to_num(a, posinf=0, neginf=0), -1e6, 1e6).astype(np.int64)
    if kind == "complex":
        return a + 1j
    if kind == "strided" and a.ndim >= 1:
        return np.repeat(a[..., None], 2, axis=-1)[..., 0]
    return a


values = st.one_of(
    finite,
    anyfloat,
    st.sampled_from([-1, 0, 1, 2, 3, 7, 10**20]),
    st.booleans(),
    st.none(),
    st.sampled_from(["x", "", b"\x00", 1 + 2j, (), [], {}]),
    st.tuples(finite, finite),
    st.tuples(finite, finite, finite),
    arrays(),
    arrays(),
    arrays(),
)


def _public():
    out = {}
    for name in MODULES:
        mod = importlib.import_module(name)
        names = getattr(mod, "__all__", None)
        for attr in names if names is not None else dir(mod):
            obj = getattr(mod, attr, None)
            if attr.startswith("_") or attr in SKIP:
                continue
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            # defined in the module, or exported by its __all__
            if getattr(obj, "__module__", "") != name and names is None:
                continue
            if not getattr(obj, "__module__", "").startswith("usvfast"):
                continue
            if inspect.isclass(obj) and issubclass(obj, BaseException | Warning):
                continue
            out.setdefault(f"{obj.__module__}.{obj.__qualname__}", obj)
    return dict(sorted(out.items()))


PUBLIC = _public()
COUNTS: Counter = Counter()


def _finite_input(x, depth=0) -> bool:
    """True when every number inside `x` is finite and real (NaN-free input)."""
    if depth > 3:
        return True
    if isinstance(x, bool | int | str | bytes) or x is None:
        return True
    if isinstance(x, float):
        return math.isfinite(x)
    if isinstance(x, complex):
        return False
    if isinstance(x, np.ndarray):
        return x.dtype.kind in "biu" or (x.dtype.kind == "f" and bool(np.isfinite(x).all()))
    if isinstance(x, tuple | list):
        return all(_finite_input(v, depth + 1) for v in x)
    if isinstance(x, dict):
        return all(_finite_input(v, depth + 1) for v in x.values())
    return True


def _nonfinite_output(x, depth=0) -> bool:
    if depth > 3:
        return False
    if isinstance(x, float):
        return not math.isfinite(x)
    if isinstance(x, np.ndarray):
        return x.dtype.kind in "fc" and not bool(np.isfinite(x).all())
    if isinstance(x, np.floating):
        return not bool(np.isfinite(x))
    if isinstance(x, tuple | list):
        return any(_nonfinite_output(v, depth + 1) for v in x)
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return any(_nonfinite_output(getattr(x, f.name), depth + 1) for f in dataclasses.fields(x))
    return False


def _call(fn, args, kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kwargs)


@pytest.mark.parametrize("qualname", list(PUBLIC))
@settings(
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    database=None,
    max_examples=int(os.environ.get("USVFAST_FUZZ_EXAMPLES", "40")),
    derandomize=not os.environ.get("USVFAST_FUZZ_RANDOM"),  # CI: reproducible cases
    phases=[
        Phase.explicit,
        Phase.generate,
        *([] if os.environ.get("USVFAST_FUZZ_NOSHRINK") else [Phase.shrink]),
    ],
)
@given(data=st.data())
def test_fuzz_public_callable(qualname, data):
    fn = PUBLIC[qualname]
    sig = inspect.signature(fn)
    args, kwargs = [], {}
    for p in sig.parameters.values():
        if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        required = p.default is inspect.Parameter.empty
        if not required and not data.draw(st.integers(0, 3), label="override") == 0:
            continue
        value = data.draw(values, label=p.name)
        if p.kind == p.POSITIONAL_ONLY or (required and p.kind == p.POSITIONAL_OR_KEYWORD):
            args.append(value)
        else:
            kwargs[p.name] = value
    COUNTS[qualname] += 1
    try:
        out = _call(fn, args, kwargs)
    except (ValueError, TypeError, MissingExtraError):
        return
    except Exception as exc:  # an undocumented exception type
        pytest.fail(f"{qualname}{tuple(args)} {kwargs}: {type(exc).__name__}: {exc}")
    except BaseException as exc:  # pyo3's PanicException derives from BaseException
        if isinstance(exc, KeyboardInterrupt):
            raise
        pytest.fail(f"{qualname}{tuple(args)} {kwargs}: PANIC {type(exc).__name__}: {exc}")
    name = qualname.rsplit(".", 1)[-1]
    if name not in NAN_DOCUMENTED and _finite_input((args, kwargs)) and _nonfinite_output(out):
        pytest.fail(f"{qualname}{tuple(args)} {kwargs}: non-finite result from finite input")


def test_fuzz_counts():
    """Prints how many cases the fuzz ran (pytest -s) and checks it reached every callable."""
    print(f"\nfuzz: {sum(COUNTS.values())} cases over {len(COUNTS)} public callables")
    assert len(PUBLIC) >= 250  # every package above; a module dropping out is noticed
