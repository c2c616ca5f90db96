"""Optional dependencies: import one, or fail with one line naming the extra to install."""

from __future__ import annotations

import importlib
from types import ModuleType


class MissingExtraError(ImportError):
    """An optional dependency is not installed; the message names the extra that brings it
    (e.g. "install usvfast[lidar] for pcap files: no module named 'velodyne_decoder'")."""


def require(module: str, extra: str, purpose: str) -> ModuleType:
    """Import `module`, or raise MissingExtraError saying `pip install usvfast[extra]` is what
    `purpose` needs."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtraError(
            f"install usvfast[{extra}] for {purpose} (pip install 'usvfast[{extra}]'): "
            f"no module named {module!r}"
        ) from None
