"""Converting a one-hour recording to .rrd: columns vs one rr.log per row.

    .venv/bin/python benchmarks/replay_bench.py [--hours 1] [--source hardware|synthetic]

The recording: `hardware` (default) is one hour of agent time of the virtual agent with the hardware preset,
learning at --speed max, recorded by the ground station (~133,000 samples: 40 Hz while recovering); `synthetic`
is the generated 10 Hz hour (36,000 samples, episodes, dumps). Prints wall time and samples/s of
`dive replay FILE --rrd OUT` (read MCAP, decode, columnar send_columns) and, in the same run, of the anchor:
the same rows logged one `rr.log` call at a time; then the ratio. Goals: ratio >= 10, and the hardware hour
converted in under 2 s (issue 16).
"""

from __future__ import annotations

import argparse
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np
import rerun as rr

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from groundstation.links import make_link  # noqa: E402
from groundstation.mcap_io import RecordingContents, iter_messages  # noqa: E402
from groundstation.recording.files import group_recordings  # noqa: E402
from groundstation.recording.recorder import Recorder, RecorderConfig  # noqa: E402
from groundstation.session.agent_session import Session, SessionConfig  # noqa: E402
from groundstation.session.events import Received  # noqa: E402
from groundstation.view import replay_convert as replay  # noqa: E402
from groundstation.view.model import ENTITIES, Batch, Kind  # noqa: E402
from groundstation.view.replay_items import read_items  # noqa: E402
from groundstation.view.rerun_sink import log_frame, new_recording, send_batch, send_styles  # noqa: E402
from protocol import Mode  # noqa: E402
from protocol import messages as m  # noqa: E402
from tests.groundstation.synthetic_agent import generate, record  # noqa: E402


def convert_columns(mcap: Path, rrd: Path) -> tuple[float, int]:
    """What `dive replay FILE --rrd OUT` does."""
    global columns_cpu_s
    began, cpu = time.perf_counter(), time.process_time()
    batch, _ = replay.convert_recording(mcap, RecordingContents())
    rec = new_recording("bench")
    rec.save(rrd)
    send_styles(rec)
    send_batch(rec, batch)
    rec.flush()
    rec.disconnect()
    columns_cpu_s = time.process_time() - cpu
    return time.perf_counter() - began, len(batch["depth/z_up_m"])


columns_cpu_s = 0.0  # CPU seconds of the last convert_columns (this process; rerun's threads included)


def first_data(mcap: Path, rrd: Path) -> tuple[float, float, float]:
    """`dive replay` as it feeds a viewer now: the rows in slices (replay_convert.convert_parts with a sink).
    Seconds until the first slice was logged, until all was, and the CPU seconds of it all."""
    began, cpu = time.perf_counter(), time.process_time()
    first: list[float] = []
    rec = new_recording("bench")
    rec.save(rrd)
    send_styles(rec)

    def sink(batch: Batch) -> None:
        send_batch(rec, batch)
        if not first:
            first.append(time.perf_counter() - began)

    (parts,) = group_recordings([mcap])
    batch, _ = replay.convert_parts(parts, [RecordingContents()], sink=sink)
    send_batch(rec, batch)
    rec.flush()
    rec.disconnect()
    return first[0], time.perf_counter() - began, time.process_time() - cpu


