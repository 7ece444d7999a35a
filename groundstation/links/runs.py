"""The `dive run`s on this machine: each announces its hub in a small file, keyed by run, under the runtime folder.

`dive view`, `status`, `mark`, `surface`, ... find a run here and attach to its hub (groundstation/run/hub.py)
instead of opening a second link to the agent, which has one TCP slot. A file whose process is gone is
stale: it is ignored and removed.

The folder is the user's own (0700) and each file is 0600: it holds the run's hub token (links/hub_auth.py), which
only the run's owner may read. A file whose PID now belongs to another user's process is stale too (that process
is not our run); one whose PID a process of ours took is found out by the hub handshake, which it cannot answer.
"""

from __future__ import annotations

import contextlib
import json
import os
import stat
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from urllib.parse import urlsplit

from groundstation.errors import LinkError
from groundstation.links import DEFAULT_URL, split_url

HUB_SCHEME = "hub"
RUNTIME_DIR_VARIABLE = "DIVE_RUNTIME_DIR"


class NoRunError(LinkError):
    """No running `dive run` (or not the one named) to attach to."""


class RuntimeFolderError(LinkError):
    """The runs folder is not the user's own: announcing or trusting a run there would let others in."""


def runs_dir() -> Path:
    """$DIVE_RUNTIME_DIR, else the user's runtime folder (XDG_RUNTIME_DIR), else the user's cache folder."""
    override = os.environ.get(RUNTIME_DIR_VARIABLE)
    if override:
        return Path(override) / "runs"
    import platformdirs  # only the commands that look for runs pay for it

    runtime = os.environ.get("XDG_RUNTIME_DIR")
    base = platformdirs.user_runtime_dir("dive") if runtime and os.path.isdir(runtime) else \
        platformdirs.user_cache_dir("dive")
    return Path(base) / "runs"


@dataclass(frozen=True, slots=True)
class RunInfo:
    run: str  # the run's id: its process id, unique among the processes alive
    pid: int
    hub: str  # tcp://127.0.0.1:PORT, where tools attach
    url: str  # the agent's link
    recording: str  # the current recording file ("" before the first)
    started: float  # time.time()
    token: str = field(default="", repr=False)  # the hub's secret (hex): never printed, never sent (hub_auth.py)
    # connecting: the run exists but has no hub yet (a virtual agent compiling); running: tools attach to `hub`;
    # finished: the run is over, its agent's link closed, but its web viewer (`viewer`) is still up
    state: str = "running"
    viewer: str = ""
    alarm: str = ""  # the run's alarm flag, as its status line shows it (run/alarms.py): `dive status` shows it too

    @property
    def path(self) -> Path:
        return runs_dir() / f"{self.run}.json"

    def state_line(self) -> str:
        """What the run is doing, for `dive status` and a tool that finds no run to attach to."""
        if self.state == "connecting":
            return (f"dive run {self.run} is connecting to {self.url} (for {time.time() - self.started:.0f} s): "
                    "tools attach once it is up")
        if self.state == "finished":
            viewer = f"; its web viewer is still up at {self.viewer} (Ctrl-C in its pane closes it)" \
                if self.viewer else ""
            recording = f", recording {self.recording}" if self.recording else ""
            return f"dive run {self.run} is finished ({self.url}{recording}){viewer}"
        return f"dive run {self.run} is running: hub://{self.run} ({self.url})"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return False  # another user's process has the PID now: our run (the file is ours) is gone (issue 25 H2)
    try:  # root may signal anyone: ask Linux whose process it is (macOS has no /proc: the hub handshake decides)
        return os.stat(f"/proc/{pid}").st_uid == os.geteuid()
    except OSError:
        return True


def private_runs_dir() -> Path:
    """The runs folder, made (0700) or checked: ours, and nobody else may read or write it; else RuntimeFolderError."""
    folder = runs_dir()
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    info = folder.lstat()
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.geteuid():
        raise RuntimeFolderError(f"{folder} is not a folder of this user's: no run is announced or trusted there")
    if info.st_mode & 0o077:
        os.chmod(folder, 0o700)  # ours, but made open by hand or an old version: close it
    return folder


def announce(info: RunInfo) -> Path:
    """Write (or rewrite, when the recording changes) the run's file atomically, readable by its owner only."""
    private_runs_dir()
    path = info.path
    tmp = path.with_suffix(".tmp")
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(json.dumps(asdict(info)))
    tmp.replace(path)
    return path


def withdraw(info: RunInfo) -> None:
    try:
        info.path.unlink()
    except OSError:
        pass


def running() -> list[RunInfo]:
    """The runs alive on this machine, oldest first; stale files are removed."""
    try:
        folder = private_runs_dir()
        files = sorted(folder.glob("*.json"))
    except OSError:
        return []  # RuntimeFolderError too: nothing in a folder others can write is believed
    runs = []
    for path in files:
        try:
            if path.lstat().st_uid != os.geteuid():
                continue
            info = RunInfo(**json.loads(path.read_text()))
        except (OSError, ValueError, TypeError):
            continue
        if not _alive(info.pid):
            try:
                path.unlink()
            except OSError:
                pass
            continue
        runs.append(info)
    return sorted(runs, key=lambda r: r.started)


