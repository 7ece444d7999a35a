"""A study's CPU per trial-episode and its results' digest, run in a child process on a given source tree: today's
or an older commit's whole tree (git archive into a fresh folder, its own numba cache), so the anchor's every
kernel (plant, trial loop, planning) is that commit's own."""

from __future__ import annotations

import atexit
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# Run in the child: a small study to compile or load the cache, then the timed one; prints a JSON line.
_CHILD = """
import hashlib, json, sys, time
from learning import learner_preset
from simulator.parameters import preset
from simulator.study.runner import run_study
preset_name, learner, trials, episodes, seed, threads = sys.argv[1:7]
params, config = preset(preset_name), learner_preset(learner)
run_study(params, config, 2, 2, int(seed), threads=int(threads))
start = time.process_time()
result = run_study(params, config, int(trials), int(episodes), int(seed), threads=int(threads))
cpu_s = time.process_time() - start
digest = hashlib.sha256()
for array in (result.durations_s, result.values, result.policy, result.hold, result.counters, result.recovery_hold):
    digest.update(array.tobytes())
print(json.dumps({"cpu_ms": cpu_s / (int(trials) * int(episodes)) * 1e3, "digest": digest.hexdigest()}))
"""


def source_tree(commit: str) -> Path:
    """Today's tree for '' (this checkout), else the commit's files in a fresh folder removed at exit."""
    if not commit:
        return ROOT
    folder = Path(tempfile.mkdtemp(prefix=f"study-anchor-{commit}-"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    try:
        archive = subprocess.run(["git", "archive", commit], cwd=ROOT, check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(folder)], input=archive, check=True, capture_output=True)
    except (OSError, subprocess.CalledProcessError) as e:
        raise SystemExit(f"cannot extract {commit} (a git checkout with that commit is needed): {e}") from e
    return folder


def study_cpu(tree: Path, preset_name: str, learner: str, trials: int, episodes: int, seed: int,
              threads: int) -> tuple[float, str]:
    """(CPU ms per trial-episode, digest of every per-trial array) of the study run on tree's code."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    if tree != ROOT:
        env["NUMBA_CACHE_DIR"] = str(tree / ".numba-cache")  # the anchor's kernels never meet today's
    args = [preset_name, learner, str(trials), str(episodes), str(seed), str(threads)]
    try:
        done = subprocess.run([sys.executable, "-c", _CHILD, *args], cwd=tree, env=env, check=True,
                              capture_output=True, text=True)
    except subprocess.CalledProcessError as e:
        last = (e.stderr.strip().splitlines() or ["no message"])[-1]
        raise SystemExit(f"the study on {tree} failed: {last}") from e
    answer = json.loads(done.stdout.strip().splitlines()[-1])
    return float(answer["cpu_ms"]), str(answer["digest"])
