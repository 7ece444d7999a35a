"""`dive fit`: the simulator's fit (a process of its own), after an identification manoeuvre when --excite asks."""

from __future__ import annotations

from pathlib import Path

import typer

from groundstation.cli.common import err, one_line_errors
from groundstation.cli.validate import UsageError
from groundstation.errors import GroundStationError
from groundstation.simulator_process import run_simulator_command

# The ground station's own options; everything else is the simulator's `fit` (`dive fit --help`).
EXCITE_OPTIONS = {"--excite": "url", "--depths": "depths", "--hold": "hold", "--max-depth": "max_depth",
                  "--reversals": "reversals", "--reversal-hold": "reversal_hold"}


def split_excite(args: list[str]) -> tuple[dict[str, str], list[str]]:
    """(the manoeuvre's options, the simulator's arguments)."""
    ours: dict[str, str] = {}
    rest: list[str] = []
    words = iter(args)
    for word in words:
        name, equals, value = word.partition("=")
        if name in EXCITE_OPTIONS:
            if not equals:
                value = next(words, "")
            if not value:
                raise UsageError(f"{name} needs a value")
            ours[EXCITE_OPTIONS[name]] = value
        else:
            rest.append(word)
    return ours, rest


def fit(ctx: typer.Context) -> None:
    """Fit the simulator's plant to recordings: a plant file for --params (`dive fit --help` for options).

    `dive fit --excite URL [--depths 0.3,0.6,0.4,0.8,0.3] [--hold 30] [--reversals 0.02,0.05,0.1]
    [--reversal-hold 3] [--max-depth 1.0]` first flies an identification manoeuvre (hover at each depth for --hold s
    of agent time, then the hover depth flipped each --reversals deeper than the last depth and back, twice per
    amplitude, --reversal-hold s each; `--reversals 0` for none), records it, then fits it.
    """
    raise typer.Exit(_fit(list(ctx.args)))


@one_line_errors
def _fit(args: list[str]) -> int:
    ours, rest = split_excite(args)
    if ours:
        if "url" not in ours:
            raise UsageError("--depths, --hold, --reversals, --reversal-hold and --max-depth go with --excite URL")
        rest = [*(str(p) for p in _fly(ours)), *rest]
    return run_simulator_command(["fit", *rest])


def _fly(options: dict[str, str]) -> list[Path]:
    from groundstation.run.excite import ExciteConfig, check, excite

    default = ExciteConfig()
    try:
        depths = tuple(float(x) for x in options.get("depths", "0.3,0.6,0.4,0.8,0.3").split(","))
        hold = float(options.get("hold", "30"))
        max_depth = float(options.get("max_depth", "1.0"))
        reversals = (default.reversals_m if "reversals" not in options
                     else tuple(float(x) for x in options["reversals"].split(",") if float(x) != 0.0))
        reversal_hold = float(options.get("reversal_hold", str(default.reversal_hold_s)))
    except ValueError:
        raise UsageError("--depths, --hold, --reversals, --reversal-hold and --max-depth take numbers (depths and "
                         "reversals comma-separated)") from None
    config = ExciteConfig(url=options["url"], depths_m=depths, hold_s=hold, max_depth_m=max_depth,
                          reversals_m=reversals, reversal_hold_s=reversal_hold)
    try:
        check(config)
    except GroundStationError as e:
        raise UsageError(str(e)) from None
    paths = excite(config, lambda depth, hold_s: err.print(f"excite: hover at {depth:g} m for {hold_s:g} s of agent "
                                                           "time"))
    err.print(f"excite: recorded {', '.join(str(p) for p in paths)}")
    return paths
