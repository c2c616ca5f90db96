"""Tracking and detection metrics.

- `single`: one target against its truth (`track_quality`, `clear_mot`).
- `frames`: truth and tracks per frame with their distances (`FrameSequence`), the common input
  of the multi-target scores:
- `mot`: CLEAR MOT, precision, recall, IDF1 (`mot_metrics`, equal to py-motmetrics);
- `hota`: HOTA (`hota_metrics`, equal to TrackEval);
- `ospa`: GOSPA and OSPA (`gospa_metrics`, equal to Stone Soup);
- `motchallenge`: MOTChallenge text in and out.
"""

from usvfast.metrics.frames import FrameSequence, box_iou, frames_from_times
from usvfast.metrics.hota import HotaMetrics, hota_metrics
from usvfast.metrics.mot import MotMetrics, mot_metrics
from usvfast.metrics.motchallenge import MotBoxes, read_motchallenge, write_motchallenge
from usvfast.metrics.ospa import Gospa, gospa_metrics
from usvfast.metrics.single import ClearMot, TrackQuality, clear_mot, track_quality

__all__ = [
    "ClearMot",
    "FrameSequence",
    "Gospa",
    "HotaMetrics",
    "MotBoxes",
    "MotMetrics",
    "TrackQuality",
    "box_iou",
    "clear_mot",
    "frames_from_times",
    "gospa_metrics",
    "hota_metrics",
    "mot_metrics",
    "read_motchallenge",
    "track_quality",
    "write_motchallenge",
]
