"""Backfill planning: which on-board log ranges bring back lost samples and lost episode frames."""

from __future__ import annotations

from groundstation.gaps import BackfillPlanner


def _learning_episode(planner: BackfillPlanner, episode: int, samples: range, *, start: bool, end: bool) -> None:
    if start:
        planner.episodes.starts.add(episode)
    for index in samples:
        planner.held.add(index)
        planner.episodes.saw_sample(index, episode, learning=True)
    if end:
        planner.episodes.ends.add(episode)


def _recovery(planner: BackfillPlanner, episode: int, samples: range) -> None:
    for index in samples:
        planner.held.add(index)
        planner.episodes.saw_sample(index, episode, learning=False)


def test_a_lost_episode_end_is_requested_by_the_index_of_its_last_sample() -> None:
    planner = BackfillPlanner()
    _learning_episode(planner, 1, range(10, 40), start=True, end=False)  # EPISODE_END 1 (sample 39) was lost
    assert not planner.pending()  # nothing after it yet: it may still be on its way
    _recovery(planner, 1, range(40, 45))
    assert planner.missing() == []  # no SAMPLE is missing ...
    assert planner.pending()  # ... but the episode frame is
    assert planner.due(now_s=0.0) == [(39, 40)]


def test_a_lost_episode_start_is_requested_by_the_index_of_its_first_sample() -> None:
    planner = BackfillPlanner()
    _learning_episode(planner, 4, range(100, 120), start=False, end=True)
    assert planner.due(now_s=0.0) == [(100, 101)]


def test_complete_episodes_need_nothing_and_requests_are_retried_then_given_up() -> None:
    planner = BackfillPlanner(retry_after_s=1.0, attempts=2)
    _learning_episode(planner, 1, range(0, 30), start=True, end=True)
    _recovery(planner, 1, range(30, 35))
    assert not planner.pending() and planner.due(now_s=0.0) == []
    _learning_episode(planner, 2, range(35, 50), start=True, end=False)
    _recovery(planner, 2, range(50, 52))
    assert planner.due(now_s=0.0) == [(49, 50)]
    assert planner.due(now_s=0.5) == []  # not again before the retry interval
    assert planner.due(now_s=1.5) == [(49, 50)]
    assert planner.due(now_s=3.0) == []  # two attempts, then it is left to the final report
    planner.episodes.ends.add(2)  # the replayed frame arrived
    assert not planner.pending()
