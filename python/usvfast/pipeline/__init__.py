"""The main hall: one streaming pipeline from a recording's streams to tracks (the thesis's
section 5.3): config -> streams -> pose -> LiDAR / camera chains -> tracker -> outputs.

    from usvfast.pipeline import Pipeline, load_config
    pipe = Pipeline(load_config("recording.toml"))
    for update in pipe.run(out="out/run"):
        ...
    print(pipe.summary["real_time_factor"])

See `usvfast.pipeline.config` for the config file, `core` for `Pipeline`.
"""

from usvfast.pipeline.config import (
    SCHEMA,
    ConfigError,
    PipelineConfig,
    config_from_dict,
    load_config,
    preset_names,
)
from usvfast.pipeline.core import Pipeline, TrackUpdate
from usvfast.pipeline.pose import NavigationError, VesselPose
from usvfast.pipeline.tracker import Snapshot

__all__ = [
    "SCHEMA",
    "ConfigError",
    "NavigationError",
    "Pipeline",
    "PipelineConfig",
    "Snapshot",
    "TrackUpdate",
    "VesselPose",
    "config_from_dict",
    "load_config",
    "preset_names",
]
