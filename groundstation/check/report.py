"""The report of a check run: a rich table (section, check, result, detail) and a summary line, or JSON."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table
from rich.text import Text

from groundstation.check.registry import Outcome, Result
from groundstation.check.runner import Report
from groundstation.safe_output import styled

_STYLE = {Result.PASS: "green", Result.FAIL: "bold red", Result.SKIP: "yellow"}


def table(outcomes: list[Outcome], sentences: bool = False) -> Table:
    t = Table(show_lines=False, expand=False)
    t.add_column("section", style="dim", no_wrap=True)
    t.add_column("check", no_wrap=True)
    t.add_column("result", no_wrap=True)
    t.add_column("detail")
    for o in outcomes:  # Text, never markup: a detail quotes what the agent sent (issue 13 item 8)
        detail = styled(o.detail, "")
        if sentences or o.result == Result.FAIL:
            detail.append_text(styled(f"\n“{o.check.sentence}”", "dim"))
        t.add_row(o.check.section, o.check.id, styled(o.result.value, _STYLE[o.result]), detail)
    return t


def summary(report: Report) -> Text:
    counts = ", ".join(f"{report.count(r)} {r.value.lower()}ed" if r != Result.SKIP else f"{report.count(r)} skipped"
                       for r in Result)
    verdict = styled("conforms", "green") if report.passed else styled("does not conform", "bold red")
    aborted = f" (stopped: {report.aborted})" if report.aborted else ""
    return Text.assemble(styled(f"{report.url}: ", ""), verdict,
                         styled(f": {counts} in {report.seconds:.1f} s{aborted}", ""))


def print_report(report: Report, console: Console, sentences: bool = False) -> None:
    console.print(table(report.outcomes, sentences))
    console.print(summary(report))
