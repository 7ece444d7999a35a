"""`dive` as people type it: validation before acting, one exit-code convention, units in help, quick start-up,
plain lines when not on a terminal, TOML parameter files. Real processes and real TCP where a user would see one."""

from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import click
import pytest
import typer
from rich.markup import render
from typer.testing import CliRunner, Result

from groundstation.cli.app import app
from tests.groundstation.fake_agent import FakeAgent

DIVE = [sys.executable, "-m", "groundstation.cli.app"]


def dive(*args: str, cwd: Path | None = None, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("DIVE_URL", "DIVE_KEY_FILE")}
    return subprocess.run([*DIVE, *args], env={**env, "COLUMNS": "200"}, capture_output=True, text=True,
                          timeout=timeout, cwd=cwd)


def _one_line(done: subprocess.CompletedProcess[str], code: int, text: str) -> None:
    assert done.returncode == code, (done.stdout, done.stderr)
    assert "Traceback" not in done.stderr and text in done.stderr, done.stderr


@pytest.mark.parametrize(("args", "text"), [
    (["run", "--episodes", "-3"], "--episodes"),
    (["run", "--episodes", "4294967296"], "--episodes"),
    (["run", "--web-port", "0"], "--web-port"),
    (["run", "--grpc-port", "65536"], "--grpc-port"),
    (["replay", "x.mcap", "--web-port", "70000"], "--web-port"),
    (["run", "--speed", "fast"], "bad speed 'fast'"),
    (["run", "tcp://127.0.0.1:9", "--speed", "10"], "apply to the built-in virtual agent"),
    (["params", "set", "x"], "expected `dive params [URL] set NAME VALUE`"),
    (["hover", "deep"], "DEPTH must be a number"),
])
def test_bad_usage_is_exit_2_before_anything_starts(args: list[str], text: str) -> None:
    done = CliRunner().invoke(app, args, env={"COLUMNS": "200"})
    assert done.exit_code == 2 and text in done.stderr, done.stderr
    assert "virtual agent did not start" not in done.stderr and "connecting" not in done.stderr


@pytest.mark.parametrize(("args", "text"), [
    (["run", "--episodes", "-3"], "invalid value for '--episodes': -3 is out of range: from 0 to 4294967295"),
    (["run", "--web-port", "70000"], "invalid value for '--web-port': 70000 is out of range: from 1 to 65535"),
    (["view", "--foxglove", "70000"], "invalid value for '--foxglove': 70000 is out of range: from 0 to 65535"),
])
def test_a_value_out_of_range_is_the_one_line_the_readme_promises(args: list[str], text: str) -> None:
    done = dive(*args)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [f"dive: {text} (dive {args[0]} -h lists the options)"], done.stderr


@pytest.mark.parametrize(("args", "line"), [
    (["export"], "dive: no such command 'export' (dive -h lists the commands)"),
    (["log", "inf"], "dive: no such command 'inf'. Did you mean 'info'? (dive log -h lists the commands)"),
    (["replay"], "dive: missing argument 'FILES...' (dive replay -h lists the options)"),
    (["status", "--bogus"], "dive: no such option '--bogus' (dive status -h lists the options)"),
])
def test_any_usage_error_is_one_line_not_a_box(args: list[str], line: str) -> None:
    done = dive(*args)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [line], done.stderr


