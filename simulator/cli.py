"""Command line of the simulator process (`python -m simulator`); `dive sim` and `dive study` forward here."""

from __future__ import annotations

import os

import typer

from learning import learner_help
from simulator.fit.cli import fit
from simulator.serve.cli import serve
from simulator.study.cli import study

app = typer.Typer(
    name="simulator",
    help="The virtual diving agent and the batch study runner.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},  # as dive's own commands: `dive study -h`
)


app.command()(serve)
app.command(name="sim", hidden=True)(serve)  # `dive sim` forwards here as `sim`, so its usage line says `dive sim`


@app.callback()
def _root() -> None:
    """The virtual diving agent and the batch study runner."""


# Every learner on a line of its own (typer's help keeps a line break only between paragraphs).
app.command(name="study", epilog="\n\n".join(["Learners:", *learner_help().splitlines()]))(study)
app.command(name="fit")(fit)


def main() -> None:
    # Started by `dive sim` / `dive study`, usage lines name the command the user typed (see groundstation).
    app(prog_name=os.environ.get("DIVE_SIMULATOR_PROG_NAME", "python -m simulator"))
