"""The notebook example of docs/recordings.md runs as written (issue 28 item 5): extracted from the page and run
against a real recording, with numpy alone (pandas hidden), and it prints the window's agent text."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from groundstation.recording.recorder import Recorder, RecorderConfig
from tests.groundstation.synthetic_agent import generate, play_session
from tests.simulator.agent_client import ROOT as ROOT_TEXT

ROOT = Path(ROOT_TEXT)


def test_the_notebook_example_runs_as_written(tmp_path: Path) -> None:
    page = (ROOT / "docs" / "recordings.md").read_text()
    block = re.search(r"## In a notebook\n\n```python\n(.*?)```", page, re.S)
    assert block is not None
    (tmp_path / "recordings").mkdir()
    recorder = Recorder(RecorderConfig(path=tmp_path / "recordings" / "run.mcap"))
    try:
        play_session(generate(duration_s=300.0), [recorder])
    finally:
        recorder.close()
    no_pandas = "import sys; sys.modules['pandas'] = None\n"  # as on a fresh install: the example needs none
    done = subprocess.run([sys.executable, "-c", no_pandas + block.group(1)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, env={"PYTHONPATH": str(ROOT), "PATH": ""})
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].startswith("3000 samples; depth")
    assert lines[1:] and all(re.fullmatch(r"episode \d+ done", line) for line in lines[1:]), lines
