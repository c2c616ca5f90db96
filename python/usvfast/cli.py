"""The `usvfast` command line. Each concern adds its subcommands in its own module."""

from __future__ import annotations

import typer

from usvfast import __version__
from usvfast.bearing.command import bearing_command, demo_command
from usvfast.lidar.command import lidar_command
from usvfast.nav.inspect import inspect_command
from usvfast.sweep.command import sweep_command

app = typer.Typer(
    help="usvfast: fast maritime multi-sensor detection and tracking.",
    no_args_is_help=True,
    add_completion=False,
)


@app.command()
def version() -> None:
    """Print the installed usvfast version."""
    typer.echo(__version__)


app.command("bearing")(bearing_command)
app.command("demo")(demo_command)
app.command("lidar")(lidar_command)
app.command("inspect")(inspect_command)
app.command("sweep")(sweep_command)


def main() -> None:
    """Entry point of the `usvfast` console script."""
    app()


if __name__ == "__main__":
    main()
