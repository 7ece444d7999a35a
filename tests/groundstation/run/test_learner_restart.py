"""Issue 39's tank day: a learner restart mid-run (pause, a learner parameter set, resume) is a new chapter.

A real `dive run` against each agent (the Python virtual agent, the C firmware's host build, the firmware on the
emulated Cortex-M4), its hub, and the tools as processes. The agent numbers the new learner's episodes from 1
again; every EPISODE_END it sent is then counted exactly once in `dive log info`, the Parquet episodes table,
open_recording().episodes(), the npz transitions and the Minari dataset, keyed (boot, generation, episode), and
the run pane says where the learner restarted.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from groundstation.recording.tables import open_recording
from tests.groundstation.hub_helpers import DIVE, dive, dive_env, running

pytestmark = pytest.mark.slow

AGENTS = {
    "python": "sim://?speed=5&seed=4",
    "c": "sim://?speed=5&firmware=c&seed=4",
    "qemu": "sim://?speed=5&firmware=qemu&seed=4",
}
EPISODES = 10  # the run's budget, across the restart (speed 5: about 2 s an episode)


@pytest.fixture(scope="module")
def qemu_env(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, str]]:
    """The environment `dive run` starts QEMU from (the ELF built once for the module)."""
    from simulator.serve.firmware_qemu import ELF_ENV, build_elf

    for tool, package in (("arm-none-eabi-gcc", "gcc-arm-none-eabi"), ("qemu-system-arm", "qemu-system-arm")):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not found: the QEMU agent needs {package}")
    yield {ELF_ENV: str(build_elf(tmp_path_factory.mktemp("qemu-build")))}


@pytest.mark.parametrize("agent", list(AGENTS))
def test_a_learner_restart_mid_run_counts_every_episode_once_everywhere(
        agent: str, tmp_path: Path, request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> None:
    if agent == "qemu":
        for name, value in request.getfixturevalue("qemu_env").items():
            monkeypatch.setenv(name, value)
    runtime, out = tmp_path / "runtime", tmp_path / "tank.mcap"
    with running(runtime, AGENTS[agent], out, "--episodes", str(EPISODES), "--success-time", "3",
                 start_timeout_s=180) as run:
        pane_lines: list[str] = []
        second = threading.Event()  # the pane said the second episode ended: the restart comes mid-run

        def read_pane() -> None:
            assert run.stderr is not None
            for line in run.stderr:
                pane_lines.append(line)
                if line.startswith("episode 2 "):
                    second.set()

        reader = threading.Thread(target=read_pane, daemon=True)
        reader.start()
        assert second.wait(120), "".join(pane_lines)[-3000:]
        paused = dive(runtime, "pause")
        assert paused.returncode == 0, paused.stderr
        changed = dive(runtime, "params", "set", "gamma", "0.98", "--reset-model")
        assert changed.returncode == 0, changed.stderr
        resumed = dive(runtime, "resume")
        assert resumed.returncode == 0, resumed.stderr
        run.wait(240)
        reader.join(10)
    pane = "".join(pane_lines)
    assert run.returncode == 0, pane[-3000:]
    # The run pane: one line where the learner restarted, naming who caused it and the new chapter.
    restarted = [line for line in pane.splitlines() if "the learner restarted" in line]
    assert len(restarted) == 1 and "PARAM_SET gamma" in restarted[0] and "chapter 2" in restarted[0], pane

    rec = open_recording(out)
    sent = [json.loads(msg.data) for msg in rec.messages({"/agent/EPISODE_END"})]
    keys = [(1, e["generation"], e["episode"]) for e in sent]
    assert len(set(keys)) == len(keys) and {k[1] for k in keys} == {1, 2}, keys  # two chapters, no key twice
    # the agent's own count: episodes 1..n of each generation, as its HEARTBEATs numbered them
    beats = [json.loads(msg.data) for msg in rec.messages({"/agent/HEARTBEAT"})]
    for generation in (1, 2):
        last = max(b["episode"] for b in beats if b["generation"] == generation)
        assert sorted(k[2] for k in keys if k[1] == generation)[-1] >= last

    episodes = rec.episodes()
    assert sorted(zip(episodes["boot"].tolist(), episodes["generation"].tolist(), episodes["episode"].tolist(),
                      strict=True)) == sorted(keys)

    info = dive(runtime, "log", "info", str(out), "--json")
    assert info.returncode == 0, info.stderr
    (summary,) = json.loads(info.stdout) if info.stdout.lstrip().startswith("[") else [json.loads(info.stdout)]
    assert sorted((e["boot"], e["generation"], e["episode"]) for e in summary["episodes"]) == sorted(keys)
    text = dive(runtime, "log", "info", str(out))
    assert re.search(r"-- chapter \d \(boot 1, generation 2\): the learner restarted", text.stdout), text.stdout

    tables = tmp_path / "tables"
    exported = dive(runtime, "log", "export", str(out), "--format", "parquet", "--out", str(tables), timeout=120)
    assert exported.returncode == 0, exported.stderr
    import pyarrow.parquet as pq

    parquet = pq.read_table(tables / "episodes").to_pydict()
    assert sorted(zip(parquet["boot"], parquet["generation"], parquet["episode"], strict=True)) == sorted(keys)
    assert set(pq.read_table(tables / "samples", columns=["generation"]).to_pydict()["generation"]) == {1, 2}

    npz = tmp_path / "transitions.npz"
    assert dive(runtime, "log", "export", str(out), "--format", "npz", "--out", str(npz)).returncode == 0
    with np.load(npz) as data:
        in_npz = set(zip(data["boot"].tolist(), data["generation"].tolist(), data["episode"].tolist(), strict=True))
        steps = {k: int(s) for k, s in zip(keys, (e["steps"] for e in sent), strict=True)}
        for key in in_npz:  # never two chapters' episodes merged into one
            mine = (data["generation"] == key[1]) & (data["episode"] == key[2])
            assert int(mine.sum()) <= steps[key], key
    assert in_npz <= set(keys) and {k[1] for k in in_npz} == {1, 2}

    import minari

    datasets = tmp_path / "datasets"
    env = {**dive_env(runtime), "MINARI_DATASETS_PATH": str(datasets)}
    exported = subprocess.run([*DIVE, "log", "export", str(out), "--format", "minari", "--out", str(datasets)],
                              env=env, capture_output=True, text=True, timeout=120)
    assert exported.returncode == 0, exported.stderr
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(datasets))
    (dataset_id,) = minari.list_local_datasets(str(datasets))
    seen = []
    for episode in minari.load_dataset(dataset_id).iterate_episodes():
        chapter = {(b, g, e) for b, g, e in zip(episode.infos["boot"], episode.infos["generation"],
                                                episode.infos["episode"], strict=True)}
        assert len(chapter) == 1  # one episode of one chapter, never merged across the restart
        seen.extend(chapter)
    assert len(seen) == len(set(seen)) and set(seen) <= set(keys) and {k[1] for k in seen} == {1, 2}

