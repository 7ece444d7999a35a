"""The `dive` command line: parses, calls library code, and maps errors to one line and an exit code."""

from __future__ import annotations

import os
import sys
from typing import Annotated

import typer
from rich.text import Text

from groundstation.cli import agent as cli_agent
from groundstation.cli import check as cli_check
from groundstation.cli import control as cli_control
from groundstation.cli import fit as cli_fit
from groundstation.cli import log as cli_log
from groundstation.cli import record as record_cli
from groundstation.cli import run as cli_run
from groundstation.cli import view as view_cli
from groundstation.cli.common import TAKES_NEGATIVE, err, hostile_data_reason
from groundstation.cli.typer_help import load_typer_help
from groundstation.safe_output import one_line
from groundstation.session.keys import keygen
from groundstation.simulator_process import run_simulator_command

app = typer.Typer(
    name="dive",
    help="Ground station for the micro diving agent: connect, command, record (MCAP), view (Rerun), replay.\n\n"
         "Exit codes: 0 done, 1 failed (one line on stderr says why), 2 bad usage, 130 stopped by Ctrl-C.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode="rich",
    context_settings={"help_option_names": ["-h", "--help"]},
)
def _version(value: bool) -> None:
    if value:
        from groundstation.session.hello import tool_version

        typer.echo(f"dive {tool_version()}")
        raise typer.Exit()


@app.callback()
def _options(version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                                   help="Print dive's version and exit.")] = False) -> None:
    """Options of dive itself (the app's help text is the Typer's)."""


app.add_typer(cli_log.log_app, name="log")

_FORWARD = {"allow_extra_args": True, "ignore_unknown_options": True, "help_option_names": []}

# In the order `dive --help` lists them.
app.command("run")(cli_run.run_command)
app.command()(cli_agent.status)
app.command("params", context_settings=TAKES_NEGATIVE)(cli_agent.params_command)
app.command()(cli_control.start)
app.command()(cli_control.pause)
app.command()(cli_control.resume)
app.command()(cli_control.stop)
app.command(context_settings=TAKES_NEGATIVE)(cli_control.target)
app.command()(cli_control.surface)
app.command(context_settings=TAKES_NEGATIVE)(cli_control.hover)
app.command("reset-model")(cli_control.reset_model)
app.command()(cli_agent.dump)
app.command()(cli_agent.mark)
app.command()(cli_agent.ack)
app.command("check")(cli_check.check_command)


# ---------------------------------------------------------------------- the simulator process
@app.command(context_settings=_FORWARD, add_help_option=False)
def sim(ctx: typer.Context) -> None:
    """Serve a virtual diving agent over TCP or a pseudo-terminal (`dive sim --help` for options)."""
    raise typer.Exit(run_simulator_command(["sim", *ctx.args]))


@app.command(context_settings=_FORWARD, add_help_option=False)
def study(ctx: typer.Context) -> None:
    """Run N trials x E episodes of a learner on the simulated plant (`dive study --help` for options)."""
    raise typer.Exit(run_simulator_command(["study", *ctx.args]))


app.command(context_settings=_FORWARD, add_help_option=False)(cli_fit.fit)
app.command(name="view")(view_cli.view)
app.command(name="replay")(view_cli.replay)
app.command(name="record")(record_cli.record)
app.command(name="keygen")(keygen)


def main() -> None:
    """Exit codes (README): 0 done, 1 failed, 2 bad usage, 130 interrupted. A bug is one line too, not a traceback
    (DIVE_DEBUG=1 shows it)."""
    load_typer_help()
    from groundstation.view.options import with_flag_value

    sys.argv[1:] = with_flag_value(sys.argv[1:])
    try:
        app()
    except KeyboardInterrupt:
        sys.exit(130)
    except (RecursionError, OverflowError) as e:
        if os.environ.get("DIVE_DEBUG"):
            raise
        err.print(Text.assemble(("dive:", "bold red"), " ", hostile_data_reason(e)), soft_wrap=True)
        sys.exit(1)
    except Exception as e:  # noqa: BLE001 the last line of defence: a traceback reaching a user is a bug
        if os.environ.get("DIVE_DEBUG"):
            raise
        # A SafeConsole prints markup as text (issue 25 L2): the style goes in a Text, the error's words as data.
        err.print(Text.assemble(("dive: internal error:", "bold red"), f" {type(e).__name__}: {one_line(str(e))} "
                                "(DIVE_DEBUG=1 shows where)"), soft_wrap=True)
        sys.exit(1)


if __name__ == "__main__":
    main()
