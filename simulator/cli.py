"""Command line of the simulator process (`python -m simulator`); `dive sim` and `dive study` forward here."""

from __future__ import annotations

import typer

from simulator.serve_cli import serve

app = typer.Typer(
    name="simulator",
    help="The virtual diving agent and the batch study runner.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


app.command()(serve)


@app.callback()
def _root() -> None:
    """The virtual diving agent and the batch study runner."""


def main() -> None:
    app()
