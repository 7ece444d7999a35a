"""Issue 38 item 2's A/B: does any client of a run's listeners slow or starve the recording?

Run: `PYTHONPATH=. .venv/bin/python benchmarks/foxglove_ab_bench.py [--speed 20] [--seconds 25] [--attack hub]`.
Not a test: it prints figures and ratios.

Two `dive run sim://?speed=S --foxglove 0` jobs in turn, the same seed, in this script at the same load:
- control: nobody attached;
- attack: 40 slow readers (WebSocket clients that subscribe to /agent/SAMPLE and never read, reconnecting when
  dropped or refused), 4 clients flapping their /agent/SAMPLE subscription, and a flood of malformed bytes on every
  listener at once (random bytes as new connections to the Foxglove port and the hub port; random frames after a
  valid WebSocket upgrade), all for the whole run.
`--attack hub` (the hub's part of item 2) attacks with tools on the run's hub instead: 10 that prove the token, say
HELLO and never read (connecting again when the hub drops them), beside a `dive record` attached to the run reading
normally; its own recording is read back too (samples, missing, and whether the hub dropped it). 10 leave the hub's
16 slots room for the recorder and the owner's two surfaces. Use --seconds 100: a tool is dropped when a whole
queue (65 536 frames, over a minute at --speed 100) and what the kernel holds for it wait.
After `--seconds` of streaming the owner's CMD_SURFACE is timed from a tool's session on the run's hub (sent to
ACK), then `dive surface` (the command's wall time, its interpreter's start included), then the run is stopped
with Ctrl-C. Printed for both: SAMPLEs recorded per second of streaming (first to last
SAMPLE in the recording), samples lost (missing indices between the first and last recorded, and the run's own
"samples lost" line), peak memory (VmHWM of the `dive run` process), the surface's time; and attack / control.
Every attacker's loop is bounded in count and time; traffic goes to 127.0.0.1 only.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import re
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from websockets.exceptions import WebSocketException  # noqa: E402

from groundstation.links.hub_auth import tool_side  # noqa: E402
from groundstation.mcap_io import read_recording  # noqa: E402
from protocol import FrameEncoder  # noqa: E402
from protocol import messages as m  # noqa: E402
from tests.groundstation.foxglove_client import FoxgloveClient  # noqa: E402
from tests.security.foxglove_intruder import Client, frame  # noqa: E402

DIVE = [sys.executable, "-m", "groundstation.cli.app"]
SAMPLE = "/agent/SAMPLE"
SLOW_READERS, FLAPPERS = 40, 4
FLAPS = [0]  # subscribe + unsubscribe pairs the flappers sent (the attack's own figure)
HUB_STALLS = 10  # tools on the hub that never read (--attack hub)
STALLED = [0]  # their connections that proved the token and said HELLO
TOOL_HELLO = m.Hello(protocol_version=1, node_kind=2, definitions_hash=0, firmware_major=0, firmware_minor=0,
                     firmware_patch=0, node_id=38, boot_id=38, name="never reads")
MAX_ROUNDS = 100_000  # every attacker loop ends after this many rounds, or when the run ends


@dataclass
class Figures:
    rate: float  # SAMPLEs recorded per second of streaming
    missing: int  # indices missing between the first and the last recorded
    said_lost: int  # the run's own "N samples lost" / "not backfilled" lines
    peak_mb: float
    surface_s: float  # `dive surface`'s wall time, its interpreter's start included
    surface_ok: bool
    ack_s: float  # CMD_SURFACE sent to its ACK, from a tool's session attached to the run's hub (nan: no ACK)
    tools_dropped: int = 0  # the run's own count of hub tools dropped for falling behind
    record: str = ""  # --attack hub: what the `dive record` beside the run recorded


def _announced(runtime: Path) -> dict[str, str] | None:
    for path in (runtime / "runs").glob("*.json"):
        try:
            return dict(json.loads(path.read_text()))
        except (OSError, ValueError):
            continue
    return None


def _hub_port(runtime: Path) -> int | None:
    info = _announced(runtime)
    try:
        return int(info["hub"].rsplit(":", 1)[1]) if info is not None else None
    except (KeyError, ValueError):
        return None


def _peak_mb(pid: int) -> float:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return float("nan")
    found = re.search(r"VmHWM:\s+(\d+) kB", status)
    return int(found.group(1)) / 1024 if found else float("nan")


def _loop(until: threading.Event, pause_s: float, step: Callable[[], None]) -> None:
    for _ in range(MAX_ROUNDS):
        if until.is_set():
            return
        try:
            step()
        except (OSError, ValueError, KeyError, IndexError, WebSocketException):
            pass  # a refusal, a drop: the attacker tries again
        until.wait(pause_s)


def _slow_reader(port: int, until: threading.Event) -> None:
    def step() -> None:
        client = Client(port)
        if not client.upgraded:
            client.sock.close()
            return
        client.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        for opcode, payload in client.frames(2.0):
            op = json.loads(payload) if opcode == 1 else {}
            if op.get("op") == "advertise":
                for channel in op["channels"]:
                    if channel["topic"] == SAMPLE:
                        client.send_json({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channel["id"]}]})
        while not until.is_set():  # never reads; ends when the server drops it
            if until.wait(1.0):
                break
            try:
                client.send_json({"op": "getParameters", "parameterNames": ["x"], "id": "x"})  # noticing a drop
            except OSError:
                break
        client.sock.close()

    _loop(until, 0.5, step)


def _flapper(port: int, until: threading.Event) -> None:
    def step() -> None:
        with FoxgloveClient.connected(port) as fox:
            if not fox.pump(lambda: SAMPLE in fox.channels, 5):
                return
            channel = fox.channels[SAMPLE]["id"]
            for i in range(MAX_ROUNDS):
                if until.is_set():
                    return
                fox.ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": i, "channelId": channel}]}))
                fox.ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": [i]}))
                FLAPS[0] += 1
                fox.pump(lambda: False, 0.01)  # reads what comes, as the app does

    _loop(until, 0.5, step)


def _junk(ports: Callable[[], list[int]], until: threading.Event) -> None:
    rng = random.Random(38)

    def step() -> None:
        for port in ports():
            with socket.create_connection(("127.0.0.1", port), timeout=1.0) as sock:
                sock.sendall(rng.randbytes(4096))
        client = Client(ports()[0])  # after a valid upgrade: frames that are no frames, then a torn one
        with client.sock:
            client.sock.sendall(rng.randbytes(2048) + frame(0x2, rng.randbytes(300))[:-7])

    _loop(until, 0.02, step)


def _never_reads(runtime: Path, until: threading.Event) -> None:
    """A tool on the run's hub that proves the token, says HELLO and never reads; when dropped, it comes back."""
    encoder = FrameEncoder()

    def step() -> None:
        info = _announced(runtime)
        if info is None:
            return
        with socket.create_connection(("127.0.0.1", int(info["hub"].rsplit(":", 1)[1])), timeout=3.0) as sock:
            tool_side(sock, info["token"], "hub")
            sock.sendall(encoder.encode(TOOL_HELLO).wire)
            STALLED[0] += 1
            beat = m.Heartbeat(uptime_ms=0, mode=0, battery_mv=0, rx_frames=0, rx_rejects=0, rx_lost=0,
                               log_first_sample=0, log_next_sample=0, episode=0, signing_rejects=0)
            while not until.wait(1.0):
                sock.sendall(encoder.encode(beat).wire)  # fails once the hub has closed it: connect again

    _loop(until, 0.5, step)


