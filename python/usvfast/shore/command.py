"""`usvfast shore`: run the shore/bridge camera chain over a video or a folder of frames."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from usvfast.shore.pipeline import DETECTORS, TRACKERS, ShoreConfig, run_shore


def shore_command(
    input_path: Annotated[
        Path, typer.Argument(metavar="INPUT", help="A video file or a folder of frames")
    ],
    out: Annotated[Path, typer.Option("--out", help="Output folder")],
    detector: Annotated[str, typer.Option(help=f"Detector: {', '.join(DETECTORS)}")] = "bayes",
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
        config = ShoreConfig(detector=detector, tracker=tracker, horizon_filter=horizon_filter)
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
