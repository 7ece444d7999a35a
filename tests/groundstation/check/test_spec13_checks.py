"""`dive check` 1.3 (issue 39): the generation across a learner restart, the answer time and the cross-parameter
refusals pass on the virtual agent, and an agent lacking each rule (tests/groundstation/broken_agent.py) fails
exactly that check, in its SPEC section."""

from __future__ import annotations

from pathlib import Path

import pytest

from groundstation.session.keys import write_key_file
from tests.groundstation.check_helpers import BROKEN_AGENT, agent, check

pytestmark = pytest.mark.slow
SPEC_13 = ("generation.named", "generation.restart", "link.answer_time", "params.cross_refused",
           "signing.estimate_cap", "signing.resync", "link.taken")
ONLY = [arg for check_id in SPEC_13 for arg in ("--only", check_id)]


def test_the_virtual_agent_passes_the_1_3_checks(tmp_path: Path) -> None:
    key = write_key_file(tmp_path / "dive.key")
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--seed", "3", "--key-file", str(key)) as url:
        code, report = check(url, "--allow-motion", "--timeout", "10", "--key-file", str(key), *ONLY)
    results = {c["id"]: (c["result"], c["detail"]) for c in report["checks"]}
    assert {k: v[0] for k, v in results.items()} == dict.fromkeys(SPEC_13, "PASS"), results
    assert code == 0


def test_the_cross_refusals_pass_on_the_hardware_learner(tmp_path: Path) -> None:
    """Planning on growth is refused without the shared model like the early stop; an agent whose learner has no room
    without the shared model (the `hardware` learner's 1 401 states: the RAM budget refuses shared_model = 0) is not
    failed for it: those pairs are named as not tried, with the agent's reason."""
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--seed", "3") as url:
        code, report = check(url, "--allow-motion", "--timeout", "10", "--only", "params.cross_refused")
    assert code == 0
    plain = {c["id"]: c["detail"] for c in report["checks"] if c["result"] == "PASS"}
    assert "plan_growth with shared_model = 0 refused" in plain["params.cross_refused"]
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--seed", "3", "--preset", "hardware", "--learner", "hardware") as url:
        code, report = check(url, "--allow-motion", "--timeout", "10", "--only", "params.cross_refused")
    assert code == 0
    detail = {c["id"]: c["detail"] for c in report["checks"] if c["result"] == "PASS"}["params.cross_refused"]
    assert "velocity_filter with vel_diff_steps = 2 refused" in detail
    assert "plan_growth not tried: shared_model = 0 alone refused" in detail and "bytes of RAM" in detail


@pytest.mark.parametrize(("fault", "failed", "said"), [
    ("generation-stuck", "generation.restart", "after CMD_RESET_MODEL generation"),
    ("slow-answers", "link.answer_time", "over the 1 s bound"),
    ("no-cross-refusals", "params.cross_refused", "wanted BAD_VALUE"),
    ("no-estimate-cap", "signing.estimate_cap", "may move the estimate by 10 s only"),
    ("no-resync", "signing.resync", "a re-sync with a wrong nonce: BAD_VALUE"),
    ("no-link-taken-text", "link.taken", "no TEXT `link taken by another ground`"),
])
def test_an_agent_lacking_a_1_3_rule_fails_its_check(tmp_path: Path, fault: str, failed: str, said: str) -> None:
    key = write_key_file(tmp_path / "dive.key")
    script = [str(BROKEN_AGENT), fault, "serve"]
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--seed", "3", "--key-file", str(key), script=script) as url:
        code, report = check(url, "--allow-motion", "--timeout", "10", "--key-file", str(key), "--only", failed)
    (outcome,) = [c for c in report["checks"] if c["id"] == failed]
    assert outcome["result"] == "FAIL" and said in outcome["detail"], outcome
    assert outcome["section"].endswith("(1.3)") and outcome["sentence"]
    assert code == 1


@pytest.mark.parametrize("check_id", SPEC_13)
def test_each_1_3_check_quotes_spec_md(check_id: str) -> None:
    """The sentence a 1.3 check prints is SPEC.md's, piece by piece (`[...]` marks what it leaves out): no check
    tests a rule of the ground's own invention."""
    import importlib
    import re

    from groundstation.check.registry import REGISTRY
    from protocol.spec import SPEC_PATH

    for module in ("generations", "signing_resync", "link_taken"):  # importing a module registers its checks
        importlib.import_module(f"groundstation.check.{module}")

    def plain(text: str) -> str:  # the words, without Markdown's emphasis and code marks
        return " ".join(text.replace("`", "").replace("*", "").split())

    spec = plain(SPEC_PATH.read_text(encoding="utf-8"))
    (found,) = [c for c in REGISTRY.checks if c.id == check_id]
    for piece in re.split(r"\s*\[\.\.\.\]\s*", found.sentence):
        assert plain(piece) in spec, (check_id, piece)
