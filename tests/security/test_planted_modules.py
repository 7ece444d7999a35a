"""A folder the owner starts dive from may hold another user's code (/tmp, a shared project folder): the Python
children dive starts with `-m` (the simulator, the viewers' bridge) must not import it from there (issue 38).
`python -m` puts the current folder first on the import path unless told `-P`.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from groundstation.view.web_server import private_network_problem

DIVE = str(Path(sys.executable).with_name("dive"))


def _plant(folder: Path, module: str) -> Path:
    """`module` (dotted) as a package tree in `folder` whose code leaves a mark when it runs; the mark's path."""
    mark = folder / f"ran-{module}"
    parts = module.split(".")
    package = folder.joinpath(*parts[:-1]) if len(parts) > 1 else folder / parts[0]
    package.mkdir(parents=True)
    for depth in range(1, len(parts)):
        (folder.joinpath(*parts[:depth]) / "__init__.py").write_text("")
    code = f"open({str(mark)!r}, 'w').write('planted')\nraise SystemExit(7)\n"
    if len(parts) == 1:
        (package / "__init__.py").write_text("")
        (package / "__main__.py").write_text(code)
    else:
        (package / f"{parts[-1]}.py").write_text(code)
    return mark


def test_a_simulator_folder_where_dive_is_started_is_not_what_runs(tmp_path: Path) -> None:
    mark = _plant(tmp_path, "simulator")
    done = subprocess.run([DIVE, "sim", "--help"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert not mark.exists(), "the planted simulator ran as the owner"
    assert done.returncode == 0 and "dive sim" in done.stdout, (done.returncode, done.stdout[-300:], done.stderr)


def test_a_planted_bridge_where_dive_is_started_is_not_what_runs(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    mark = _plant(tmp_path, "groundstation.view.web_bridge")
    monkeypatch.chdir(tmp_path)
    private_network_problem()  # asks the bridge's own code, in a child started from this folder
    assert not mark.exists(), "the planted bridge ran as the owner"
