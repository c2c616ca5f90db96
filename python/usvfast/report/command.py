"""`usvfast report`: (re)write the metrics, table and pictures of a finished run."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape

from usvfast.report import write_report


def report_command(
    out: Annotated[Path, typer.Argument(help="Folder of a run (tracks.csv, detections.csv, ...)")],
    truth: Annotated[
        Path | None, typer.Option(help="Ground truth truth.csv (time,object_id,kind,north,east)")
    ] = None,
    scene: Annotated[
        Path | None, typer.Option(help="scene.json (harbour walls, moored boats) for the map")
    ] = None,
    animation: Annotated[
        bool | None,
        typer.Option(
            "--animation/--no-animation", help="Write animation.gif (default: with camera_frames/)"
        ),
    ] = None,
    html: Annotated[
        bool, typer.Option(help="Also write the interactive map.html (needs plotly)")
    ] = False,
    max_range: Annotated[
        float | None,
        typer.Option(
            help="Objects count as targets within this range of the USV all round, m "
            "(default: the sensors' coverage in summary.json, else 40)"
        ),
    ] = None,
) -> None:
    """Write metrics.json (with --truth), map.png, nis.png, errors.png and animation.gif into
    OUT and print the metrics table."""
    console = Console()
    start = time.time()
    options: dict[str, Any] = {} if max_range is None else {"max_range": max_range}
    try:
        metrics = write_report(
            out,
            truth=truth,
            scene=scene,
            animation=animation,
            html=html,
            console=console,
            **options,
        )
    except (FileNotFoundError, ValueError, TypeError) as exc:
        Console(stderr=True).print(f"[red]error:[/red] {escape(str(exc))}")
        raise typer.Exit(2) from None
    written = [
        p.name
        for p in sorted(out.iterdir())
        if p.suffix in (".png", ".gif", ".json", ".html") and p.stat().st_mtime >= start - 1
    ]
    console.print(f"wrote {', '.join(written)} in {escape(str(out))}", soft_wrap=True)
    if not metrics:
        console.print("no --truth: pictures only")
