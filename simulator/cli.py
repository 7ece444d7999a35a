"""Command line of the simulator process (`python -m simulator`); `dive sim` and `dive study` forward here."""

from __future__ import annotations

import os
import sys
from typing import Any

import typer

from simulator.serve.cli import serve

SERVE_NAMES = ("serve", "sim")  # `dive sim` forwards here as `sim`, so its usage line says `dive sim`


def _root() -> None:
    """The virtual diving agent and the batch study runner."""


def build_app(with_study_and_fit: bool = True) -> typer.Typer:
    """The simulator's typer app. Without study and fit (`serve` alone), scipy and matplotlib are not imported: a
    virtual agent prints its address, and answers its link, a second or more sooner (seconds on a loaded machine)."""
    app = typer.Typer(
        name="simulator",
        help="The virtual diving agent and the batch study runner.",
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
        context_settings={"help_option_names": ["-h", "--help"]},  # as dive's own commands: `dive study -h`
    )
    app.command()(serve)
    app.command(name="sim", hidden=True)(serve)
    app.callback()(_root)
    if with_study_and_fit:
        from learning import learner_help
        from simulator.fit.cli import fit
        from simulator.study.cli import study

        # Every learner on a line of its own (typer's help keeps a line break only between paragraphs).
        app.command(name="study", epilog="\n\n".join(["Learners:", *learner_help().splitlines()]))(study)
        app.command(name="fit")(fit)
    return app


def __getattr__(name: str) -> Any:
    """`app`, the whole command line (tests drive it), built when first asked for."""
    if name == "app":
        return build_app()
    raise AttributeError(name)


def main() -> None:
    # Started by `dive sim` / `dive study`, usage lines name the command the user typed (see groundstation).
    app = build_app(with_study_and_fit=sys.argv[1:2] not in ([n] for n in SERVE_NAMES))
    app(prog_name=os.environ.get("DIVE_SIMULATOR_PROG_NAME", "python -m simulator"))
