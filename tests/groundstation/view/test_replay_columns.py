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


def test_a_viewer_fed_in_slices_gets_the_rows_of_one_batch(tmp_path: Path) -> None:
    """`dive replay` hands the viewer the first minutes while it converts the rest: the slices, joined, are the
    one batch, in order, the first one small."""
    from groundstation.recording.files import group_recordings
    from groundstation.view.model import Rows

    path = record(generate(duration_s=900.0, rate_hz=40.0), tmp_path / "r.mcap")
    (parts,) = group_recordings([path])
    whole, count = replay.convert_parts(parts, [RecordingContents()])
    slices: list[Batch] = []
    last, sliced_count = replay.convert_parts(parts, [RecordingContents()], sink=slices.append)
    assert sliced_count == count and len(slices) >= 3
    assert len(slices[0]["depth/z_up_m"]) < len(whole["depth/z_up_m"]) // 4  # the first slice comes early
    joined: Batch = {}
    for batch in [*slices, last]:
        for entity, rows in batch.items():
            into = joined.setdefault(entity, Rows())
            for name in ("agent_time_s", "host_time_ns", "episode", "step", "values"):
                getattr(into, name).extend(getattr(rows, name))
    _same({k: v for k, v in joined.items() if v.values}, {k: v for k, v in whole.items() if v.values})


@pytest.mark.parametrize("bound", ["5", "60s"])
def test_a_window_opens_on_the_state_every_sample_before_it_leaves(tmp_path: Path, bound: str) -> None:
    """convert() feeds only the last SAMPLE before each other item ahead of a window: what the window shows (its
    rows, the heatmaps and curve it opens on, the count of backfilled samples) is what feeding every one gave."""
    from groundstation.view.model import ViewModel
    from groundstation.view.replay_window import parse_bound, select

    path = record(generate(duration_s=240.0, rate_hz=40.0, backfill_every=7), tmp_path / "r.mcap")
    reference = ViewModel()
    fed_before, count = False, 0
    for item in select(read_items(path, RecordingContents()), parse_bound(bound), None):
        if not item.before and fed_before:
            reference.keep_state()
            fed_before = False
        fed_before = fed_before or item.before
        item.feed(reference)  # every item, as convert() did before
        count += not item.before
    got, got_count = replay.convert(select(read_items(path, RecordingContents()), parse_bound(bound), None))
    expected = reference.take()
    assert got_count == count > 0 and "link/backfilled_samples" in expected
    _same(got, expected)
