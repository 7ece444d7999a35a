"""`dive log info` over recordings: the indexed, columnar summary vs reading every message with the mcap library.

    .venv/bin/python benchmarks/loginfo_bench.py [FILE|FOLDER ...] [--episodes 40] [--files 2] [--repeat 3]
    .venv/bin/python benchmarks/loginfo_bench.py --folder DIR [--folder-mb 280] [--repeat 3]

Without recordings given it makes its own: `--files` recordings of `dive run --preset hardware --speed max
--episodes N --viewer none` (the virtual agent with the hardware plant, learning at full speed). Prints, per file
and in all, MB of file per CPU second of this process (per core: the load of other processes does not count) of
summarize() (what `dive log info` does for each file) and of the anchor, the mcap library's reader iterating
every message of the same files without decoding them; then the ratio. Also the wall time of the whole folder
through summarize_files (worker processes where it pays). Goals (issue 28): >= 50 MB/s per core, ratio >= 5.

--folder DIR: the issue's folder, made in DIR when it holds no recording (kept for the next run; never commit it):
16 files, about --folder-mb MB, of the virtual agent's on-board programs over their plants stepped in-process
(tests/groundstation/recording/onboard_recording.py: the real program, plant and recorder, no socket, so the
folder takes minutes, not the hour `dive run` needs on a loaded machine): hardware and paper presets, the C
firmware's host build on both plants, and one recording split into 4 parts by the recorder's split option. Then
the wall time of `dive log info DIR --json` as a user runs it (a new process: start-up included), best of
--repeat, next to the anchor: the mcap library reading every message of the same files in this process. Goal
(issue 28): under 10 s.
"""

from __future__ import annotations

import argparse
import os
import resource
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


# The folder: (name, preset, on-board program, seed, parts); 12 whole recordings and one of 4 parts.
FOLDER_PLAN = ([(f"hardware-{i}", "hardware", "python", i, 1) for i in range(1, 7)]
               + [(f"paper-{i}", "paper", "python", i, 1) for i in range(1, 4)]
               + [("firmware-paper-1", "paper", "c", 1, 1), ("firmware-paper-2", "paper", "c", 2, 1),
                  ("firmware-hardware-1", "hardware", "c", 3, 1), ("hardware-split", "hardware", "python", 7, 4)])


def make_folder(folder: Path, total_mb: float) -> list[Path]:
    """FOLDER_PLAN's recordings in `folder`, each part about total_mb / 16 MB."""
    from tests.groundstation.recording.onboard_recording import record_onboard

    part_bytes = int(total_mb * 1e6 / sum(parts for *_, parts in FOLDER_PLAN))
    folder.mkdir(parents=True, exist_ok=True)
    made: list[Path] = []
    for name, preset_name, program, seed, parts in FOLDER_PLAN:
        began = time.perf_counter()
        made += record_onboard(folder / f"{name}.mcap", preset_name, program, seed, episodes=10**9,
                               max_steps=10**9, until_bytes=int(part_bytes * (parts - 0.1)),
                               split_bytes=part_bytes if parts > 1 else 0, dumps=True)
        print(f"recorded {name} ({preset_name} plant, {program} program, {parts} part(s)) in "
              f"{time.perf_counter() - began:.1f} s", flush=True)
    return made


def folder_info(folder: Path, total_mb: float, repeat: int) -> None:
    """`dive log info FOLDER --json` on the issue's folder (made if missing), timed next to the anchor."""
    files = expand([folder]) if folder.is_dir() and any(folder.glob("*.mcap")) else make_folder(folder, total_mb)
    size_mb = sum(p.stat().st_size for p in files) / 1e6
    times, cpus = [], []
    for _ in range(repeat):
        began, used = time.perf_counter(), _children_cpu_s()
        done = subprocess.run([sys.executable, "-c", _DIVE, "log", "info", str(folder), "--json"],
                              capture_output=True, text=True)
        times.append(time.perf_counter() - began)
        cpus.append(_children_cpu_s() - used)  # the command and its worker processes: what load does not change
        if done.returncode != 0:
            sys.exit(f"dive log info failed ({done.returncode}): {done.stderr.strip()}")
    anchors = []
    for _ in range(repeat):
        began = time.perf_counter()
        messages = sum(anchor(path) for path in files)
        anchors.append(time.perf_counter() - began)
    ours, theirs = min(times), min(anchors)
    print(f"{len(files)} files, {size_mb:.0f} MB, {messages} messages in {folder}")
    print(f"dive log info FOLDER --json: {ours:.2f} s wall (runs: {', '.join(f'{t:.2f}' for t in times)}; goal "
          f"< 10 s), {min(cpus):.2f} s CPU with its workers; anchor (mcap reader, every message): {theirs:.2f} s; "
          f"ratio {theirs / ours:.1f}x; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


def _children_cpu_s() -> float:
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    return used.ru_utime + used.ru_stime


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
    parser.add_argument("--folder", type=Path, help="time dive log info on the issue's folder (made here if empty)")
    parser.add_argument("--folder-mb", type=float, default=280.0)
    args = parser.parse_args()
    if args.folder is not None:
        folder_info(args.folder, args.folder_mb, args.repeat)
        return
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
