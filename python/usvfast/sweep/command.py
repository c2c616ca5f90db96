"""`usvfast sweep SPEC --out DIR`: run a sweep spec on a Dask cluster and summarise it."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def sweep_command(
    spec: Annotated[Path, typer.Argument(help="Sweep spec (TOML): recordings, base, grid")],
    out: Annotated[Path, typer.Option(help="Output folder (results.parquet, plots)")],
    engine: Annotated[
        str, typer.Option(help="local (a Dask local cluster) or dask (--address)")
    ] = "local",
    address: Annotated[
        str | None, typer.Option(help="Dask scheduler address, e.g. tcp://host:8786")
    ] = None,
    workers: Annotated[int, typer.Option(help="Worker processes of the local cluster")] = 2,
    retry_failed: Annotated[
        bool, typer.Option(help="Run again the jobs that failed in an earlier run")
    ] = False,
) -> None:
    """Run every job (recording × parameter set) of SPEC not yet finished in OUT, one Parquet
    row per job in OUT/results.parquet, then print the best jobs and write the plots."""
    from rich.console import Console
    from rich.markup import escape
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn
    from rich.table import Table

    console = Console(stderr=True)
    try:
        from usvfast.sweep.run import run_sweep
        from usvfast.sweep.spec import load_spec
        from usvfast.sweep.summary import best_rows, param_columns, write_plots

        parsed = load_spec(spec, out)
        out.mkdir(parents=True, exist_ok=True)
        with Progress(
            "[progress.description]{task.description}",
            BarColumn(),
            MofNCompleteColumn(),
            TimeRemainingColumn(),
            console=console,
        ) as progress:
            task = progress.add_task(parsed.name, total=len(parsed.jobs))
            failed = 0

            def advance(row: dict) -> None:
                nonlocal failed
                failed += row.get("status") != "ok"
                progress.advance(task)

            result = run_sweep(
                parsed,
                out,
                engine=engine,
                address=address,
                workers=workers,
                retry_failed=retry_failed,
                on_result=advance,
            )
            progress.update(task, completed=len(parsed.jobs))
    except (ValueError, ImportError, OSError) as exc:
        console.print(f"[red]error:[/red] {escape(str(exc))}", soft_wrap=True)
        raise typer.Exit(code=1) from None
    table = result.table
    plots = write_plots(table, out, parsed.metric, parsed.maximize)
    best = best_rows(table, parsed.metric, parsed.maximize)
    summary = Table(title=f"{parsed.name}: best by {parsed.metric}")
    cols = ["recording", *param_columns(table), *[c for c in table if c.startswith("metric.")]]
    for c in cols:
        summary.add_column(c.split(".", 1)[-1], overflow="fold")
    for _, r in best.iterrows():
        summary.add_row(
            *[
                Path(str(r[c])).name
                if c == "recording"
                else f"{r[c]:.4g}"
                if isinstance(r[c], float)
                else str(r[c])
                for c in cols
            ]
        )
    Console().print(summary)
    n_bad = int((table["status"] != "ok").sum())
    typer.echo(
        f"{len(table)} jobs ({result.ran} run now, {result.skipped} finished before, "
        f"{n_bad} failed) -> {result.path}; plots: {', '.join(p.name for p in plots) or 'none'}"
    )
    if n_bad:
        raise typer.Exit(code=2)
