"""docs/reproduction.md is a reference, not a lab notebook: short, every figure with its command, and the figures
its cheapest command gives are the ones it documents (scripts/check_reproduction.py runs the rest)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from scripts.check_reproduction import CHECKS

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "reproduction.md"
# Words of how the work was organised, not of the project ("stop 35", "stops 34-35", "since the last session").
NOTEBOOK = re.compile(r"\bstops? \d+|\b(?:last|this|next|previous) session\b", re.IGNORECASE)


def _sections(text: str) -> list[tuple[str, str]]:
    """(heading, body) for every ## and ### section; a ## section's body ends at its first ###."""
    parts = re.split(r"^(#{2,3} .*)$", text, flags=re.MULTILINE)
    return list(zip(parts[1::2], parts[2::2], strict=True))


def _is_figure_row(line: str) -> bool:
    """A table row that carries figures: not the separator, not a row of pictures."""
    return line.startswith("|") and not set(line) <= set("|-: ") and "![" not in line and bool(re.search(r"\d", line))


def test_the_page_is_under_400_lines() -> None:
    assert len(DOC.read_text().splitlines()) < 400


def test_no_page_of_docs_speaks_of_work_sessions() -> None:
    pages = [p for p in sorted((ROOT / "docs").rglob("*")) if p.suffix in {".md", ".toml"}]
    found = [f"{p.relative_to(ROOT)}: {m.group()!r}" for p in pages for m in NOTEBOOK.finditer(p.read_text())]
    assert not found


def test_every_section_with_figures_has_its_command() -> None:
    missing = [heading for heading, body in _sections(DOC.read_text())
               if any(_is_figure_row(line) for line in body.splitlines()) and "```bash" not in body]
    assert not missing, f"sections with a figure table and no ```bash block: {missing}"


def test_the_checker_runs_the_pages_commands_and_checks_its_figures() -> None:
    text = DOC.read_text()
    for check in CHECKS:
        assert check.command in text, f"{check.name}: its command is not on the page"
        for figure in check.figures:
            assert figure.documented in text, f"{check.name}: {figure.documented!r} is not on the page"


@pytest.mark.slow
def test_the_cheapest_check_agrees_with_the_page() -> None:
    # One study of one trial (a few seconds once the study's kernels are compiled).
    done = subprocess.run([sys.executable, "scripts/check_reproduction.py", "--only", "trial0"], cwd=ROOT,
                          capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "documented episode 20, measured episode 20: ok" in done.stdout
