"""The shore-camera chain of one frame and of a whole video: detector -> horizon filter ->
image tracker -> MOTChallenge files, annotated video and summary.

`ShoreChain.step(image)` runs one frame and returns a `FrameResult`; `run_shore` drives a
`FrameSource` through it and writes `tracks.txt`, `detections.txt`, `annotated.mp4` and
`summary.json` into the output folder.
"""

from __future__ import annotations

import json
import time
from collections import Counter
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Literal, cast

import cv2
import numpy as np
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

from usvfast._core import HaarCascade
from usvfast._validate import instance
from usvfast.shore.annotate import draw_frame
from usvfast.shore.bayes import BayesDetector, BayesDetectorConfig
from usvfast.shore.boxes import Detections
from usvfast.shore.cascade import CascadeConfig, CascadeDetector
from usvfast.shore.change import ChangeConfig, ChangeDetector
from usvfast.shore.contrast import ContrastConfig, ContrastDetector
from usvfast.shore.daynight import DayNightClassifier
from usvfast.shore.defaults import DetectorChoice, coco_export, is_coco_export, resolve_detector
from usvfast.shore.filters import ReflectionFilter, WakeFilter
from usvfast.shore.frames import FrameSource
from usvfast.shore.fused import FUSED_CNN_FLOOR, FUSED_RELATIVE, FUSED_THRESHOLD, FusedDetector
from usvfast.shore.horizon import HorizonConfig, HorizonLine, detect_horizon, horizon_keep
from usvfast.shore.mot import mot_rows, write_mot
from usvfast.shore.particle import ParticleConfig, ParticleTracker
from usvfast.shore.pixel_kalman import AdaptiveConfig, AdaptiveTracker
from usvfast.shore.sort import SortConfig, SortTracker
from usvfast.shore.ssd_runtime import BACKENDS, PRECISIONS, resolve_backend

DetectorName = Literal["auto", "bayes", "cascade", "cnn", "contrast", "fused", "change", "ssd"]
TrackerName = Literal["sort", "adaptive", "particle"]
DETECTORS: tuple[str, ...] = (
    "auto",
    "bayes",
    "cascade",
    "cnn",
    "contrast",
    "fused",
    "change",
    "ssd",
)
TRACKERS: tuple[str, ...] = ("sort", "adaptive", "particle")


