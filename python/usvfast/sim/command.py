"""`usvfast simulate`: write a simulated harbour recording (rosbag2, optionally the D1
layout), its ground truth and the pipeline config that runs it."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from usvfast.sim.recording import SimulationOptions, simulate


def simulate_command(
    out: Annotated[Path, typer.Option(help="New (or empty) output folder")],
    seed: Annotated[int, typer.Option(help="Seed of the harbour; same seed, same bytes")] = 0,
    duration: Annotated[float, typer.Option(help="Recording length, s")] = 60.0,
    d1: Annotated[
        bool, typer.Option("--d1/--no-d1", help="Also write the D1 layout (pcap + mp4 + NMEA)")
    ] = False,
    width: Annotated[int, typer.Option(help="Camera image width, px")] = 640,
    height: Annotated[int, typer.Option(help="Camera image height, px")] = 360,
    jpeg_quality: Annotated[int, typer.Option(help="JPEG quality of the frames, 1-100")] = 70,
    lidar_buildings: Annotated[
        bool,
        typer.Option(
            "--lidar-buildings/--no-lidar-buildings",
            help="Whether the LiDAR sees the buildings behind the quays (off: a smaller bag)",
        ),
    ] = True,
    zstd_level: Annotated[int, typer.Option(help="zstd level of the bag messages, 1-22")] = 9,
) -> None:
    """Simulate a harbour recording: VLP-16 packets, camera JPEGs, GNSS NMEA, IMU, truth."""
    console = Console(stderr=True)
    try:
        opts = SimulationOptions(
            seed=seed,
            duration=duration,
            width=width,
            height=height,
            jpeg_quality=jpeg_quality,
            d1=d1,
            lidar_buildings=lidar_buildings,
            zstd_level=zstd_level,
        )
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    t0 = time.perf_counter()
    columns = (
        TextColumn("[bold]simulate[/]"),
        BarColumn(),
        TextColumn("{task.completed:.1f}/{task.total:.0f} s"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=console, transient=True) as bar:
        task = bar.add_task("simulate", total=duration)

        def progress(done: float) -> None:
            bar.update(task, completed=min(max(done, 0.0), duration))

        try:
            result = simulate(out, opts, progress=progress)
        except ValueError as exc:
            raise typer.BadParameter(str(exc)) from exc
    elapsed = time.perf_counter() - t0
    counts = ", ".join(f"{k} {v}" for k, v in sorted(result.counts.items()))
    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    typer.echo(f"wrote {out} ({size / 1e6:.1f} MB) in {elapsed:.1f} s: {counts}")
    typer.echo(
        f"truth: {result.truth_rows} rows; run it with: usvfast run {out / 'recording.toml'}"
    )
