"""Issue 25 L5 on the Python agent: one signed frame moves the agent's estimate of "now" a bounded step (SPEC.md
s. 12, step 5), so a ground clock ahead cannot ratchet it until every new link id is refused as too old."""

from __future__ import annotations

from pathlib import Path

from protocol import AckResult, FrameEncoder, Signer, messages
from protocol.signing import ESTIMATE_STEP_S, FUTURE_WINDOW_S
from tests.simulator.agent_client import connected

KEY = bytes(range(32))
T_NS = 1_735_689_600 * 10**9 + 10**15  # well after 2025, never below a mark of an earlier run


def test_a_clock_ahead_moves_the_estimate_a_bounded_step_and_locks_no_new_ground_out(tmp_path: Path) -> None:
    key_file = tmp_path / "agent.key"
    key_file.write_text(KEY.hex() + "\n")
    key_file.chmod(0o600)  # the agent refuses a key file others can read
    args = ("--tcp", "127.0.0.1:0", "--speed", "50", "--seed", "11", "--key-file", str(key_file),
            "--state-dir", str(tmp_path / "state"))
    ahead_s = FUTURE_WINDOW_S - 1  # inside the window: accepted, but the estimate moves ESTIMATE_STEP_S only
    assert ahead_s > ESTIMATE_STEP_S
    with connected(*args) as (_, c):
        c.encoder = FrameEncoder(100, signer=Signer(KEY, 5, clock_ns=lambda: T_NS))
        assert c.command(messages.ParamGet(index=0)).result == AckResult.ACCEPTED  # the estimate: T
        fast = [T_NS + int(ahead_s * 1e9)]
        c.encoder = FrameEncoder(200, signer=Signer(KEY, 6, clock_ns=lambda: fast[0]))
        assert c.command(messages.ParamGet(index=0)).result == AckResult.ACCEPTED
        fast[0] += int(ahead_s * 1e9)  # one more minute: before the bound the estimate was at T + 59 s, now T + 10 s
        assert c.command(messages.ParamGet(index=0)).result == AckResult.UNAUTHORIZED  # too new
        # a new ground (a fresh link id) with the right time is not "too old" against a run-away estimate
        c.encoder = FrameEncoder(300, signer=Signer(KEY, 7, clock_ns=lambda: T_NS + 10**9))
        assert c.command(messages.ParamGet(index=0)).result == AckResult.ACCEPTED