def _tool_recording(folder: Path, proc: subprocess.Popen[str]) -> str:
    """What the `dive record` beside the run recorded, its exit and its last line."""
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    last = [line for line in err.splitlines() if line.strip()][-1:] or [""]
    files = sorted(folder.glob("*.mcap"))
    if not files:
        return f"no recording (exit {proc.returncode}: {last[0]})"
    indices = sorted({json.loads(msg.data)["sample"] for f in files for msg in read_recording(f, {SAMPLE}).messages})
    missing = (indices[-1] - indices[0] + 1 - len(indices)) if indices else 0
    return f"{len(indices)} samples, {missing} missing between its first and last; exit {proc.returncode}: {last[0]}"


def _surface_ack_s(runtime: Path) -> float:
    """The owner's CMD_SURFACE through the run's hub, as `dive surface` sends it: seconds from sending to its ACK."""
    from groundstation.errors import GroundStationError
    from groundstation.links import make_link
    from groundstation.session import control
    from groundstation.session.agent_session import Session, SessionConfig

    os.environ["DIVE_RUNTIME_DIR"] = str(runtime)
    try:
        with Session(make_link("hub://"), SessionConfig(backfill=False, fetch_params=False)) as session:
            began = time.monotonic()
            answer = control.surface(session)
            return time.monotonic() - began if answer.accepted else float("nan")
    except GroundStationError as e:
        print(f"  the tool's surface failed: {e}")
        return float("nan")


