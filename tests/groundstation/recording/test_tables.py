"""`open_recording` and `dive log export --format minari` on real `dive run` recordings of two boots."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from groundstation import open_recording
from groundstation.errors import RecordingError
from groundstation.recording.info import summarize
from tests.reliability.recordings import dive
from tests.simulator.agent_client import ROOT

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def two_boots(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two `dive run` sessions, each against a freshly started virtual agent (so two boots)."""
    folder = tmp_path_factory.mktemp("recordings")
    for seed in (3, 4):
        result = dive("run", "--speed", "max", "--seed", str(seed), "--episodes", "4",
                      "--param", "success_time_s=5", "--out", str(folder / f"run{seed}.mcap"))
        assert result.returncode == 0, result.stderr
    return folder


def test_tables_match_log_info(two_boots: Path) -> None:
    path = two_boots / "run3.mcap"
    rec, summary = open_recording(path), summarize(path)
    samples = rec.samples()
    assert len(samples) == summary.samples and len(np.unique(samples["sample"])) == len(samples)
    assert np.all(np.diff(samples["sample"]) > 0)  # one row per sample, in order
    episodes = rec.episodes()
    assert list(episodes["episode"]) == [e.episode for e in summary.episodes]
    assert list(episodes["outcome"]) == [e.outcome for e in summary.episodes]
    assert {"t_us", "host_time_ns", "boot", "depth_m", "mode"} <= set(samples.dtype.names or ())
    beats = rec.table("/agent/HEARTBEAT")
    assert len(beats) == rec.topics["/agent/HEARTBEAT"] and beats["uptime_ms"].dtype == np.int64
    with pytest.raises(RecordingError, match="no topic /nope"):
        rec.table("/nope")


def test_time_window_is_agent_time(two_boots: Path) -> None:
    rec = open_recording(two_boots / "run3.mcap")
    t0 = rec.samples()["t_us"].min()
    window = [m for m in rec.messages({"/agent/SAMPLE"}, start_s=2.0, end_s=3.0)]
    times = [int(m.json()["t_us"]) for m in window]
    assert window and all(2e6 <= t - t0 < 3e6 for t in times)


def test_folder_of_two_boots_keeps_episodes_apart(two_boots: Path) -> None:
    rec = open_recording(two_boots)
    assert len(rec.boots) == 2
    episodes = rec.episodes()
    expected = sum(len(summarize(p).episodes) for p in sorted(two_boots.glob("*.mcap")))
    assert len(episodes) == expected
    assert set(episodes["boot"]) == set(rec.boots)  # episode 1 of each boot is its own row


def test_minari_dataset_loads_with_minari(two_boots: Path, tmp_path: Path) -> None:
    result = dive("log", "export", str(two_boots), "--format", "minari", "--out", str(tmp_path / "datasets"))
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    expected = sum(len(summarize(p).episodes) for p in sorted(two_boots.glob("*.mcap")))
    script = (
        "import minari, json, numpy as np\n"
        "d = minari.load_dataset('diving_agent/recordings0-v0')\n"
        "eps = list(d.iterate_episodes())\n"
        "ok = all(len(e.observations) == len(e.actions) + 1 and (e.terminations[-1] or e.truncations[-1])"
        " and not (e.terminations[:-1].any() or e.truncations[:-1].any()) for e in eps)\n"
        "inside = all(d.spec.observation_space.contains(o) for e in eps for o in e.observations)\n"
        "env = d.recover_environment()\n"
        "print(json.dumps([int(d.total_episodes), d.spec.env_spec.id, ok, inside, int(env.action_space.n)]))\n"
    )
    env = {**os.environ, "MINARI_DATASETS_PATH": str(tmp_path / "datasets")}
    loaded = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, env=env,
                            timeout=240)
    assert loaded.returncode == 0, loaded.stderr
    assert loaded.stdout.strip().splitlines()[-1] == f"[{expected}, \"DivingAgent-v0\", true, true, 2]"
    again = dive("log", "export", str(two_boots), "--format", "minari", "--out", str(tmp_path / "datasets"))
    assert again.returncode == 1 and "already exists" in again.stderr  # never overwritten


def test_observation_bounds_are_the_environments() -> None:
    import simulator.gym.env as gym_env
    from groundstation.recording import minari_export

    assert tuple(gym_env.OBS_LOW) == minari_export.OBS_LOW and tuple(gym_env.OBS_HIGH) == minari_export.OBS_HIGH


def _layout_references(layout: dict) -> set[tuple[str, str]]:
    """(topic, field path) pairs the Foxglove layout reads from a recording, its script's inputs included."""
    import re

    wanted: set[tuple[str, str]] = set()
    outputs = set()
    for node in layout["userNodes"].values():
        source = node["sourceCode"]
        outputs.add(re.search(r'output = "([^"]+)"', source).group(1))  # type: ignore[union-attr]
        (topic,) = re.findall(r'inputs = \["([^"]+)"\]', source)
        wanted |= {(topic, name) for name in re.findall(r"start\.(\w+)", source)}
    for config in layout["configById"].values():
        for value in [p["value"] for p in config.get("paths", [])] + [config.get("topicPath", "")]:
            if not value:
                continue
            topic, _, field = re.sub(r"\.@\w+$", "", value).partition(".")  # a math modifier (.@negative) off
            if topic not in outputs:
                wanted.add((topic, field))
    return wanted


def test_foxglove_layout_plots_only_what_is_recorded(two_boots: Path) -> None:
    import json

    from scripts.foxglove_layout import OUT, layout

    shipped = json.loads(OUT.read_text())
    assert shipped == layout(), "docs/foxglove layout is stale: run python scripts/foxglove_layout.py"
    rec = open_recording(two_boots / "run3.mcap")
    references = _layout_references(shipped)
    assert {"/agent/SAMPLE", "/agent/EPISODE_END", "/link", "/agent/TEXT"} <= {t for t, _ in references}
    for topic, field in sorted(references):
        assert topic in rec.topics, f"the layout reads {topic}, which a recording does not hold"
        if field:
            body = next(rec.messages({topic})).json()
            for part in field.split("."):
                assert isinstance(body, dict) and part in body, f"{topic} has no field {field}"
                body = body[part]
