"""Shared test configuration: hypothesis profiles (fast in CI, thorough locally on demand)."""

import os
import sys
from pathlib import Path

from hypothesis import HealthCheck, settings

# tests/peers.py and friends are importable as top-level helpers.
sys.path.insert(0, str(Path(__file__).parent))

settings.register_profile("ci", max_examples=60, deadline=None)
settings.register_profile(
    "thorough", max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

# The real field data lives in shared/data beside the repository (as on CI); set
# USVFAST_SHARED_DATA to use another copy (e.g. from a git worktree elsewhere).
SHARED_DATA = Path(
    os.environ.get("USVFAST_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data")
)
