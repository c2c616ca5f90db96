"""Shared test configuration: hypothesis profiles (fast in CI, thorough locally on demand)."""

import os
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# tests/peers.py and friends are importable as top-level helpers.
sys.path.insert(0, str(Path(__file__).parent))

# CI draws the same examples every run (a failure reproduces; no run-to-run flakiness).
settings.register_profile("ci", max_examples=60, deadline=None, derandomize=True)
settings.register_profile(
    "thorough", max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

# Real field data. The small, permissively licensed files the tests use are vendored in
# tests/data (each folder with its licence); larger or GPL data (MarDCT) stays in shared/data
# beside the repository (as on CI). USVFAST_SHARED_DATA points at another copy of that folder.
VENDORED_DATA = Path(__file__).resolve().parent / "data"
SHARED_ROOT = Path(
    os.environ.get("USVFAST_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data")
)


class _DataRoot:
    """`SHARED_DATA / "nmea"`: the vendored copy when there is one, else shared/data's."""

    def __truediv__(self, name: str) -> Path:
        vendored = VENDORED_DATA / name
        return vendored if vendored.exists() else SHARED_ROOT / name

    def __str__(self) -> str:
        return str(SHARED_ROOT)


SHARED_DATA = _DataRoot()


def shared_data(name: str) -> Path:
    """The folder `name` of shared/data (data not vendored, e.g. GPL-licensed MarDCT).

    Skips the calling test when the folder is absent (a plain clone), unless
    USVFAST_REQUIRE_SHARED=1 (set by .ci/run): then its absence fails the test.
    """
    path = SHARED_ROOT / name
    if not path.is_dir():
        if os.environ.get("USVFAST_REQUIRE_SHARED") == "1":
            pytest.fail(f"{path} is missing and USVFAST_REQUIRE_SHARED=1")
        pytest.skip(f"{path} is absent (data not vendored; see tests/data/README.md)")
    return path


@pytest.fixture(scope="session", autouse=True)
def _user_model_folder(tmp_path_factory: pytest.TempPathFactory):
    """No test reads or writes the user's model folder (`usvfast shore` caches and finds
    models there): $USVFAST_MODELS points at a temporary folder and the model variables of
    the developer's shell are cleared. Tests that need their own folder monkeypatch it."""
    names = ("USVFAST_MODELS", "USVFAST_SHORE_MODEL", "USVFAST_SHORE_SSD_MODEL")
    saved = {n: os.environ.pop(n, None) for n in names}
    os.environ["USVFAST_MODELS"] = str(tmp_path_factory.mktemp("user-models"))
    yield
    for n, v in saved.items():
        os.environ.pop(n, None)
        if v is not None:
            os.environ[n] = v


@pytest.fixture(scope="session")
def mardct_annotations() -> Path:
    """MarDCT's annotated training frames (GPL, in shared/data only): skipped or failed as
    :func:`shared_data` says."""
    return shared_data("mardct") / "training" / "annotations"
