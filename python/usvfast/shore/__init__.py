"""Shore and bridge camera surveillance: detection, horizon line and image-plane tracking of
vessels in video (MOTChallenge output).

Built from two papers: Bloisi et al., VTS camera surveillance and fusion (horizon line with
validation by paired sample points, detection scores TPR/FAR, CLEAR MOT), and Kim, Chung and
Lee, vessel tracking with Bayes classification, Kalman filter and an adaptive rule (day/night
classifier, threshold + morphology + keypoints detector, pixel Kalman filter). A SORT-like
tracker with colour-histogram re-identification is the multi-target baseline.

Example::

    from usvfast.shore import ShoreConfig, run_shore
    summary = run_shore("harbour.mp4", "out/", ShoreConfig(tracker="sort"))
"""

from usvfast.shore.boxes import Detections, iou_matrix
from usvfast.shore.daynight import DayNightClassifier
from usvfast.shore.frames import DamagedVideoWarning, FrameSource
from usvfast.shore.horizon import HorizonConfig, HorizonLine, detect_horizon
from usvfast.shore.pipeline import ShoreChain, ShoreConfig, ShoreSummary, run_shore
from usvfast.shore.sort import SortConfig, SortTracker

__all__ = [
    "DamagedVideoWarning",
    "DayNightClassifier",
    "Detections",
    "FrameSource",
    "HorizonConfig",
    "HorizonLine",
    "ShoreChain",
    "ShoreConfig",
    "ShoreSummary",
    "SortConfig",
    "SortTracker",
    "detect_horizon",
    "iou_matrix",
    "run_shore",
]
