"""`usvfast shore`: run the shore/bridge camera chain over a video or a folder of frames."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from usvfast.shore.cascade import CascadeConfig, save_cascade, train_detector
from usvfast.shore.mardct import load_mardct
from usvfast.shore.pipeline import DETECTORS, TRACKERS, ShoreConfig, run_shore


def shore_command(
    input_path: Annotated[
        Path, typer.Argument(metavar="INPUT", help="A video file or a folder of frames")
    ],
    out: Annotated[Path, typer.Option("--out", help="Output folder")],
    detector: Annotated[str, typer.Option(help=f"Detector: {', '.join(DETECTORS)}")] = "bayes",
    model: Annotated[
        Path | None, typer.Option(help="Cascade XML for --detector cascade (shore-train)")
    ] = None,
    tracker: Annotated[str, typer.Option(help=f"Tracker: {', '.join(TRACKERS)}")] = "sort",
    horizon_filter: Annotated[
        bool, typer.Option(help="Drop detections well above the horizon line")
    ] = True,
    video: Annotated[bool, typer.Option(help="Write the annotated video")] = True,
    max_frames: Annotated[int, typer.Option(help="Stop after this many frames (0: all)")] = 0,
    progress: Annotated[bool, typer.Option(help="Show a progress bar")] = True,
) -> None:
    """Detect and track vessels in shore or bridge camera footage; write tracks.txt and
    detections.txt (MOTChallenge), an annotated video and summary.json into OUT."""
    try:
        config = ShoreConfig(
            detector=detector,  # pyright: ignore[reportArgumentType]  # (ShoreConfig checks it)
            tracker=tracker,  # pyright: ignore[reportArgumentType]
            horizon_filter=horizon_filter,
            cascade_model=model,
        )
        s = run_shore(
            input_path, out, config, video=video, progress=progress, max_frames=max_frames
        )
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    console = Console()
    console.print(
        f"{s.frames} frames ({s.undecoded_frames} undecoded) at {s.processing_fps:.1f} FPS; "
        f"{s.detections} detections ({s.detections_raw} before the horizon filter), "
        f"{s.tracks} tracks; outputs in {out}"
    )
    if s.undecoded_frames:
        console.print(
            f"[yellow]{s.undecoded_frames} frame(s) could not be decoded "
            f"(damaged or truncated input): processed up to the damage[/yellow]"
        )


def shore_train_command(
    annotations: Annotated[
        Path, typer.Argument(help="Folder of NAME_FRAME.png + NAME_FRAME.txt (boat X Y W H)")
    ],
    out: Annotated[Path, typer.Option("--out", help="Cascade XML file to write")],
    max_stages: Annotated[int, typer.Option(help="Most stages (the last on wakes)")] = 14,
    seed: Annotated[int, typer.Option(help="Seed of the negative windows")] = 0,
) -> None:
    """Train the Haar boat cascade (60 × 30 window) on annotated frames; write OpenCV XML
    (loadable by `cv2.CascadeClassifier` and by `usvfast shore --detector cascade`)."""
    try:
        frames = [f for v in load_mardct(annotations).values() for f in v]
        t0 = time.perf_counter()
        detector, report = train_detector(frames, CascadeConfig(max_stages=max_stages, seed=seed))
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    save_cascade(detector, out)
    Console().print(
        f"{len(report['stages'])} stages from {report['positives']} positive windows in "
        f"{time.perf_counter() - t0:.1f} s; wrote {out}"
    )