def cli_replay(mcap: Path, rrd: Path) -> tuple[float, float]:
    """`dive replay FILE --rrd OUT` as a user runs it, imports included: wall and CPU seconds (user + system)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    began = time.perf_counter()
    subprocess.run([sys.executable, "-m", "groundstation.cli.app", "replay", str(mcap), "--rrd", str(rrd)],
                   check=True, capture_output=True)
    wall = time.perf_counter() - began
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime


def convert_rows(mcap: Path, rrd: Path) -> tuple[float, int]:
    """The anchor: the same rows, one rr.log call each (time set per row)."""
    began = time.perf_counter()
    batch: Batch
    batch, _ = replay.convert(read_items(mcap, RecordingContents()))
    rec = rr.RecordingStream("diving_agent", recording_id=uuid.uuid4())
    rec.save(rrd)
    send_styles(rec)
    for path, rows in batch.items():
        kind = ENTITIES[path][0]
        for i, value in enumerate(rows.values):
            rec.set_time("agent_time", duration=rows.agent_time_s[i])
            rec.set_time("host_time", timestamp=np.datetime64(rows.host_time_ns[i], "ns"))
            rec.set_time("episode", sequence=rows.episode[i])
            rec.set_time("step", sequence=rows.step[i])
            if kind in (Kind.SCALAR, Kind.POINT):
                rec.log(path, rr.Scalars(value))
            elif kind == Kind.TEXT:
                rec.log(path, rr.TextLog(value[0], level=value[1]))
            elif kind == Kind.BOX:
                rec.log(path, rr.Boxes2D(centers=[value[:2]], half_sizes=[(0.5, 0.5)], labels=[value[2]]))
            elif kind == Kind.FRAME:
                log_frame(rec, path, value)  # logged row by row by the view too
            elif kind == Kind.BARS:
                rec.log(path, rr.BarChart(value[1], abscissa=value[0]))
            else:
                rec.log(path, rr.Image(value, color_model="RGB"))
    rec.flush()
    rec.disconnect()
    return time.perf_counter() - began, len(batch["depth/z_up_m"])


class _AgentClock:
    """Session listener: the agent time of the newest SAMPLE, from the first one out of IDLE."""

    def __init__(self) -> None:
        self.first_s: float | None = None
        self.agent_s = 0.0

    def on_received(self, received: Received) -> None:
        # The hour counts from the first SAMPLE out of IDLE: before CMD_START the agent idles at --speed max,
        # one SAMPLE per agent second, for as long as the handshake takes in wall time.
        sample = received.message
        if isinstance(sample, m.Sample) and (self.first_s is not None or sample.mode != Mode.IDLE):
            self.agent_s = max(self.agent_s, sample.t_us / 1e6)
            self.first_s = self.agent_s if self.first_s is None else self.first_s

    def on_sent(self, sent: object) -> None:
        pass

    def on_event(self, event: object) -> None:
        pass


def record_hardware(path: Path, hours: float, seed: int = 1) -> int:
    """`hours` of agent time of the virtual agent (hardware preset, learning, --speed max) recorded by the
    ground station's Session and Recorder, as `dive run` records it; returns the SAMPLEs in the file."""
    agent = subprocess.Popen([sys.executable, "-m", "simulator", "serve", "--tcp", "127.0.0.1:0", "--speed", "max",
                              "--seed", str(seed), "--preset", "hardware"], stdout=subprocess.PIPE, text=True)
    recorder = Recorder(RecorderConfig(path=path))
    clock = _AgentClock()
    try:
        assert agent.stdout is not None
        with Session(make_link(agent.stdout.readline().strip()), SessionConfig(fetch_params=False),
                     [recorder, clock]) as session:
            session.command(m.StartLearning(max_episodes=0))
            while clock.first_s is None or clock.agent_s - clock.first_s < hours * 3600.0:
                time.sleep(0.05)
    finally:
        recorder.close()
        agent.send_signal(signal.SIGTERM)
        agent.wait(30)
    return sum(1 for _ in iter_messages(path, {"/agent/SAMPLE"}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=1.0)
    parser.add_argument("--source", choices=("hardware", "synthetic"), default="hardware")
    parser.add_argument("--keep", type=Path, help="also copy the generated recording here")
    parser.add_argument("--recording", type=Path, help="convert this recording instead of making one")
    parser.add_argument("--rounds", type=int, default=3, help="conversions of the columnar path (median shown)")
    parser.add_argument("--no-anchor", action="store_true",
                        help="skip the one-rr.log-per-row anchor (it takes minutes on a loaded machine)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        began = time.perf_counter()
        mcap = directory / "hour.mcap"
        if args.recording is not None:
            shutil.copy(args.recording, mcap)
            expected = sum(1 for _ in iter_messages(mcap, {"/agent/SAMPLE"}))
        elif args.source == "hardware":
            expected = record_hardware(mcap, args.hours)
        else:
            traffic = generate(duration_s=args.hours * 3600.0)
            record(traffic, mcap)
            expected = traffic.samples
        if args.keep is not None:
            shutil.copy(mcap, args.keep)
        source = args.recording or args.source
        print(f"{source}: {mcap.stat().st_size / 1e6:.1f} MB MCAP, {expected} samples, "
              f"ready in {time.perf_counter() - began:.1f} s")
        runs = []
        for _ in range(args.rounds):
            columns_s, samples = convert_columns(mcap, directory / "columns.rrd")
            runs.append((columns_s, columns_cpu_s))
            assert samples == expected, (samples, expected)
        columns_s, cpu_s = sorted(runs)[len(runs) // 2]
        print(f"columnar (dive replay --rrd): {columns_s:6.2f} s wall (median of {len(runs)}: "
              f"{', '.join(f'{w:.2f}' for w, _ in runs)}), {cpu_s:.2f} s CPU, {samples / columns_s:10,.0f} samples/s, "
              f"{(directory / 'columns.rrd').stat().st_size / 1e6:.1f} MB")
        sliced = sorted(first_data(mcap, directory / f"sliced{i}.rrd") for i in range(args.rounds))[len(runs) // 2]
        print(f"sliced (dive replay now): first data logged after {sliced[0]:.2f} s wall, all after {sliced[1]:.2f} s, "
              f"{sliced[2]:.2f} s CPU; one batch: first data = all, after {columns_s:.2f} s: "
              f"{columns_s / sliced[0]:.1f}x sooner")
        cli = sorted(cli_replay(mcap, directory / f"cli{i}.rrd") for i in range(args.rounds))[len(runs) // 2]
        print(f"dive replay FILE --rrd OUT, imports included: {cli[0]:.2f} s wall, {cli[1]:.2f} s CPU "
              f"(median of {args.rounds})")
        if not args.no_anchor:
            rows_s, samples_rows = convert_rows(mcap, directory / "rows.rrd")
            assert samples_rows == expected
            print(f"one rr.log per row (anchor):  {rows_s:6.2f} s wall, {samples / rows_s:10,.0f} samples/s, "
                  f"{(directory / 'rows.rrd').stat().st_size / 1e6:.1f} MB")
            print(f"ratio: columnar is {rows_s / columns_s:.1f}x faster (goal >= 10x)")
        print(f"{args.hours:g} h ({samples} samples) converted in {columns_s:.2f} s wall, {cpu_s:.2f} s CPU "
              f"(goal < 2 s for the hardware hour)")


if __name__ == "__main__":
    main()
