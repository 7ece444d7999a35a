"""`dive log info` over recordings: the indexed, columnar summary vs reading every message with the mcap library.

    .venv/bin/python benchmarks/loginfo_bench.py [FILE|FOLDER ...] [--episodes 40] [--files 2] [--repeat 3]

Without recordings given it makes its own: `--files` recordings of `dive run --preset hardware --speed max
--episodes N --viewer none` (the virtual agent with the hardware plant, learning at full speed). Prints, per file
and in all, MB of file per CPU second of this process (per core: the load of other processes does not count) of
summarize() (what `dive log info` does for each file) and of the anchor, the mcap library's reader iterating
every message of the same files without decoding them; then the ratio. Also the wall time of the whole folder
through summarize_files (worker processes where it pays). Goals (issue 28): >= 50 MB/s per core, ratio >= 5.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mcap.reader import make_reader

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from groundstation.recording.files import expand  # noqa: E402
from groundstation.recording.info import summarize  # noqa: E402
from groundstation.recording.summaries import summarize_files, workers  # noqa: E402

_DIVE = "import sys; sys.argv[0] = 'dive'; from groundstation.cli.app import main; main()"


def make_recordings(folder: Path, files: int, episodes: int) -> list[Path]:
    """Hardware-preset runs of the virtual agent at full speed, recorded by `dive run` (a real run each)."""
    made = []
    env = {**os.environ, "DIVE_RUNTIME_DIR": str(folder / "runtime")}
    for i in range(files):
        out = folder / f"hardware-{i + 1}.mcap"
        print(f"recording {out.name}: dive run --preset hardware --speed max --episodes {episodes} --seed {i + 1}",
              flush=True)
        subprocess.run([sys.executable, "-c", _DIVE, "run", "--preset", "hardware", "--speed",
                        "max", "--episodes", str(episodes), "--seed", str(i + 1), "--viewer", "none",
                        "--out", str(out)], check=True, env=env, stdout=subprocess.DEVNULL)
        made.append(out)
    return made


def cpu_seconds(work: object, repeat: int) -> float:
    """The least CPU time of this process over `repeat` runs of work() (the least disturbed by the machine)."""
    best = float("inf")
    for _ in range(repeat):
        cpu = time.process_time()
        work()  # type: ignore[operator]
        best = min(best, time.process_time() - cpu)
    return best


def anchor(path: Path) -> int:
    with path.open("rb") as f:
        return sum(1 for _ in make_reader(f).iter_messages(log_time_order=False))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("paths", nargs="*", type=Path)
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--files", type=int, default=2)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="loginfo-bench-") as tmp:
        files = expand(args.paths) if args.paths else make_recordings(Path(tmp), args.files, args.episodes)
        summarize(files[0])  # imports and first-use costs outside the measurement
        total_mb = ours_s = anchor_s = 0.0
        for path in files:
            mb = path.stat().st_size / 1e6
            ours = cpu_seconds(lambda p=path: summarize(p), args.repeat)
            theirs = cpu_seconds(lambda p=path: anchor(p), args.repeat)
            total_mb, ours_s, anchor_s = total_mb + mb, ours_s + ours, anchor_s + theirs
            print(f"{path.name}: {mb:.1f} MB  summary {mb / ours:.1f} MB/s per core  "
                  f"anchor (mcap reader, every message) {mb / theirs:.1f} MB/s  ratio {theirs / ours:.1f}x")
        began = time.perf_counter()
        summarize_files(files)
        wall_s = time.perf_counter() - began
        load = os.getloadavg()[0]
        print(f"all {len(files)} files, {total_mb:.1f} MB: summary {total_mb / ours_s:.1f} MB/s per core, "
              f"anchor {total_mb / anchor_s:.1f} MB/s per core, ratio {anchor_s / ours_s:.1f}x "
              "(goals: >= 50 MB/s per core, >= 5x)")
        print(f"folder through summarize_files: {wall_s:.2f} s wall on {workers()} core(s), load average {load:.1f}")


if __name__ == "__main__":
    main()
