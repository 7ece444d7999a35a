"""The `dive` command line: parses, calls library code, and maps errors to one line and an exit code."""

from __future__ import annotations

import typer

from groundstation import view_cli
from groundstation.simulator_process import run_simulator_command

app = typer.Typer(
    name="dive",
    help="Ground station for the micro diving agent: connect, command, record (MCAP), view (Rerun), replay.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode="rich",
)

_FORWARD = {"allow_extra_args": True, "ignore_unknown_options": True, "help_option_names": []}


@app.command(context_settings=_FORWARD, add_help_option=False)
def sim(ctx: typer.Context) -> None:
    """Serve a virtual diving agent over TCP or a pseudo-terminal (`dive sim --help` for options)."""
    raise typer.Exit(run_simulator_command(["serve", *ctx.args]))


@app.command(context_settings=_FORWARD, add_help_option=False)
def study(ctx: typer.Context) -> None:
    """Run N trials x E episodes of a learner on the simulated plant (`dive study --help` for options)."""
    raise typer.Exit(run_simulator_command(["study", *ctx.args]))


app.command(name="view")(view_cli.view)
app.command(name="replay")(view_cli.replay)


def main() -> None:
    app()
