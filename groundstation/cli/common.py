"""What every `dive` command shares: the consoles, errors as one line and an exit code, the agent's session."""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, TypeVar
from urllib.parse import urlsplit

import typer
from rich.text import Text

from groundstation.cli.validate import UsageError
from groundstation.errors import BadUrlError, GroundStationError
from groundstation.safe_output import SafeConsole, one_line
from groundstation.session.keys import resolve_key

if TYPE_CHECKING:  # the session (mcap, numpy) is imported by the commands that open one
    from groundstation.session.agent_session import Session

F = TypeVar("F", bound=Callable[..., Any])
err = SafeConsole(stderr=True)  # agent text and file names are data: no markup, control characters escaped
out = SafeConsole()


def wait_while_run_connects(url: str | None) -> None:
    """A run still connecting to its agent (a virtual one compiles for minutes) is waited for, saying so in one line,
    not answered "no dive run" or "tools attach once it is up" (`dive record`, `dive view`)."""
    from groundstation.links.runs import holder, wait_while_connecting

    given = url or os.environ.get("DIVE_URL")
    if given and not given.startswith("hub://"):
        held = holder(given)  # an agent URL a run holds: that run's hub
        if held is None:
            return
        given = f"hub://{held.run}"
    wait_while_connecting(urlsplit(given).netloc or None if given else None,
                          lambda line: typer.echo(one_line(line), err=True))


def one_line_errors(func: F) -> F:
    """Our errors (and a bad file) become one line on stderr and exit code 1 (a bad value: 2); Ctrl-C exits 130."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except (UsageError, BadUrlError) as e:  # a URL that cannot be read is bad usage too (README: exit 2)
            err.print(Text.assemble(("dive:", "bold red"), " ", one_line(str(e))), soft_wrap=True)
            raise typer.Exit(2) from None
        except (GroundStationError, OSError) as e:
            message = str(e).replace("\n", " ") or type(e).__name__
            err.print(Text.assemble(("dive:", "bold red"), " ", one_line(message)), soft_wrap=True)
            raise typer.Exit(1) from None
        except (RecursionError, OverflowError) as e:  # what hostile data raises deep in a parser: say so
            err.print(Text.assemble(("dive:", "bold red"), " ", hostile_data_reason(e)), soft_wrap=True)
            raise typer.Exit(1) from None
        except KeyboardInterrupt:
            raise typer.Exit(130) from None

    return wrapper  # type: ignore[return-value]


def hostile_data_reason(error: RecursionError | OverflowError) -> str:
    """The one line for what a damaged or hostile input raises where no check caught it first."""
    if isinstance(error, RecursionError):
        return "the data is nested too deeply to read (a damaged or hostile record?)"
    return f"a number in the data is out of range ({one_line(str(error))}; a damaged or hostile record?)"


@contextmanager
def agent_session(url: str | None, key_file: Path | None = None, reconnect: bool = False,
                  fetch_params: bool = True) -> Iterator[Session]:
    """A session with *the* agent: the URL given, else $DIVE_URL, else the running `dive run` (never a new sim).

    `reconnect`: a command whose link drops before its ACK is sent again on a new connection (the controls: an
    operator's `dive surface` must not fail because the radio blinked; SPEC.md s. 5 says how to read its answer)."""
    from groundstation.cli.waiting import BusyLine
    from groundstation.links import make_link
    from groundstation.links.runs import attach_url
    from groundstation.session.agent_session import Session, SessionConfig

    busy = BusyLine(err)  # a virtual agent still building its program answers BUSY: one line says we wait
    session = Session(make_link(attach_url(url)),
                      SessionConfig(reconnect=reconnect, backfill=False, key=resolve_key(key_file), name=tool_name(),
                                    fetch_params=fetch_params), [busy])
    with busy, session:
        yield session


def tool_name() -> str:
    """The command running ("dive target"): its HELLO's name, by which a run's pane says who sent a command."""
    import click

    return command_path(click.get_current_context(silent=True))


def command_path(context: Any) -> str:
    """"dive params" for a click context, however dive was started (`python -m groundstation.cli.app` too)."""
    names: list[str] = []
    while context is not None and context.parent is not None:  # the root's name is how it was started
        names.insert(0, context.info_name or "")
        context = context.parent
    return " ".join(["dive", *names])


_URL_HELP = ("tcp://HOST:PORT, serial:///dev/ttyUSB0?baud=115200, sim://?speed=max, hub://RUN "
             "(default: $DIVE_URL, else the running `dive run`)")
UrlArg = Annotated[str | None, typer.Argument(help=_URL_HELP, show_default=False)]

TAKES_NEGATIVE = {"ignore_unknown_options": True}  # `-5` is a value, not an unknown option


def split_url(args: list[str], actions: tuple[str, ...] = ()) -> tuple[str | None, list[str]]:
    """An optional URL (it has `://` or is a /dev path), then the command's own words. The URL may also follow an
    action word (`dive params get tcp://... NAME`), the order people type who think of the action first."""
    def is_url(word: str) -> bool:
        return ("://" in word or word.startswith("/dev/")) and word not in actions

    if args and is_url(args[0]):
        return args[0], args[1:]
    if len(args) > 1 and args[0] in actions and is_url(args[1]):
        return args[1], [args[0], *args[2:]]
    return None, args


def existing(path: Path) -> Path:
    if not path.is_file():
        raise GroundStationError(f"no such recording: {path}")
    return path

