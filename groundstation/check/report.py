"""The report of a check run: a rich table (section, check, result, detail) and a summary line, or JSON."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table

from groundstation.check.registry import Outcome, Result
from groundstation.check.runner import Report

_STYLE = {Result.PASS: "green", Result.FAIL: "bold red", Result.SKIP: "yellow"}


def table(outcomes: list[Outcome], sentences: bool = False) -> Table:
    t = Table(show_lines=False, expand=False)
    t.add_column("section", style="dim", no_wrap=True)
    t.add_column("check", no_wrap=True)
    t.add_column("result", no_wrap=True)
    t.add_column("detail")
    for o in outcomes:
        detail = o.detail + (f"\n[dim]“{o.check.sentence}”[/]" if sentences or o.result == Result.FAIL else "")
        t.add_row(o.check.section, o.check.id, f"[{_STYLE[o.result]}]{o.result.value}[/]", detail)
    return t


def summary(report: Report) -> str:
    counts = ", ".join(f"{report.count(r)} {r.value.lower()}ed" if r != Result.SKIP else f"{report.count(r)} skipped"
                       for r in Result)
    verdict = "[green]conforms[/]" if report.passed else "[bold red]does not conform[/]"
    aborted = f" (stopped: {report.aborted})" if report.aborted else ""
    return f"{report.url}: {verdict}: {counts} in {report.seconds:.1f} s{aborted}"


def print_report(report: Report, console: Console, sentences: bool = False) -> None:
    console.print(table(report.outcomes, sentences))
    console.print(summary(report))
