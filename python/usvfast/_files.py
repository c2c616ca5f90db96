"""Input files of the readers: refuse what is not a regular file, read lines with a bound.

A path naming a directory, a FIFO or a device (`/dev/zero`, `/dev/stdin`) would make a reader
never return or exhaust memory; `regular_file` refuses it with a ValueError naming the
argument. `bounded_lines` reads a binary stream line by line without ever holding more than
`MAX_LINE_BYTES` of one line: an over-long line is reported (its length) and skipped.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

#: Longest line a text reader accepts (NMEA sentences are <= 82 bytes, CSV rows a few hundred).
MAX_LINE_BYTES = 64 * 1024


def regular_file(path: str | os.PathLike[str], label: str, *, directory: bool = False) -> Path:
    """`path` as a Path when it names an existing regular file (or, with `directory`, a
    directory); else ValueError naming `label` and saying what it is instead."""
    p = Path(path)
    try:
        mode = p.stat().st_mode
    except FileNotFoundError:
        raise ValueError(f"{label}: no such file or directory: {p}") from None
    except OSError as exc:
        raise ValueError(f"{label}: cannot read {p}: {exc.strerror}") from None
    if stat.S_ISREG(mode) or (directory and stat.S_ISDIR(mode)):
        return p
    kind = (
        "a directory"
        if stat.S_ISDIR(mode)
        else "a FIFO (named pipe)"
        if stat.S_ISFIFO(mode)
        else "a device"
        if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
        else "a socket"
        if stat.S_ISSOCK(mode)
        else "not a regular file"
    )
    raise ValueError(f"{label}: {p} is {kind}, not a regular file")


#: What `bounded_lines` yields instead of a line longer than its limit (not ASCII, no
#: sentence start: every text reader counts it as one damaged line).
OVERLONG_LINE = b"\xff<over-long line>\n"


def bounded_lines(fh: BinaryIO, limit: int = MAX_LINE_BYTES) -> Iterator[bytes]:
    """The lines of `fh` (bytes, newline kept); an over-long line is read past in pieces of
    `limit` bytes and yielded as `OVERLONG_LINE`."""
    while True:
        line = fh.readline(limit + 1)
        if not line:
            return
        if len(line) <= limit:
            yield line
            continue
        while not line.endswith(b"\n"):
            line = fh.readline(limit + 1)
            if not line:
                break
        yield OVERLONG_LINE


def read_image(path: str | os.PathLike[str], flags: int | None = None) -> Any:
    """The image at `path` decoded by OpenCV (`cv2.imread` with `flags`, default colour BGR),
    or ValueError naming the file when OpenCV cannot read it (instead of a None passed on)."""
    import cv2

    image = cv2.imread(str(path), cv2.IMREAD_COLOR if flags is None else flags)
    if image is None:
        raise ValueError(f"path: OpenCV cannot read an image from {path}")
    return image
