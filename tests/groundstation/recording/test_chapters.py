"""A learner restart in a recording (issue 39): a new chapter in every data path, read from the wire (SPEC 1.3) or
inferred from what a 1.2 agent's recording shows (its TEXT, its episode numbers going back), and said so.

Real recordings: the virtual agent's program (Python, or the C firmware's host build) stepped in-process into the
real recorder, a pause, a learner parameter set and a start in the middle, as on a tank day.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from groundstation.recording.chapters import wire_generation
from groundstation.recording.info import format_summary, summarize, summarize_stream
from groundstation.recording.tables import open_recording
from protocol import Mode
from tests.groundstation.recording.onboard_recording import record_onboard

CASES = {  # firmware, as a 1.2 agent, its restart TEXT kept
    "python 1.3": ("python", False, True),
    "c 1.3": ("c", False, True),
    "1.2, its TEXT": ("python", True, True),
    "1.2, episode numbers only": ("c", True, False),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_restart_is_a_chapter_in_every_reading(case: str, tmp_path: Path) -> None:
    firmware, as_1_2, text = CASES[case]
    (path,) = record_onboard(tmp_path / "tank.mcap", "paper", firmware, seed=3, episodes=5, restart_after=2,
                             as_1_2=as_1_2, restart_text=text)
    rec = open_recording(path)
    episodes = rec.episodes()
    keys = list(zip(episodes["boot"].tolist(), episodes["generation"].tolist(), episodes["episode"].tolist(),
                    strict=True))
    # every EPISODE_END once: the second learner's episodes 1, 2 ... beside the first's, none dropped or merged
    # (the recording may stop inside the next episode: its row is "open")
    assert len(set(keys)) == len(keys)
    assert int(np.sum(episodes["outcome"] != "open")) == len(list(rec.messages({"/agent/EPISODE_END"})))
    assert {g for _, g, _ in keys} == {1, 2} and (1, 2, 1) in keys and (1, 1, 1) in keys
    (restart,) = rec.restarts
    assert restart.generation == 2 and restart.inferred == as_1_2
    # each learning sample joins exactly one episode on (boot, generation, episode): no row inflated, none lost
    samples = rec.samples()
    learning = samples[samples["mode"] == int(Mode.LEARNING)]
    joined = sum(int(np.sum((learning["generation"] == g) & (learning["episode"] == e))) for _, g, e in keys)
    assert joined == len(learning)
    # dive log info, both readers alike: per-chapter figures and a chapter line that says whether it was inferred
    indexed, stream = summarize(path), summarize_stream(path)
    assert indexed.chapters == stream.chapters
    assert [(c.generation, c.episodes) for c in indexed.chapters] == \
        [(g, int(np.sum((episodes["generation"] == g) & (episodes["outcome"] != "open")))) for g in (1, 2)]
    text_out = format_summary(indexed)
    assert "-- chapter 2 (boot 1, generation 2): the learner restarted" in text_out
    assert ("inferred: the recording carries no generation" in text_out) == as_1_2


def test_a_message_without_the_field_or_with_0_carries_no_generation() -> None:
    """An old recording's JSON has no `generation`; a 1.2 agent recorded by a 1.3 ground has 0: both are inferred."""
    assert wire_generation({"episode": 3}) == wire_generation({"generation": 0}) == 0
    assert wire_generation({"generation": 2}) == 2 and wire_generation({"generation": True}) == 0


def test_replay_names_a_chapter_and_its_curves_start_afresh(tmp_path: Path) -> None:
    """`dive replay --from 2:1 --to 2:2`: chapter 2's episodes 1-2, not the first learner's; the view's learning
    curves restart at the chapter (the by-episode bars never hold two learners' episode 1) and its log says so."""
    from groundstation.view.replay_convert import convert
    from groundstation.view.replay_items import read_items
    from groundstation.view.replay_window import parse_bound, select
    from protocol import messages as m

    (path,) = record_onboard(tmp_path / "tank.mcap", "paper", "python", seed=3, episodes=5, restart_after=2)
    ends: list[tuple[int, int]] = []

    class Spy:
        def feed(self, message: object, *_: object, **__: object) -> None:
            if isinstance(message, m.EpisodeEnd):
                ends.append((message.generation, message.episode))

    for item in select(read_items(path), parse_bound("2:1"), parse_bound("2:2")):
        if not item.before:  # what comes before the window only sets the state it opens on (dumps, curve)
            item.feed(Spy())  # type: ignore[arg-type]
    assert ends == [(2, 1), (2, 2)]
    batch, _ = convert(read_items(path))
    texts = [text for text, _level in batch["log/events"].values]
    assert sum("the learner restarted (generation 2)" in text for text in texts) == 1
    bars_episodes, _durations = batch["learning_curve_by_episode/duration_s"].values[-1]
    assert list(bars_episodes) == sorted(set(bars_episodes))  # one learner's episodes, each once
