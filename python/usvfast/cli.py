"""The `usvfast` command line. Each concern adds its subcommands in its own module."""

from __future__ import annotations

import typer

from usvfast import __version__
from usvfast.bearing.command import bearing_command, demo_command
from usvfast.fusion.command import vts_command
from usvfast.lidar.command import lidar_command
from usvfast.nav.inspect import inspect_command
from usvfast.pipeline.command import demo_command as pipeline_demo_command
from usvfast.pipeline.command import run_command
from usvfast.pipeline.draft import init_command
from usvfast.report.command import report_command
from usvfast.shore.command import shore_command, shore_train_command
from usvfast.sim.command import simulate_command
from usvfast.sweep.command import sweep_command
from usvfast.trackcmd import track_command

app = typer.Typer(
    help="usvfast: fast maritime multi-sensor detection and tracking.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,  # user errors are one line (main), not a traceback box
)


def _print_version(value: bool) -> None:
    if value:
        typer.echo(__version__)
        raise typer.Exit()


@app.callback()
def _options(
    version: bool = typer.Option(
        False, "--version", callback=_print_version, is_eager=True, help="Print the version."
    ),
) -> None:
    """usvfast: fast maritime multi-sensor detection and tracking."""


@app.command()
def version() -> None:
    """Print the installed usvfast version."""
    typer.echo(__version__)


app.command("bearing")(bearing_command)
app.command("bearing-demo")(demo_command)
app.command("demo")(pipeline_demo_command)
app.command("run")(run_command)
app.command("init")(init_command)
app.command("lidar")(lidar_command)
app.command("inspect")(inspect_command)
app.command("track")(track_command)
app.command("report")(report_command)
app.command("simulate")(simulate_command)
app.command("shore")(shore_command)
app.command("shore-train")(shore_train_command)
app.command("vts")(vts_command)
app.command("sweep")(sweep_command)


def main() -> None:
    """Entry point of the `usvfast` console script. A bad input or a missing optional
    dependency is one line on stderr and exit status 2, not a traceback."""
    from usvfast._extras import MissingExtraError

    try:
        app()
    except (ValueError, TypeError, OSError, MissingExtraError) as exc:
        typer.echo(f"usvfast: error: {exc}", err=True)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