@dataclass
class ShoreConfig:
    """The chain: `detector` ('auto': the best detector with weights at hand, in the order of
    :mod:`usvfast.shore.defaults` — a fine-tuned SSD, a trained CNN, the zero-shot COCO SSD,
    else 'bayes'; 'bayes': Kim, Chung and Lee's threshold + keypoints; 'cascade':
    Bloisi et al.'s Haar cascade, from the OpenCV XML file `cascade_model` that
    `usvfast shore-train` writes; 'cnn': a YOLO-layout network, `cnn_model` an ONNX or
    TorchScript file, default :func:`usvfast.shore.cnn.default_model`; 'contrast': the
    training-free "object on the water" detector of :mod:`usvfast.shore.contrast`; 'fused':
    the CNN's boxes rescored by that contrast, :class:`usvfast.shore.fused.FusedDetector`;
    'change': what moves against the registered background of the previous frames,
    :class:`usvfast.shore.change.ChangeDetector`, online; 'ssd': the COCO-pretrained
    SSD-MobileNetV2, `ssd_model` the ONNX file `usvfast shore-train --detector ssd` writes,
    default the fine-tuned one in the user model folder, else the zero-shot COCO export, run by
    `ssd_backend` at `ssd_precision` (:mod:`usvfast.shore.ssd_runtime`; 'auto': OpenVINO
    float32 when the `openvino` extra is installed, else OpenCV DNN; same scores to 1e-5) at
    its card's threshold, :class:`usvfast.shore.pretrained.SsdDetector`),
    `reflection_filter` (drop boxes with few ORB
    keypoints), `wake_model` (a one-stage cascade XML from `WakeFilter`, drops wakes), `tracker`
    ('sort': Kalman + IoU assignment + colour re-identification; 'adaptive': the same paper's
    single-vessel adaptive Kalman tracker; 'particle': Bloisi et al.'s two-tier particle
    filter), `horizon_filter` (drop detections well above the horizon line) and the parameters
    of each part (`sort`: :class:`usvfast.shore.sort.SortConfig`, whose `high_score` and
    `low_score` turn on ByteTrack's two-stage association).

    After construction `detector` and the model fields hold what runs ('auto' resolved) and
    `choice` (:class:`usvfast.shore.defaults.DetectorChoice`) says which weights and why.
    Raises ValueError when the named detector has no usable model (the message says what to
    train or install)."""

    detector: DetectorName = "auto"
    tracker: TrackerName = "sort"
    horizon_filter: bool = True
    cascade_model: Path | None = None
    cnn_model: Path | None = None
    ssd_model: Path | None = None
    ssd_backend: str = "auto"
    ssd_precision: str = "f32"
    reflection_filter: bool = False
    wake_model: Path | None = None
    horizon: HorizonConfig = field(default_factory=HorizonConfig)
    bayes: BayesDetectorConfig = field(default_factory=BayesDetectorConfig)
    sort: SortConfig = field(default_factory=SortConfig)
    adaptive: AdaptiveConfig = field(default_factory=AdaptiveConfig)
    particle: ParticleConfig = field(default_factory=ParticleConfig)
    cascade: CascadeConfig = field(default_factory=CascadeConfig)
    contrast: ContrastConfig = field(default_factory=ContrastConfig)
    change: ChangeConfig = field(default_factory=ChangeConfig)
    fused_threshold: float = FUSED_THRESHOLD
    fused_relative: float = FUSED_RELATIVE
    choice: DetectorChoice | None = field(default=None, init=False, compare=False)

    def __post_init__(self) -> None:
        instance("sort", self.sort, SortConfig)
        if self.detector not in DETECTORS:
            raise ValueError(f"detector: expected one of {DETECTORS}, got {self.detector!r}")
        if self.tracker not in TRACKERS:
            raise ValueError(f"tracker: expected one of {TRACKERS}, got {self.tracker!r}")
        if self.ssd_backend != "auto" and self.ssd_backend not in BACKENDS:
            raise ValueError(
                f"ssd_backend: expected 'auto' or one of {BACKENDS}, got {self.ssd_backend!r}"
            )
        if self.ssd_precision not in PRECISIONS:
            raise ValueError(
                f"ssd_precision: expected one of {PRECISIONS}, got {self.ssd_precision!r}"
            )
        self.choice = resolve_detector(
            self.detector, self.cnn_model, self.ssd_model, self.cascade_model
        )
        self.detector = cast(DetectorName, self.choice.detector)  # (a DETECTORS name)
        if self.detector in ("cnn", "fused"):
            self.cnn_model = self.choice.model
        elif self.detector == "ssd":
            self.ssd_model = self.choice.model


@dataclass
class FrameResult:
    """One frame's output: raw and kept detections (before/after the horizon filter), the
    reported tracks (ids (t,), boxes (t, 4) px, scores (t,)), the horizon, the frame class."""

    raw: Detections
    kept: Detections
    track_ids: np.ndarray
    track_boxes: np.ndarray
    track_scores: np.ndarray
    horizon: HorizonLine | None
    frame_class: str


