"""The study's trial kernels with an older commit's planning (learning/planning.py and shared.py from git): the
anchor a benchmark measures in the same run as today's."""

from __future__ import annotations

import atexit
import importlib
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parent.parent


def _git_show(commit: str, path: str) -> str:
    try:
        return subprocess.run(["git", "show", f"{commit}:{path}"], cwd=ROOT, check=True, capture_output=True,
                              text=True).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        raise SystemExit(f"cannot read {path} at {commit} (a git checkout with that commit is needed): {e}") from e


def anchor_kernels(commit: str) -> tuple[ModuleType, Path]:
    """Today's simulator/study/kernel.py, its planning calls bound to the commit's planning modules; and the
    folder that holds the copies (a fresh one, removed at exit: numba's cache never mixes them with today's)."""
    folder = Path(tempfile.mkdtemp(prefix=f"study-anchor-{commit}-"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    tag = f"_anchor_{commit}"
    (folder / f"{tag}_planning.py").write_text(_git_show(commit, "learning/planning.py"))
    shared = _git_show(commit, "learning/shared.py").replace("from learning.planning import",
                                                             f"from {tag}_planning import")
    (folder / f"{tag}_shared.py").write_text(shared)
    (folder / f"{tag}_kernel.py").write_text((ROOT / "simulator" / "study" / "kernel.py").read_text())
    sys.path.insert(0, str(folder))
    kernel = importlib.import_module(f"{tag}_kernel")
    # numba reads a kernel's globals when it first compiles it: rebound here, before any call.
    kernel.plan_kernel = importlib.import_module(f"{tag}_planning").plan_kernel
    kernel.plan_shared_kernel = importlib.import_module(f"{tag}_shared").plan_shared_kernel
    return kernel, folder

