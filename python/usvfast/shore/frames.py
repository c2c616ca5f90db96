"""Frames of a shore or bridge camera: a video file or a folder of images, in order.

A damaged or truncated video yields every frame up to the damage; what could not be decoded
is counted (`FrameSource.undecoded`: frames the container announced but did not deliver) and
reported. A folder yields its images sorted by the number in their names (MarDCT's
`NAME_FRAME.png`), else by name; unreadable images are skipped and counted.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from usvfast._damage import DamageCounter, DamagedRecordsWarning

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


class DamagedVideoWarning(DamagedRecordsWarning):
    """Frames of a video or image folder could not be decoded (counted on the FrameSource)."""


@dataclass(frozen=True)
class Frame:
    """One image: `number` counts from 1 in reading order (MOTChallenge frame numbers),
    `name` is the file name or `frame N`, `image` is (h, w, 3) uint8 BGR."""

    number: int
    name: str
    image: np.ndarray


def _frame_key(path: Path) -> tuple[str, int, str]:
    m = re.match(r"^(.*?)(\d+)$", path.stem)
    return (m.group(1), int(m.group(2)), path.name) if m else (path.stem, -1, path.name)


def image_files(folder: Path) -> list[Path]:
    """The images of `folder` in frame order (trailing number in the name, then name)."""
    files = [p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES]
    return sorted(files, key=_frame_key)


class FrameSource:
    """Iterate the frames of `path` (a video file or a folder of images) as `Frame`s.

    After iteration: `frames_read` (frames yielded), `expected` (the container's frame count,
    or the number of images; None when unknown), `undecoded` (expected − read when the video
    stopped early, plus unreadable images), `fps` (the container's frame rate, or None).
    Raises ValueError naming `input` when the path is missing or nothing can be opened.
    """

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise ValueError(f"input: {self.path} does not exist")
        self.frames_read = 0
        self.undecoded = 0
        self.fps: float | None = None
        self.damage = DamageCounter(
            str(self.path), what="undecoded frame(s)", category=DamagedVideoWarning
        )
        if self.path.is_dir():
            self.files = image_files(self.path)
            if not self.files:
                raise ValueError(f"input: no images ({', '.join(IMAGE_SUFFIXES)}) in {self.path}")
            self.expected: int | None = len(self.files)
        else:
            self.files = []
            cap = cv2.VideoCapture(str(self.path))
            try:
                if not cap.isOpened():
                    raise ValueError(f"input: OpenCV cannot open {self.path} as a video")
                count = cap.get(cv2.CAP_PROP_FRAME_COUNT)
                fps = cap.get(cv2.CAP_PROP_FPS)
            finally:
                cap.release()
            self.expected = int(count) if np.isfinite(count) and count > 0 else None
            self.fps = float(fps) if np.isfinite(fps) and fps > 0 else None

    def __iter__(self) -> Iterator[Frame]:
        self.frames_read = 0
        self.undecoded = 0
        if self.files:
            yield from self._iter_folder()
        else:
            yield from self._iter_video()
        self.damage.warn(stacklevel=3)

    def _iter_folder(self) -> Iterator[Frame]:
        for f in self.files:
            image = cv2.imread(str(f), cv2.IMREAD_COLOR)
            if image is None:
                self.undecoded += 1
                self.damage.add(f"{f.name} unreadable")
                continue
            self.frames_read += 1
            yield Frame(self.frames_read, f.name, image)

    def _iter_video(self) -> Iterator[Frame]:
        cap = cv2.VideoCapture(str(self.path))
        try:
            while True:
                ok, image = cap.read()
                if not ok or image is None:
                    break
                self.frames_read += 1
                yield Frame(self.frames_read, f"frame {self.frames_read}", image)
        finally:
            cap.release()
        if self.expected is not None and self.frames_read < self.expected:
            self.undecoded = self.expected - self.frames_read
            self.damage.add(f"stopped after frame {self.frames_read} of {self.expected} announced")
            # one reason for the whole tail; count every missing frame
            self.damage.count = self.undecoded
        if self.frames_read == 0:
            raise ValueError(f"input: no frame of {self.path} could be decoded")
