"""The columnar conversion of a recording gives the rows, values and timelines of the per-frame conversion."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from groundstation.mcap_io import RecordingContents
from groundstation.view import replay_convert as replay
from groundstation.view.model import Batch
from groundstation.view.replay_items import read_items
from tests.groundstation.synthetic_agent import generate, record


def _same(a: Batch, b: Batch) -> None:
    assert sorted(a) == sorted(b)
    for path in a:
        left, right = a[path], b[path]
        assert left.agent_time_s == right.agent_time_s, path
        assert left.host_time_ns == right.host_time_ns, path
        assert left.episode == right.episode, path
        assert left.step == right.step, path
        assert len(left.values) == len(right.values), path
        for x, y in zip(left.values, right.values, strict=True):
            if isinstance(x, np.ndarray):
                assert np.array_equal(x, y), path
            elif isinstance(x, tuple) and isinstance(x[0], np.ndarray):  # a learning curve: (episodes, durations)
                assert len(x) == len(y) and all(np.array_equal(u, v) for u, v in zip(x, y, strict=True)), path
            else:
                assert x == y and type(x) is type(y), path


@pytest.mark.parametrize("backfill_every", [0, 7])
def test_columnar_conversion_matches_the_per_frame_one(tmp_path: Path, backfill_every: int) -> None:
    path = record(generate(duration_s=240.0, rate_hz=40.0, backfill_every=backfill_every), tmp_path / "r.mcap")
    expected, expected_count = replay.convert(read_items(path, RecordingContents()))
    got, count = replay.convert_recording(path, RecordingContents())
    assert count == expected_count
    _same(got, expected)


def test_damaged_frames_are_skipped_alike(tmp_path: Path) -> None:
    path = record(generate(duration_s=120.0, rate_hz=40.0), tmp_path / "r.mcap")
    data = bytearray(path.read_bytes())
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(bytes(data[: len(data) * 2 // 3]))  # truncated: what was complete is shown
    expected, expected_count = replay.convert(read_items(cut, RecordingContents()))
    got, count = replay.convert_recording(cut, RecordingContents())
    assert count == expected_count > 0
    _same(got, expected)
