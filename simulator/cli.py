"""Command line of the simulator process (`python -m simulator`); `dive sim` and `dive study` forward here."""

from __future__ import annotations

import typer

from simulator.serve_cli import serve
from simulator.study_cli import study

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


app.command(name="study")(study)


def main() -> None:
    app()
