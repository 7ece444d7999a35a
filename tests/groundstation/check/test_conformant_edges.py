"""`dive check` never fails a conformant agent at the edges of issue 26 (D1-D4), against real agent processes."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.session.keys import write_key_file
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
    old check to lose it here; the external agent of the review lost it.)"""
    key = write_key_file(tmp_path / "dive.key")
    script = [str(BROKEN_AGENT), "optional-unimplemented,slow-surface", "serve"]
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--speed", "1", "--preset", "hardware", "--seed", "2",
               "--key-file", str(key), script=script) as url:
        code, report = check(url, "--allow-motion", "--key-file", str(key), "--timeout", "10",
                             "--only", "signing.surface_always", "--only", "dump.counts_stale")
    assert by_result(report, "FAIL") == [], report
    assert code == 0
    assert {c["id"] for c in report["checks"] if c["result"] == "PASS"} == {
        "signing.surface_always", "dump.counts_stale"}


@pytest.mark.slow
def test_status_against_a_keyed_agent_without_or_with_a_wrong_key_fails_with_the_agents_reason(
        tmp_path: Path) -> None:
    """D4: the agent refuses PARAM_LIST (UNAUTHORIZED): `dive status` says so and exits 1, it does not print a
    cached "34 parameters"; with the right key it works (after which a cached table exists to tempt it)."""
    key = write_key_file(tmp_path / "dive.key")
    wrong = write_key_file(tmp_path / "other.key")
    runner = CliRunner()
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--key-file", str(key)) as url:
        good = runner.invoke(app, ["status", url, "--key-file", str(key)])
        assert good.exit_code == 0, good.output
        assert "34 parameters" in good.stdout
        for args in ([], ["--key-file", str(wrong)]):
            refused = runner.invoke(app, ["status", url, *args])
            assert refused.exit_code == 1, (args, refused.output)
            assert "UNAUTHORIZED" in refused.stderr and "parameters" not in refused.stdout, (args, refused.output)
            lines = [line for line in refused.stderr.splitlines() if line.strip()]
            assert len(lines) == 1 and lines[0].startswith("dive:"), refused.stderr


@pytest.mark.slow
def test_dive_sim_conforms_on_a_115200_baud_link(tmp_path: Path) -> None:
    """A paced link (bytes at a UART's rate, as through the ESP8266's serial): dumps, log replays and the parameter
    list compete with SAMPLEs, and those checks still pass. (The whole suite passes too, in about 130 s:
    scripts/check_soak.py --baud 115200 runs it.)"""
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--preset", "paper", "--seed", "4", "--baud", "115200") as url:
        code, report = check(url, "--allow-motion", "--timeout", "10", "--only", "handshake", "--only", "params.list",
                             "--only", "dump", "--only", "log", "--only", "timesync")
    assert by_result(report, "FAIL") == [], report
    assert code == 0
    print(f"115200 baud: {report['counts']} in {report['seconds']} s")
