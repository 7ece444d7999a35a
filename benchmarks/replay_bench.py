"""Converting a one-hour recording (10 Hz, 36,000 samples, episodes, dumps) to .rrd: columns vs one rr.log per row.

    .venv/bin/python benchmarks/replay_bench.py [--hours 1]

Prints wall time and samples/s of `dive replay FILE --rrd OUT` (read MCAP, decode, columnar send_columns) and,
in the same run, of the anchor: the same rows logged one `rr.log` call at a time; then the ratio.
Goal: ratio >= 10 and the one-hour file converted in under 3 s.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np
import rerun as rr

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from groundstation import replay  # noqa: E402
from groundstation.mcap_io import RecordingContents  # noqa: E402
from groundstation.rerun_view import new_recording, send_batch, send_styles  # noqa: E402
from groundstation.view_model import ENTITIES, Batch, Kind  # noqa: E402
from tests.groundstation.synthetic_agent import generate, record  # noqa: E402


def convert_columns(mcap: Path, rrd: Path) -> tuple[float, int]:
    """What `dive replay FILE --rrd OUT` does."""
    began = time.perf_counter()
    batch, _ = replay.convert(replay.read_items(mcap, RecordingContents()))
    rec = new_recording("bench")
    rec.save(rrd)
    send_styles(rec)
    send_batch(rec, batch)
    rec.flush()
    rec.disconnect()
    return time.perf_counter() - began, len(batch["depth/depth_m"])


def convert_rows(mcap: Path, rrd: Path) -> tuple[float, int]:
    """The anchor: the same rows, one rr.log call each (time set per row)."""
    began = time.perf_counter()
    batch: Batch
    batch, _ = replay.convert(replay.read_items(mcap, RecordingContents()))
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
            else:
                rec.log(path, rr.Image(value, color_model="RGB"))
    rec.flush()
    rec.disconnect()
    return time.perf_counter() - began, len(batch["depth/depth_m"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=1.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        began = time.perf_counter()
        traffic = generate(duration_s=args.hours * 3600.0)
        mcap = record(traffic, directory / "hour.mcap")
        print(f"generated {mcap.stat().st_size / 1e6:.1f} MB MCAP: {traffic.samples} samples, "
              f"{len(traffic.frames)} frames in {time.perf_counter() - began:.1f} s (recorded by Recorder)")
        columns_s, samples = convert_columns(mcap, directory / "columns.rrd")
        rows_s, samples_rows = convert_rows(mcap, directory / "rows.rrd")
        assert samples == samples_rows == traffic.samples
        print(f"columnar (dive replay --rrd): {columns_s:6.2f} s  {samples / columns_s:10,.0f} samples/s  "
              f"{(directory / 'columns.rrd').stat().st_size / 1e6:.1f} MB")
        print(f"one rr.log per row (anchor):  {rows_s:6.2f} s  {samples / rows_s:10,.0f} samples/s  "
              f"{(directory / 'rows.rrd').stat().st_size / 1e6:.1f} MB")
        print(f"ratio: columnar is {rows_s / columns_s:.1f}x faster (goal >= 10x); "
              f"{args.hours:g} h converted in {columns_s:.2f} s (goal < 3 s for 1 h)")


if __name__ == "__main__":
    main()
