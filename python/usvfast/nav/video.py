"""Video files (or image sequences) as frames with per-frame UNIX timestamps, via OpenCV.

Two time bases:
- container timestamps (`CAP_PROP_POS_MSEC` after each read: the frame's presentation time,
  variable frame rate included) when the container has them and they increase;
- otherwise, as for the thesis's dataset D1 (section 5.2.3: a camera that cannot stamp frames,
  only the time the file was written is known), start time + frame index / frame rate.

The absolute time of frame k is `start_time + relative_k + offset`, where `start_time` is given,
or derived from `end_time` (e.g. the file's write time) minus the video duration, and `offset`
is the manually tuned correction the thesis needed for its D1 recordings.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from usvfast.nav._damage import DamageCounter, check_file

TimeBase = Literal["auto", "container", "rate"]


@dataclass(frozen=True)
class VideoFrame:
    """One frame: time (UNIX s, offset applied), index (0-based frame number in the file),
    image (h, w, 3) uint8 BGR, or None when iterated with decode=False."""

    time: float
    index: int
    image: np.ndarray | None


class VideoReader:
    """Lazy reader of a video file's frames with per-frame timestamps; iterate for VideoFrames.

    path: a video file (or an OpenCV image-sequence pattern such as `frames/f_%04d.png`).
    start_time: UNIX s of the first frame. end_time: UNIX s just after the last frame (the
    D1 case: the file's write time); used when start_time is None as end_time - duration.
    When both are None the file's modification time is taken as end_time.
    offset: seconds added to every timestamp (clock correction). fps: frames per second for the
    rate time base (default: the container's; required when the container has none).
    time_base: 'auto' (the rate when fps is given, else container timestamps while they
    increase, then rate-based from the last good one), 'container' or 'rate'.
    skip_until: frames before this UNIX time (after the offset) are grabbed without decoding
    and not yielded.
    Raises ValueError naming the argument for a file OpenCV cannot open, a missing frame rate,
    or both start_time and end_time given.
    """

    def __init__(
        self,
        path: Path | str,
        *,
        start_time: float | None = None,
        end_time: float | None = None,
        offset: float = 0.0,
        fps: float | None = None,
        time_base: TimeBase = "auto",
        skip_until: float | None = None,
    ) -> None:
        self.path = Path(path)
        if "%" not in self.path.name:
            check_file(self.path, "video")
        if time_base not in ("auto", "container", "rate"):
            raise ValueError(
                f"time_base: expected 'auto', 'container' or 'rate', got {time_base!r}"
            )
        if start_time is not None and end_time is not None:
            raise ValueError("start_time, end_time: give at most one of them")
        for name, v in (
            ("start_time", start_time),
            ("end_time", end_time),
            ("offset", offset),
            ("fps", fps),
            ("skip_until", skip_until),
        ):
            if v is not None and (
                isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
            ):
                raise ValueError(f"{name}: expected a finite number, got {v!r}")
        if fps is not None and fps <= 0:
            raise ValueError(f"fps: must be a positive number, got {fps!r}")
        cap = self._open()
        try:
            container_fps = cap.get(cv2.CAP_PROP_FPS)
            frames = cap.get(cv2.CAP_PROP_FRAME_COUNT)
        finally:
            cap.release()
        if time_base == "auto" and fps is not None:
            time_base = "rate"  # the user's frame rate overrides the container's clock
        if fps is None:
            if not (math.isfinite(container_fps) and container_fps > 0):
                raise ValueError(f"fps: {self.path} has no frame rate; give fps")
            fps = float(container_fps)
        self.fps = float(fps)
        self.frame_count = int(frames) if math.isfinite(frames) and frames > 0 else None
        """Frame count from the container header (an estimate for some formats), or None."""
        if start_time is None:
            if end_time is None:
                end_time = self.path.stat().st_mtime if self.path.exists() else None
            if end_time is None:
                raise ValueError(f"start_time: {self.path} has no file time; give start_time")
            if self.frame_count is None:
                raise ValueError(
                    f"end_time: {self.path} has no frame count to derive the start; give start_time"
                )
            start_time = end_time - self.frame_count / self.fps
        self.start_time = float(start_time)
        self.offset = float(offset)
        self.time_base: TimeBase = time_base
        self.skip_until = skip_until
        self.damaged = 0
        self.used_container = 0
        """Frames of the last iteration timed by container timestamps (the rest by rate)."""

    def _open(self) -> cv2.VideoCapture:
        cap = cv2.VideoCapture(str(self.path))
        if not cap.isOpened():
            raise ValueError(f"video: OpenCV cannot open {self.path}")
        return cap

    def __iter__(self) -> Iterator[VideoFrame]:
        return self.frames()

    def frames(self, decode: bool = True) -> Iterator[VideoFrame]:
        """Iterate the frames (decode=False: grab only, image None: fast time scans)."""
        cap = self._open()
        damage = DamageCounter(str(self.path))
        self.used_container = 0
        use_container = self.time_base != "rate"
        last_rel = -math.inf
        # Rate-based times count from an anchor: the last container-timed frame, or frame 0.
        anchor_rel, anchor_idx = 0.0, 0
        index = -1
        try:
            while True:
                if not cap.grab():
                    break
                index += 1
                rel: float | None = None
                if use_container:
                    ms = cap.get(cv2.CAP_PROP_POS_MSEC)
                    if math.isfinite(ms) and ms >= 0 and ms * 1e-3 > last_rel:
                        rel = ms * 1e-3
                        anchor_rel, anchor_idx = rel, index
                        self.used_container += 1
                    elif self.time_base == "container":
                        damage.add(f"frame {index}: no increasing container timestamp ({ms})")
                        continue
                    else:
                        use_container = False  # auto: fall back to the rate from here on
                if rel is None:
                    rel = anchor_rel + (index - anchor_idx) / self.fps
                last_rel = rel
                t = self.start_time + rel + self.offset
                if self.skip_until is not None and t < self.skip_until:
                    continue
                image = None
                if decode:
                    ok, image = cap.retrieve()
                    if not ok or image is None:
                        damage.add(f"frame {index}: cannot decode")
                        continue
                yield VideoFrame(t, index, image)
        finally:
            cap.release()
            self.damaged = damage.count
            damage.warn(stacklevel=2)

    def times(self) -> np.ndarray:
        """All frame times (UNIX s) without decoding images."""
        return np.array([f.time for f in self.frames(decode=False)], dtype=np.float64)