def test_run_help_is_readable_at_80_columns() -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("DIVE_URL", "DIVE_KEY_FILE")}
    done = subprocess.run([*DIVE, "run", "-h"], env={**env, "COLUMNS": "80"}, capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    options = [line for line in lines if line.startswith("│ --")]
    # the help text starts within the first half of the line: no 41-column option column squeezing it
    assert options and all(line.index(" ", line.index("--") + 1) < 40 for line in options), options
    assert not any(re.search(r"\d$", line.rstrip(" │")) and re.match(r"│ +\d", after)
                   for line, after in zip(lines, lines[1:], strict=False)), done.stdout  # no number split
    assert len(lines) <= 90, len(lines)  # 159 before issue 40


def test_a_web_port_in_use_is_refused_before_the_run_starts() -> None:
    with socket.socket() as busy:
        busy.bind(("0.0.0.0", 0))
        busy.listen()
        port = busy.getsockname()[1]
        done = CliRunner().invoke(app, ["run", "--viewer", "web", "--web-port", str(port)])
    assert done.exit_code == 2
    assert f"port {port} is in use by another process: choose another with --web-port" in done.stderr


def test_version_short_help_and_units_in_help() -> None:
    version = CliRunner().invoke(app, ["--version"])
    assert version.exit_code == 0 and version.stdout.startswith("dive ")
    helped = CliRunner().invoke(app, ["run", "-h"], env={"COLUMNS": "200"})
    assert helped.exit_code == 0
    for unit in ("target depth z_d [m]", "learning region [m/s]", "counts as success [s]", "--grpc-port"):
        assert unit in helped.stdout, unit
    assert "--install-completion" in CliRunner().invoke(app, ["-h"]).stdout


@pytest.mark.parametrize("command", ["sim", "study", "fit"])
def test_the_forwarded_simulator_commands_take_dash_h_too(command: str) -> None:
    done = subprocess.run([sys.executable, "-c", "import sys; sys.argv[0] = 'dive'; "
                           "from groundstation.cli import app as cli; cli.main()", command, "-h"],
                          capture_output=True, text=True, timeout=60,
                          env={**os.environ, "COLUMNS": "100"})
    assert done.returncode == 0, done.stderr
    assert f"Usage: dive {command}" in done.stdout


def test_help_imports_neither_rerun_nor_numba_nor_matplotlib() -> None:
    done = subprocess.run([sys.executable, "-X", "importtime", "-m", "groundstation.cli.app", "--help"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0
    imported = {line.split("|")[-1].strip() for line in done.stderr.splitlines() if line.startswith("import time")}
    for heavy in ("rerun", "numba", "matplotlib", "mcap", "numpy", "simulator", "learning",
                  # deferred to where they are used (issue 14 item 5: `dive --help` under 0.3 s):
                  "rich.markdown", "markdown_it", "rich.traceback", "pygments", "ctypes", "socket", "secrets"):
        assert heavy not in imported, heavy


@pytest.mark.parametrize("argv", [["--help"], ["run", "-h"], ["log", "export", "-h"], ["params", "-h"]])
def test_help_without_the_markdown_renderer_is_the_help_typer_prints(argv: list[str]) -> None:
    """main() loads Typer's help with stand-ins for the renderers dive never uses: the text must not change."""
    def help_text(entry: str) -> str:
        code = f"import sys; sys.argv[0] = 'dive'; from groundstation.cli import app as cli; cli.{entry}"
        done = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=60,
                              env={**os.environ, "COLUMNS": "100"})
        assert done.returncode == 0, done.stderr
        return done.stdout

    deferred, typer_alone = help_text("main()"), help_text("app()")
    assert deferred == typer_alone and "Usage: dive" in deferred


def test_not_on_a_terminal_dive_run_prints_one_line_per_episode(tmp_path: Path) -> None:
    agent = FakeAgent(episode_len=10)
    try:
        done = dive("run", agent.url, "--episodes", "3", "--out", str(tmp_path))
    finally:
        agent.close()
    assert done.returncode == 0, done.stderr
    lines = done.stderr.splitlines()
    assert lines[0] == f"connecting to {agent.url}"
    episodes = [line for line in lines if line.startswith("episode ")]
    assert [line.split(":")[0] for line in episodes][:3] == ["episode 1 of 3", "episode 2 of 3", "episode 3 of 3"]
    assert not any("\r" in line or "━" in line for line in lines)  # no progress bar redrawn into a log
    assert any(line.startswith("other tools attach to this run as hub://") for line in lines)
    assert not any("[dim]" in line or "[/]" in line for line in lines)  # styles applied, not printed as text

    info = _cli("log", "info", str(tmp_path), str(tmp_path), "--json")  # a folder, twice: a list of summaries
    rows = json.loads(info.stdout)
    assert info.exit_code == 0 and len(rows) == 2
    assert rows[0]["agent"]["node_id"] == "000a6e47"  # hex, as `dive status` and the file name show it
    assert rows[0]["agent"]["boot_id"] == f"{1234:08x}" and rows[0]["agent"]["firmware_major"] == 9
    assert isinstance(rows[0]["parameters"]["z_tol_m"], float) and rows[0]["being_recorded_by"] is None
    exported = _cli("log", "export", str(tmp_path), "--format", "csv")  # a folder: one CSV beside each recording
    assert exported.exit_code == 0 and [p.suffix for p in tmp_path.iterdir()].count(".csv") == 1, exported.stderr


def _cli(*args: str) -> Result:
    return CliRunner().invoke(app, list(args), env={"COLUMNS": "200"})


def test_params_save_diff_load_and_run_share_one_toml_format(tmp_path: Path) -> None:
    agent = FakeAgent()
    saved = tmp_path / "agent.toml"
    try:
        assert _cli("params", agent.url, "save", str(saved)).exit_code == 0
        text = saved.read_text()
        assert "z_tol_m = 0.1" in text and "max_episodes = 0" in text
        assert "0 of 7 differ" in _cli("params", agent.url, "diff", str(saved)).stdout
        saved.write_text(text.replace("z_tol_m = 0.1", "z_tol_m = 0.25"))
        diff = _cli("params", agent.url, "diff", str(saved))
        assert "z_tol_m: agent 0.1, file 0.25" in diff.stdout and "1 of 7 differ" in diff.stdout
        assert diff.exit_code == 1  # as diff(1): a script can tell the file differs
        loaded = _cli("params", agent.url, "load", str(saved), "--reset-model")  # z_tol_m restarts the learner
        assert loaded.exit_code == 0 and "z_tol_m = 0.25" in loaded.stdout, loaded.stderr
        assert "0 of 7 differ" in _cli("params", agent.url, "diff", str(saved)).stdout
        action_first = _cli("params", "get", agent.url, "z_tol_m")  # the order people who think "get" first type
        assert action_first.exit_code == 0 and "z_tol_m = 0.25" in action_first.stdout, action_first.stderr
        pattern = _cli("params", agent.url, "get", "z_*")  # a pattern: every parameter it matches, one a line
        assert pattern.exit_code == 0 and pattern.stdout.splitlines() == ["z_tol_m = 0.25"], pattern.stdout
        nothing = _cli("params", agent.url, "get", "nope_*")
        assert nothing.exit_code == 1 and "no parameter matches 'nope_*'" in nothing.stderr, nothing.stderr
        whole = _cli("params", agent.url, "set", "max_episodes", "3.7")
        assert whole.exit_code == 1 and "3.7 is not a whole number" in whole.stderr
        bad = tmp_path / "bad.toml"
        bad.write_text("z_tol = 0.2\n")
        guess = _cli("params", agent.url, "load", str(bad))
        assert guess.exit_code == 1 and "did you mean z_tol_m" in guess.stderr
        run_file = tmp_path / "run.toml"
        run_file.write_text("target_depth_m = 0.7\n")
        done = _cli("run", agent.url, "--episodes", "1", "--params", str(run_file), "--out", str(tmp_path / "r"))
        assert done.exit_code == 0, done.stderr
    finally:
        agent.close()
    assert agent.params["target_depth_m"][1] == pytest.approx(0.7)


def test_a_run_with_a_viewer_has_the_agent_dump_its_values_and_policy_each_episode(tmp_path: Path) -> None:
    agent = FakeAgent()
    try:
        watched = _cli("run", agent.url, "--episodes", "1", "--viewer", "none", "--rrd", str(tmp_path / "v.rrd"),
                       "--out", str(tmp_path / "a"))
        assert watched.exit_code == 0, watched.stderr
        assert agent.params["dump_each_episode"][1] == 1  # the heatmaps get a dump at every episode end
    finally:
        agent.close()


def test_params_and_hover_honour_dive_url() -> None:
    agent = FakeAgent()
    try:
        env = {"DIVE_URL": agent.url, "COLUMNS": "200"}
        hovered = CliRunner().invoke(app, ["hover", "0.4"], env=env)
        assert hovered.exit_code == 0 and f"hovering at 0.4 m ({agent.url})" in hovered.stdout, hovered.stderr
        got = CliRunner().invoke(app, ["params", "get", "z_tol_m"], env=env)
        assert got.exit_code == 0 and "z_tol_m = 0.1" in got.stdout, got.stderr
    finally:
        agent.close()
    assert agent.connections == 2 and agent.executed.count("CMD_HOVER") == 1


def _help_texts(command: click.Command, path: str = "dive") -> Iterator[tuple[str, str, bool]]:
    """Every help text dive's commands, arguments and options carry: where it is shown, the text, an argument's?"""
    yield path, command.help or "", False
    for param in command.params:
        yield f"{path} {param.name}", getattr(param, "help", None) or "", isinstance(param, click.Argument)
    if isinstance(command, click.Group):
        for name, sub in command.commands.items():
            yield from _help_texts(sub, f"{path} {name}")


def test_no_help_text_loses_words_to_rich_markup() -> None:
    """Help is rendered as Rich markup: an unescaped `[default: 2]` is read as a style tag and vanishes."""
    lost = [f"{where}: {text!r}" for where, text, _ in _help_texts(typer.main.get_command(app))
            if render(text).plain != text.replace("\\[", "[")]
    assert lost == []


def test_every_argument_says_what_it_takes() -> None:
    """typer 0.20 under click 8.5 dropped every argument's help text without a word: pyproject holds click below."""
    bare = [where for where, text, argument in _help_texts(typer.main.get_command(app)) if argument and not text]
    assert bare == []
