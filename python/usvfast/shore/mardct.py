"""The MarDCT annotated frames (Bloisi et al.'s shore-camera database, as published with a
vessel-detection project): `NAME_FRAME.png` with `NAME_FRAME.txt` holding one `boat X Y W H`
line per boat (top-left corner and size, pixels). The frames of one video, ordered by FRAME,
form a time-ordered sequence with irregular spacing."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class AnnotatedFrame:
    """One annotated frame: `video` name, `index` (frame index in its source video), `path`
    of the image, `boxes` (k, 4) x, y, w, h px."""

    video: str
    index: int
    path: Path
    boxes: np.ndarray


def read_boxes(path: Path) -> np.ndarray:
    """(k, 4) boxes of one annotation file; raises ValueError naming the file and line."""
    rows = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        if len(parts) != 5:
            raise ValueError(f"{path}:{n}: expected 'label x y w h', got {line!r}")
        rows.append([float(v) for v in parts[1:]])
    return np.array(rows, dtype=float).reshape(-1, 4)


def load_mardct(folder: Path | str) -> dict[str, list[AnnotatedFrame]]:
    """The annotated frames of `folder` (MarDCT's `training/annotations`) grouped by video,
    each list ordered by frame index. Raises ValueError when the folder holds none."""
    folder = Path(folder)
    videos: dict[str, list[AnnotatedFrame]] = {}
    for png in folder.glob("*.png"):
        m = re.match(r"^(.+)_(\d+)$", png.stem)
        txt = png.with_suffix(".txt")
        if not m or not txt.exists():
            continue
        frame = AnnotatedFrame(m.group(1), int(m.group(2)), png, read_boxes(txt))
        videos.setdefault(frame.video, []).append(frame)
    if not videos:
        raise ValueError(f"folder: no annotated MarDCT frames (NAME_FRAME.png + .txt) in {folder}")
    return {v: sorted(f, key=lambda a: a.index) for v, f in sorted(videos.items())}
