"""Backfill planning: which on-board log ranges bring back lost samples and lost episode frames."""

from __future__ import annotations

from groundstation.session.gaps import BackfillPlanner


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


def test_complete_episodes_need_nothing_and_requests_are_retried_while_the_agent_holds_them() -> None:
    planner = BackfillPlanner(retry_after_s=1.0, max_wait_s=4.0)
    _learning_episode(planner, 1, range(0, 30), start=True, end=True)
    _recovery(planner, 1, range(30, 35))
    assert not planner.pending() and planner.due(now_s=0.0) == []
    _learning_episode(planner, 2, range(35, 50), start=True, end=False)
    _recovery(planner, 2, range(50, 52))
    assert planner.due(now_s=0.0) == [(49, 50)]
    assert planner.due(now_s=0.5) == []  # not again before the retry interval
    assert planner.due(now_s=1.5) == [(49, 50)]
    assert planner.due(now_s=2.0) == []  # the wait grows: 1.5 s after the second try
    assert planner.due(now_s=3.0) == [(49, 50)]
    asked = [t for t in range(4, 200) if planner.due(now_s=float(t))]
    assert len(asked) >= 40  # never given up while the log holds it, at most every 4 s
    planner.episodes.ends.add(2)  # the replayed frame arrived
    assert not planner.pending()


def test_a_gap_is_lost_only_once_the_agents_log_no_longer_holds_it() -> None:
    planner = BackfillPlanner()
    for index in [*range(0, 100), *range(2000, 2010)]:
        planner.held.add(index)
    planner.saw_log_window(0, 2010)
    assert planner.lost() == 0 and planner.pending()
    pieces = planner.due(now_s=0.0)
    assert pieces[0] == (100, 612) and all(b - a <= 512 for a, b in pieces)  # the agent replays 512 at most
    assert sum(b - a for a, b in pieces) == 1900
    planner.saw_log_window(1000, 2010)  # the log was overwritten up to 1000 (LOG_RANGE / HEARTBEAT says so)
    assert planner.lost() == 900
    assert planner.fetchable() == [(1000, 2000)]


def test_a_new_learner_s_lost_episode_start_is_requested_though_the_old_one_had_its_number() -> None:
    """SPEC 1.3: after a learner restart episode 1 comes again; its lost EPISODE_START is not the old episode 1's."""
    planner = BackfillPlanner()
    planner.episodes.saw_generation(1)
    _learning_episode(planner, 1, range(0, 30), start=True, end=True)
    _recovery(planner, 1, range(30, 35))
    planner.episodes.saw_generation(2)  # the restart (a HEARTBEAT naming generation 2)
    _recovery(planner, 0, range(35, 40))
    _learning_episode(planner, 1, range(40, 60), start=False, end=True)
    assert planner.due(now_s=0.0) == [(40, 41)]
