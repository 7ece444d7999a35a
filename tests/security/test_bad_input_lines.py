"""Bad input is one line with the documented exit code, never a traceback, "internal error" or a key (issue 38
N6-N10): files read bounded, nested and non-UTF-8 parameter files, URLs that do not parse, a marker that is no
UTF-8, a lying HEARTBEAT before any sample, `dive surface` without the key, `dive fit` on what is no recording."""

from __future__ import annotations

import os
import resource
import subprocess
from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.session.gaps import MAX_LOG_SAMPLES, BackfillPlanner
from protocol.signing import KEY_SIZE
from tests.groundstation.fake_agent import FakeAgent
from tests.groundstation.hub_helpers import DIVE, dive_env
from tests.security.attack import hub_run

ADDRESS_SPACE_BYTES = 3 * 1024**3  # a reader of /dev/zero ends here (MemoryError), not at 20 GB on a shared machine


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE_BYTES, ADDRESS_SPACE_BYTES))


def _dive(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*DIVE, *args], env=dive_env(tmp_path / "runtime"), capture_output=True, text=True,
                          timeout=60, preexec_fn=_limited)


def _one_line(done: subprocess.CompletedProcess[str], code: int, words: str) -> None:
    lines = [line for line in done.stderr.splitlines() if line.strip() and not line.startswith("connecting to ")]
    assert done.returncode == code, (done.returncode, done.stderr[-2000:])
    assert len(lines) == 1 and words in lines[0] and "internal error" not in lines[0], done.stderr[-2000:]


def test_parameter_files_are_read_bounded_and_whole_lines_come_back(tmp_path: Path) -> None:
    """N6, N7: /dev/zero (read whole: 20.7 GB), 100 000 nested `[` (RecursionError), a byte that is no UTF-8; by
    the ground's reader (`dive run --params`) and the simulator's (`dive sim --params`, `sim://?plant=`)."""
    from simulator.errors import ParamsError
    from simulator.parameters import read_param_table

    deep, binary = tmp_path / "deep.toml", tmp_path / "binary.toml"
    deep.write_text("a = " + "[" * 100_000)
    binary.write_bytes(b'target_depth_m = "\xff"\n')
    for path, words in (("/dev/zero", "KiB"), (str(deep), "nested too deeply"), (str(binary), "UTF-8")):
        _one_line(_dive(tmp_path, "run", "--episodes", "1", "--params", path), 1, words)
        if path != "/dev/zero":  # in a process of this test's own only where the old reader cannot eat the memory
            with pytest.raises(ParamsError, match=words):
                read_param_table(Path(path))
    _one_line(_dive(tmp_path, "sim", "--params", "/dev/zero"), 2, "KiB")


@pytest.mark.parametrize("url", ["tcp://127.0.0.1:99999", "tcp://[::1"])
def test_a_link_url_that_does_not_parse_is_bad_usage(tmp_path: Path, url: str) -> None:
    """N7: exit 1 with "internal error: ValueError", where the README promises exit 2 for a bad URL."""
    _one_line(_dive(tmp_path, "status", url), 2, "bad link URL")


def test_a_marker_that_is_no_utf_8_is_one_line(tmp_path: Path) -> None:
    """N7: `dive mark $'m\\xff'` raised UnicodeEncodeError once a run was there to send it to."""
    done = subprocess.run([*DIVE, "mark", os.fsdecode(b"m\xff")], env=dive_env(tmp_path / "runtime"),
                          capture_output=True, text=True, timeout=60)
    _one_line(done, 2, "UTF-8")


def test_a_heartbeat_lying_before_any_sample_reaches_no_count() -> None:
    """N8: a log end near 2^32 claimed before the first SAMPLE was believed whole: the run's last line said
    4 294 966 578 samples were not backfilled."""
    planner = BackfillPlanner()
    planner.saw_log_window(0, 2**32 - 2)
    for index in range(100):
        planner.held.add(index)
    planner.finish_at()
    assert sum(b - a for a, b in planner.missing()) <= MAX_LOG_SAMPLES


def test_dive_surface_without_the_key_surfaces_a_keyed_runs_agent() -> None:
    """N9: `dive surface` first asked PARAM_LIST, which a keyed run refuses unsigned: the one command that must work
    without a key did not. The agent runs an unsigned CMD_SURFACE on purpose (SPEC 1.2)."""
    agent = FakeAgent()
    try:
        with hub_run(agent.url, key=bytes(range(KEY_SIZE))):
            result = CliRunner().invoke(app, ["surface"])
    finally:
        agent.close()
    assert result.exit_code == 0, result.output
    assert "CMD_SURFACE" in agent.executed


def test_fit_names_what_is_no_recording_and_no_config_prints_a_key(tmp_path: Path) -> None:
    """N10: an empty, random or magic-only file was "no SAMPLE messages to fit"; ServeConfig and QemuConfig printed
    the key."""
    from simulator.fit.reader import FitError, read_samples
    from simulator.serve.firmware_qemu import QemuConfig
    from simulator.serve.loop import ServeConfig

    for name, data in (("empty", b""), ("random", os.urandom(4096)), ("magic", b"\x89MCAP0\r\n")):
        path = tmp_path / f"{name}.mcap"
        path.write_bytes(data)
        with pytest.raises(FitError, match="not an MCAP recording"):
            read_samples([path])
    from simulator.parameters import preset

    key = bytes(range(KEY_SIZE))
    for config in (QemuConfig(key=key), ServeConfig(plant=preset("paper"), key=key)):
        printed = f"{config!r} {config}"
        assert key.hex() not in printed and repr(key) not in printed, printed
