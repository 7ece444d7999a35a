"""`dive check` never fails a conformant agent at the edges of issue 26 (D1-D4), against real agent processes."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.check.agent import reach
from groundstation.check.probe import Probe, Timeouts, mode_of
from groundstation.cli.app import app
from groundstation.links import make_link
from groundstation.session.keys import read_key_file, write_key_file
from protocol import AckResult, Mode
from protocol import messages as m
from protocol.parameters import PARAM_COUNT
from tests.groundstation.check_helpers import BROKEN_AGENT, agent, by_result, check


@pytest.mark.slow
def test_an_optional_parameter_listed_fixed_at_its_default_passes_the_table(tmp_path: Path) -> None:
    """D1: SPEC.md 13 lets an agent without the shared-model learners report those with minimum = maximum =
    default; params.table must pass it (it knew only the start_at_rest exception)."""
    script = [str(BROKEN_AGENT), "optional-unimplemented", "serve"]
    with agent(tmp_path, "--tcp", "127.0.0.1:0", script=script) as url:
        code, report = check(url, "--only", "params.table", "--only", "params.list")
    assert by_result(report, "FAIL") == [], report
    assert code == 0 and report["counts"]["PASS"] == 2


@pytest.mark.slow
def test_at_speed_1_the_check_waits_for_idle_after_a_surface_at_the_surface(tmp_path: Path) -> None:
    """D2: a CMD_SURFACE at the surface shows SURFACING for a while (here a slow agent: 1 s at --speed 1); the next
    check's CMD_START must wait for IDLE, not be sent milliseconds later into SURFACING (NOT_ALLOWED_IN_MODE). The
    agent reports start_at_rest fixed at 0, as a real agent does, so the check reaches LEARNING through RECOVERING.
    (A regression test: against our agents the race's window, one SURFACING SAMPLE period, was too short for the
    old check to lose it here; the external agent of the review lost it.) Only the part that depends on the speed
    runs here, the checks' own way in (reach): the whole checks that follow (dump.counts_stale, ...) pass at
    --speed max in test_checks and at --speed 1 in scripts/check_soak.py; run whole here they took 60 s."""
    key_file = write_key_file(tmp_path / "dive.key")
    script = [str(BROKEN_AGENT), "optional-unimplemented,slow-surface", "serve"]
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--speed", "1", "--preset", "hardware", "--seed", "2",
               "--key-file", str(key_file), script=script) as url:
        link = make_link(url)
        link.open()
        probe = Probe(link, read_key_file(key_file), Timeouts(reply_s=10.0))
        try:
            assert probe.await_program() == ""  # its program built (a starting agent answers BUSY)
            probe.accepted(m.ParamGet(index=0, name=""))
            surfaced = probe.accepted(m.Surface(), "CMD_SURFACE at the surface")  # as signing.surface_always does
            assert probe.wait_mode({Mode.SURFACING}, surfaced.ack_at, 5.0) == Mode.SURFACING
            reach(probe, Mode.RECOVERING)  # the next check's CMD_START (reach LEARNING goes through it)
            starts = [(i, f.message) for i, f in enumerate(probe.frames(surfaced.ack_at), surfaced.ack_at)
                      if isinstance(f.message, m.Ack) and f.message.cmd_msg_id == m.StartLearning.MSG_ID]
            shown = [mode_of(f) for f in probe.frames(surfaced.ack_at, starts[0][0]) if mode_of(f) is not None]
        finally:
            probe.close()
    assert [ack.result for _, ack in starts] == [AckResult.ACCEPTED], starts  # never sent into SURFACING
    assert shown[0] == Mode.SURFACING and shown[-1] == Mode.IDLE, shown  # it waited until IDLE was shown


@pytest.mark.slow
def test_status_against_a_keyed_agent_without_or_with_a_wrong_key_fails_with_the_agents_reason(
        tmp_path: Path) -> None:
    """D4: the agent refuses PARAM_LIST (UNAUTHORIZED): `dive status` says so and exits 1, it does not print a
    cached "N parameters"; with the right key it works (after which a cached table exists to tempt it)."""
    key = write_key_file(tmp_path / "dive.key")
    wrong = write_key_file(tmp_path / "other.key")
    runner = CliRunner()
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--key-file", str(key)) as url:
        good = runner.invoke(app, ["status", url, "--key-file", str(key)])
        assert good.exit_code == 0, good.output
        assert f"{PARAM_COUNT} parameters" in good.stdout
        for args in ([], ["--key-file", str(wrong)]):
            refused = runner.invoke(app, ["status", url, *args])
            assert refused.exit_code == 1, (args, refused.output)
            assert "UNAUTHORIZED" in refused.stderr and "parameters" not in refused.stdout, (args, refused.output)
            lines = [line for line in refused.stderr.splitlines() if line.strip()]
            assert len(lines) == 1 and lines[0].startswith("dive:"), refused.stderr


@pytest.mark.slow
def test_dive_sim_conforms_on_a_115200_baud_link(tmp_path: Path) -> None:
    """A paced link (bytes at a UART's rate, as through the ESP8266's serial): dumps, log replays and the parameter
    list compete with SAMPLEs, and those checks still pass. Only the checks whose traffic competes (the others
    pass at --speed max in test_checks; the whole suite, paced, in scripts/check_soak.py --pacings 115200)."""
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--preset", "paper", "--seed", "4", "--baud", "115200") as url:
        code, report = check(url, "--allow-motion", "--timeout", "10", "--only", "params.list", "--only",
                             "dump.kinds", "--only", "dump.partial", "--only", "log")
    assert by_result(report, "FAIL") == [], report
    assert code == 0
    print(f"115200 baud: {report['counts']} in {report['seconds']} s")