def is_running(run: str) -> bool:
    """The run is announced on this machine as running: a run withdraws its announcement (or marks it finished)
    before it closes its hub, so a tool whose hub link is down while this is False has seen its run end."""
    return any(info.run == run and info.state == "running" for info in running())


def find_run(run: str | None = None, hint: str = "") -> RunInfo:
    """The run named, or the one run there is, that tools can attach to; NoRunError with one line (and `hint`)
    otherwise, naming a run that is still connecting or is over."""
    announced = running()
    runs = [info for info in announced if info.state == "running"]
    if run:
        for info in announced:
            if info.run == run:
                if info.state != "running":
                    raise NoRunError(info.state_line())
                return info
        known = ", ".join(r.run for r in runs) or "none"
        raise NoRunError(f"no dive run {run!r} on this machine (running: {known})")
    if not runs:
        others = "; ".join(info.state_line() for info in announced)
        if any(info.state == "connecting" for info in announced):
            raise NoRunError(others)  # it is there: "no dive run" would send the user to start a second one
        raise NoRunError(f"no `dive run` is running on this machine{hint}" + (f" ({others})" if others else ""))
    if len(runs) > 1:
        listed = ", ".join(f"hub://{r.run} ({r.url})" for r in runs)
        raise NoRunError(f"{len(runs)} dive runs are running; name one: {listed}")
    return runs[0]


def hub_address(url: str) -> tuple[RunInfo, str]:
    """hub:// (the one run) or hub://RUN: the run and its hub's tcp:// address."""
    info = find_run(urlsplit(url).netloc or None)
    return info, info.hub


def _agent_key(url: str) -> tuple[str, str] | None:
    """What names one agent in a URL (scheme, host:port or device), None for a URL that starts its own (sim://)."""
    parts = split_url(url)
    if parts.scheme in ("tcp", "socket", "rfc2217"):
        host = (parts.hostname or "").lower()
        host = "127.0.0.1" if host in ("localhost", "::1") else host
        return parts.scheme, f"{host}:{parts.port}"
    if parts.scheme == "serial" or url.startswith("/dev/"):
        return "serial", os.path.realpath(parts.path or url)
    return None


def holder(url: str) -> RunInfo | None:
    """The running `dive run` that holds the agent at `url` (the agent has one link: one agent, one owner)."""
    key = _agent_key(url)
    if key is None:
        return None
    # a connecting run holds it already; a finished one has closed its link
    return next((info for info in running() if info.state != "finished" and _agent_key(info.url) == key), None)


def wait_while_connecting(run: str | None, notice: Callable[[str], None], poll_s: float = 0.2) -> None:
    """While the run named (or the only one announced) is still connecting, wait for it, saying so once; return
    when it is up, or when none is connecting (find_run then says what there is)."""
    said = False
    while True:
        announced = [info for info in running() if run is None or info.run == run]
        connecting = [info for info in announced if info.state == "connecting"]
        if not connecting or any(info.state == "running" for info in announced):
            return
        if not said:
            notice(f"{connecting[0].state_line()}: waiting for it; Ctrl-C to give up")
            said = True
        time.sleep(poll_s)


def refuse_if_held(url: str) -> None:
    """`dive run URL` while another run holds that agent: one line, before a link is opened (issue 25 H4)."""
    info = holder(url)
    if info is not None:
        raise LinkError(f"{url} is held by dive run {info.run} (hub://{info.run}): one agent, one owner; attach to "
                        f"it (dive view hub://{info.run}) or stop that run first")


def attach_url(url: str | None) -> str:
    """The URL a command that acts on *the* agent uses: the one given, else $DIVE_URL, else the running run's hub.

    An agent URL that a local run holds becomes that run's hub: a second link would take the agent's one link
    from the run (both then fight over it, issue 25 H4). Never the built-in virtual agent: surfacing a fresh
    simulator and saying "surfacing" would be a lie.
    """
    url = url or os.environ.get("DIVE_URL")
    if url:
        held = holder(url)
        return f"{HUB_SCHEME}://{held.run}" if held is not None else url
    info = find_run(None, hint=": give the agent's URL (or set DIVE_URL)")
    return f"{HUB_SCHEME}://{info.run}"


def run_url_default(url: str | None) -> str:
    """`dive run`'s link: the one given, else $DIVE_URL, else the built-in virtual agent."""
    return url or os.environ.get("DIVE_URL") or DEFAULT_URL


def new_run(pid: int, hub: str, url: str, token: str, state: str = "running") -> RunInfo:
    return RunInfo(run=str(pid), pid=pid, hub=hub, url=url, recording="", started=time.time(), token=token,
                   state=state)