class ShoreChain:
    """Detector, horizon filter and tracker of one video (the trackers keep state)."""

    def __init__(
        self, config: ShoreConfig | None = None, classifier: DayNightClassifier | None = None
    ) -> None:
        self.config = cfg = config or ShoreConfig()
        self.classifier = classifier or DayNightClassifier.default()
        self.detector = BayesDetector(cfg.bayes, self.classifier)
        self.cascade: CascadeDetector | None = None
        if cfg.detector == "cascade" and cfg.cascade_model is not None:  # (post_init: given)
            path = Path(cfg.cascade_model)
            if not path.is_file():
                raise ValueError(f"cascade_model: {path} is not a file")
            text = path.read_text(encoding="utf-8")
            self.cascade = CascadeDetector(HaarCascade.from_opencv_xml(text), cfg.cascade)
        self.cnn = None
        if cfg.detector == "cnn":
            from usvfast.shore.cnn import CnnDetector

            self.cnn = CnnDetector(cfg.cnn_model)
        elif cfg.detector == "ssd":
            from usvfast.shore.pretrained import SsdDetector

            model = cfg.ssd_model
            if is_coco_export(model):  # the zero-shot SSD: exported once, then cached
                model = coco_export(model)
            backend = resolve_backend(cfg.ssd_backend)
            self.cnn = SsdDetector(model, backend=backend, precision=cfg.ssd_precision)
        self.contrast: ContrastDetector | FusedDetector | None = None
        if cfg.detector == "contrast":
            self.contrast = ContrastDetector(cfg.contrast)
        elif cfg.detector == "fused":
            from usvfast.shore.cnn import CnnDetector

            cnn = CnnDetector(cfg.cnn_model, conf_threshold=FUSED_CNN_FLOOR)
            self.contrast = FusedDetector(
                cnn, cfg.contrast, cfg.fused_threshold, cfg.fused_relative
            )
        self.change = ChangeDetector(cfg.change) if cfg.detector == "change" else None
        self.reflection = ReflectionFilter() if cfg.reflection_filter else None
        self.wake = None
        if cfg.wake_model is not None:
            path = Path(cfg.wake_model)
            if not path.is_file():
                raise ValueError(f"wake_model: {path} is not a file")
            stage = HaarCascade.from_opencv_xml(path.read_text(encoding="utf-8"))
            self.wake = WakeFilter(stage, cfg.cascade)
        self.tracker: SortTracker | AdaptiveTracker | ParticleTracker = (
            SortTracker(cfg.sort) if cfg.tracker == "sort" else AdaptiveTracker(cfg.adaptive)
        )
        if cfg.tracker == "particle":
            self.tracker = ParticleTracker(cfg.particle)
        self.seconds: Counter[str] = Counter()

    def step(self, image: np.ndarray) -> FrameResult:
        """Run one BGR uint8 frame through the chain."""
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(
                f"image: expected (h, w, 3) uint8 BGR, got {image.shape} {image.dtype}"
            )
        cfg = self.config
        t0 = time.perf_counter()
        horizon: HorizonLine | None = None
        found = False
        if self.contrast is not None:
            frame_class = self.classifier.classify(image)
            horizon = detect_horizon(image, infrared=frame_class == "ir", config=cfg.horizon)
            found = True
            raw = self.contrast.detect(image, horizon)
        elif self.change is not None:
            frame_class = self.classifier.classify(image)
            horizon = detect_horizon(image, infrared=frame_class == "ir", config=cfg.horizon)
            found = True
            raw = self.change.step(image, horizon)
        elif self.cnn is not None:
            raw = self.cnn.detect(image)
            frame_class = self.classifier.classify(image)
        elif self.cascade is None:
            raw = self.detector.detect(image)
            frame_class = self.detector.last_class
        else:
            raw = self.cascade.detect(image)
            frame_class = self.classifier.classify(image)
        if self.reflection is not None and len(raw):
            raw = raw.subset(self.reflection.keep(image, raw))
        if self.wake is not None and len(raw):
            raw = raw.subset(self.wake.keep(image, raw))
        t1 = time.perf_counter()
        if not found:
            horizon = detect_horizon(image, infrared=frame_class == "ir", config=cfg.horizon)
        kept = raw
        if cfg.horizon_filter:
            kept = raw.subset(horizon_keep(raw, horizon, image.shape[0], cfg.horizon))
        t2 = time.perf_counter()
        if isinstance(self.tracker, SortTracker | ParticleTracker):
            ids, boxes, scores = self.tracker.step(image, kept)
        else:
            tr = self.tracker.step(kept)
            ids = np.ones(len(tr), dtype=np.int64)
            boxes, scores = tr.boxes, tr.scores
        t3 = time.perf_counter()
        self.seconds.update({"detect": t1 - t0, "horizon": t2 - t1, "track": t3 - t2})
        return FrameResult(raw, kept, ids, boxes, scores, horizon, frame_class)


@dataclass
class ShoreSummary:
    """What a run did: the detector run (`detector_choice`: which weights, and whether
    `--detector auto` chose them; `model`: the weights file or None), frames processed and
    undecoded, processing frames per second (whole chain, excluding reading and writing),
    seconds per stage, counts of detections (before and after the horizon filter) and tracks,
    frame classes and horizon kinds seen."""

    input: str
    detector: str
    detector_choice: str
    model: str | None
    tracker: str
    horizon_filter: bool
    frames: int
    undecoded_frames: int
    processing_fps: float
    stage_seconds: dict[str, float]
    detections_raw: int
    detections: int
    tracks: int
    track_rows: int
    frame_classes: dict[str, int]
    horizons: dict[str, int]
    outputs: dict[str, str]