def job(folder: Path, speed: int, seed: int, seconds: float, attack: str | None) -> Figures:
    runtime = folder / "runtime"
    env = {**os.environ, "DIVE_RUNTIME_DIR": str(runtime), "DIVE_CACHE_DIR": str(folder / "cache"),
           "PYTHONPATH": str(ROOT)}
    env.pop("DIVE_URL", None)
    out = folder / "rec"
    # low_batt_v at its floor: the simulated battery (2 h, 72 s at --speed 100) never ends a long run by surfacing
    proc = subprocess.Popen([*DIVE, "run", f"sim://?speed={speed}&seed={seed}", "--out", str(out),
                             "--foxglove", "0", "--param", "low_batt_v=3.0"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    port = int(re.search(r"ws://127\.0\.0\.1:(\d+)", proc.stderr.readline()).group(1))  # type: ignore[union-attr]
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(proc.stderr), daemon=True).start()  # type: ignore[arg-type]
    deadline = time.monotonic() + 180  # the first start compiles the simulator
    while _hub_port(runtime) is None and time.monotonic() < deadline:
        time.sleep(0.2)
    hub = _hub_port(runtime)
    until = threading.Event()
    threads: list[threading.Thread] = []
    recorder: subprocess.Popen[str] | None = None
    if attack == "hub":
        recorder = subprocess.Popen([*DIVE, "record", "--out", str(folder / "tool-rec")], env=env,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        threads += [threading.Thread(target=_never_reads, args=(runtime, until), daemon=True)
                    for _ in range(HUB_STALLS)]
        for thread in threads:
            thread.start()
    elif attack == "foxglove":
        def ports() -> list[int]:
            return [port, *([hub] if hub is not None else [])]

        # the flappers first: the door lets 8 clients through, and the slow readers are to take the other slots
        threads += [threading.Thread(target=_flapper, args=(port, until), daemon=True) for _ in range(FLAPPERS)]
        threads += [threading.Thread(target=_slow_reader, args=(port, until), daemon=True)
                    for _ in range(SLOW_READERS)]
        threads.append(threading.Thread(target=_junk, args=(ports, until), daemon=True))
        for i, thread in enumerate(threads):
            thread.start()
            if i == FLAPPERS - 1:
                time.sleep(2.0)
    time.sleep(seconds)
    ack_s = _surface_ack_s(runtime)
    began = time.monotonic()
    surfaced = subprocess.run([*DIVE, "surface"], env=env, capture_output=True, text=True, timeout=60)
    surface_s = time.monotonic() - began
    if surfaced.returncode != 0:
        print(f"  ({attack or 'control'}) dive surface: {surfaced.stderr.strip()[-300:]}")
    peak_mb = _peak_mb(proc.pid)
    until.set()
    proc.send_signal(2)
    try:
        proc.wait(60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    for thread in threads:
        thread.join(5)
    record = _tool_recording(folder / "tool-rec", recorder) if recorder is not None else ""
    dropped = sum(int(n) for n in re.findall(r"(\d+) tools attached to the run's hub were dropped", "".join(lines)))
    said = sum(int(n) for n in re.findall(r"(\d+) samples (?:lost|not backfilled)", "".join(lines)))
    [recording] = sorted(out.glob("*.mcap"))
    samples = read_recording(recording, {SAMPLE}).messages
    indices = sorted({json.loads(msg.data)["sample"] for msg in samples})
    times = [msg.log_time_ns for msg in samples]
    rate = len(samples) / max(1e-9, (max(times) - min(times)) / 1e9)
    missing = (indices[-1] - indices[0] + 1 - len(indices)) if indices else 0
    return Figures(rate, missing, said, peak_mb, surface_s, surfaced.returncode == 0, ack_s, dropped, record)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=int, default=100)
    parser.add_argument("--seconds", type=float, default=25.0)
    parser.add_argument("--seed", type=int, default=38)
    parser.add_argument("--attack", choices=("foxglove", "hub"), default="foxglove",
                        help="foxglove: slow readers, flappers and junk on every listener; hub: tools on the hub that "
                             "never read, beside a `dive record` that does")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        control = job(Path(tmp) / "control", args.speed, args.seed, args.seconds, attack=None)
        attacked = job(Path(tmp) / "attack", args.speed, args.seed, args.seconds, attack=args.attack)
    if args.attack == "foxglove":
        print(f"the attack: {FLAPS[0]} subscription flaps from {FLAPPERS} clients, {SLOW_READERS} slow readers, junk "
              "on the Foxglove and hub ports")
    else:
        print(f"the attack: {HUB_STALLS} tools on the hub that never read ({STALLED[0]} connections in all), the run "
              f"dropped {attacked.tools_dropped} for falling behind; a `dive record` on the hub beside them: "
              f"{attacked.record}")
    for name, f in (("control", control), ("attack", attacked)):
        print(f"{name:8s} {f.rate:7.0f} SAMPLEs/s recorded, {f.missing} missing, {f.said_lost} said lost, peak "
              f"{f.peak_mb:6.1f} MB, CMD_SURFACE ACKed {f.ack_s:.3f} s after it was sent; `dive surface` "
              f"{'exit 0' if f.surface_ok else 'FAILED'} in {f.surface_s:.2f} s (its start included)")
    extra_mb = attacked.peak_mb - control.peak_mb
    print(f"attack / control: rate {attacked.rate / control.rate:.3f}, memory {extra_mb:+.1f} "
          f"MB ({attacked.peak_mb / control.peak_mb:.2f}x), surface ACK {attacked.ack_s / control.ack_s:.2f}x, "
          f"`dive surface` {attacked.surface_s / control.surface_s:.2f}x; "
          f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
