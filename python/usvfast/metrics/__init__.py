"""Tracking and detection metrics.

- `single`: one target against its truth (`track_quality`, `clear_mot`).
- `frames`: truth and tracks per frame with their distances (`FrameSequence`), the common input
  of the multi-target scores:
- `mot`: CLEAR MOT, precision, recall, IDF1 (`mot_metrics`, equal to py-motmetrics);
- `hota`: HOTA (`hota_metrics`, equal to TrackEval);
- `ospa`: GOSPA and OSPA (`gospa_metrics`, equal to Stone Soup);
- `motchallenge`: MOTChallenge text in and out;
- `tables`: readers of truth.csv and of a run's tracks/detections/nav/innovations tables;
- `consistency`: NEES, NIS and their χ² bands (also for samples correlated within tracks);
- `protocol`: the thesis's matching and RMSE, ANEES, ANIS, TPD, TT, TRF (`thesis_metrics`);
- `detector`: per-detector TP / FN / consecutive misses (`detector_scores`).
"""

from usvfast.metrics.consistency import (
    Consistency,
    average_consistency,
    chi2_band,
    nees,
    variance_inflation,
)
from usvfast.metrics.detector import DetectorScore, detector_scores, longest_run
from usvfast.metrics.frames import FrameSequence, box_iou, frames_from_times
from usvfast.metrics.hota import HotaMetrics, hota_metrics
from usvfast.metrics.mot import MotMetrics, mot_metrics
from usvfast.metrics.motchallenge import MotBoxes, read_motchallenge, write_motchallenge
from usvfast.metrics.ospa import Gospa, gospa_metrics
from usvfast.metrics.protocol import (
    EXCLUDED_KINDS,
    Matches,
    ObjectScore,
    ThesisMetrics,
    in_range,
    match_tracks,
    thesis_metrics,
    truth_at,
)
from usvfast.metrics.single import ClearMot, TrackQuality, clear_mot, track_quality
from usvfast.metrics.tables import (
    Detections,
    Innovations,
    Nav,
    Tracks,
    Truth,
    read_detections,
    read_innovations,
    read_nav,
    read_tracks,
    read_truth,
)

__all__ = [
    "EXCLUDED_KINDS",
    "ClearMot",
    "Consistency",
    "Detections",
    "DetectorScore",
    "FrameSequence",
    "Gospa",
    "HotaMetrics",
    "Innovations",
    "Matches",
    "MotBoxes",
    "MotMetrics",
    "Nav",
    "ObjectScore",
    "ThesisMetrics",
    "TrackQuality",
    "Tracks",
    "Truth",
    "average_consistency",
    "box_iou",
    "chi2_band",
    "clear_mot",
    "detector_scores",
    "frames_from_times",
    "gospa_metrics",
    "hota_metrics",
    "in_range",
    "longest_run",
    "match_tracks",
    "mot_metrics",
    "nees",
    "read_detections",
    "read_innovations",
    "read_motchallenge",
    "read_nav",
    "read_tracks",
    "read_truth",
    "thesis_metrics",
    "track_quality",
    "truth_at",
    "variance_inflation",
    "write_motchallenge",
]