def _open_writer(path: Path, size: tuple[int, int], fps: float) -> tuple[cv2.VideoWriter, Path]:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)  # pyright: ignore[reportAttributeAccessIssue]
    if writer.isOpened():
        return writer, path
    alt = path.with_suffix(".avi")
    return cv2.VideoWriter(str(alt), cv2.VideoWriter_fourcc(*"MJPG"), fps, size), alt  # pyright: ignore[reportAttributeAccessIssue]


def run_shore(
    input_path: Path | str,
    out_dir: Path | str,
    config: ShoreConfig | None = None,
    *,
    video: bool = True,
    progress: bool = True,
    max_frames: int = 0,
) -> ShoreSummary:
    """Process a video file or a folder of frames; write the outputs into `out_dir`.

    Writes tracks.txt and detections.txt (MOTChallenge, frames from 1; detections after the
    horizon filter, id −1), annotated.mp4 (when `video`; .avi when mp4 cannot be written) and
    summary.json. A damaged or truncated video is processed up to the damage and the rest
    counted as undecoded (a DamagedVideoWarning is emitted). `max_frames` > 0 stops early.
    Raises ValueError naming `input` when nothing can be read.
    """
    cfg = config or ShoreConfig()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    source = FrameSource(input_path)
    chain = ShoreChain(cfg)
    det_rows, trk_rows = [], []
    writer: cv2.VideoWriter | None = None
    video_path = out / "annotated.mp4"
    classes: Counter[str] = Counter()
    horizons: Counter[str] = Counter()
    n_raw = 0
    size = (0, 0)
    total = source.expected if max_frames <= 0 else min(source.expected or max_frames, max_frames)
    columns = (
        TextColumn("[bold]shore[/bold] {task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeRemainingColumn(),
    )
    try:
        with Progress(*columns, disable=not progress) as bar:
            task = bar.add_task(Path(input_path).name, total=total)
            for frame in source:
                r = chain.step(frame.image)
                n_raw += len(r.raw)
                classes[r.frame_class] += 1
                horizons[r.horizon.kind if r.horizon else "none"] += 1
                det_rows.append(
                    mot_rows(frame.number, np.full(len(r.kept), -1), r.kept.boxes, r.kept.scores)
                )
                trk_rows.append(mot_rows(frame.number, r.track_ids, r.track_boxes, r.track_scores))
                if video:
                    if writer is None:
                        h, w = frame.image.shape[:2]
                        writer, video_path = _open_writer(video_path, (w, h), source.fps or 10.0)
                        size = (w, h)
                    label = f"{frame.number} {r.frame_class} {cfg.detector}+{cfg.tracker}"
                    drawn = draw_frame(
                        frame.image, r.kept.boxes, r.track_ids, r.track_boxes, r.horizon, label
                    )
                    if drawn.shape[1::-1] != size:  # a folder of frames of several sizes
                        drawn = cv2.resize(drawn, size)
                    writer.write(drawn)
                bar.advance(task)
                if 0 < max_frames <= frame.number:
                    break
    finally:
        if writer is not None:
            writer.release()
    det = np.concatenate(det_rows) if det_rows else np.zeros((0, 10))
    trk = np.concatenate(trk_rows) if trk_rows else np.zeros((0, 10))
    write_mot(out / "detections.txt", det)
    write_mot(out / "tracks.txt", trk)
    busy = sum(chain.seconds.values())
    frames = source.frames_read
    outputs = {"tracks": "tracks.txt", "detections": "detections.txt"}
    if writer is not None:
        outputs["video"] = video_path.name
    summary = ShoreSummary(
        input=str(input_path),
        detector=cfg.detector,
        detector_choice=cfg.choice.describe() if cfg.choice else cfg.detector,
        model=str(cfg.choice.model) if cfg.choice and cfg.choice.model else None,
        tracker=cfg.tracker,
        horizon_filter=cfg.horizon_filter,
        frames=frames,
        undecoded_frames=source.undecoded,
        processing_fps=frames / busy if busy > 0 else 0.0,
        stage_seconds={k: round(v, 6) for k, v in chain.seconds.items()},
        detections_raw=n_raw,
        detections=len(det),
        tracks=len(np.unique(trk[:, 1])) if len(trk) else 0,
        track_rows=len(trk),
        frame_classes=dict(classes),
        horizons=dict(horizons),
        outputs=outputs,
    )
    (out / "summary.json").write_text(json.dumps(asdict(summary), indent=2), encoding="utf-8")
    return summary
