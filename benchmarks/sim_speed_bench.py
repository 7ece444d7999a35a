"""How fast the virtual agent runs with --speed max while streaming to a client, against the bare plant.

Run: python benchmarks/sim_speed_bench.py [--seconds 8] [--preset hardware]
Prints agent seconds per wall second of (a) `python -m simulator serve --speed max` with a TCP client
that decodes every frame, learning from CMD_START on, and (b) the plant stepping alone at the same
control periods (no program, no protocol, no server) as the anchor measured in this run, and their ratio.

The agent's battery lasts 2 h of agent time (under 2 s of wall time at 5 000x), after which it surfaces and idles
at one SAMPLE a second, which would flatter the figure: the served agent gets `low_batt_v = 3.0` (below the
discharge curve's 3.4 V floor) so that it keeps learning, and the client counts the SAMPLEs it saw outside
the diving modes (only those before CMD_START took effect).
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from typing import NamedTuple

import numpy as np

from groundstation.links.tcp import RECEIVE_BUFFER_BYTES
from protocol import FrameEncoder, Mode, StreamDecoder, compiled, messages
from simulator.parameters import preset
from simulator.plant.model import Plant

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_NOT_DIVING = (int(Mode.IDLE), int(Mode.SURFACING))
READ_BYTES = 65536  # what groundstation/links/tcp.py asks for per read


def plant_alone(preset_name: str, wall_s: float) -> float:
    """Agent seconds per wall second of Plant.step at the learner's and the recovery controller's periods."""
    params = preset(preset_name)
    plant = Plant(params, np.random.default_rng(0))
    dt_learn, dt_recover = params.control_period_s, params.recovery_period_s
    plant.step(dt_learn)
    simulated = 0.0
    start = time.perf_counter()
    while time.perf_counter() - start < wall_s:
        for _ in range(100):  # the agent's mix: 4 recovery periods for each learner period
            plant.step(dt_learn)
            for _ in range(4):
                plant.step(dt_recover)
        simulated += 100 * (dt_learn + 4 * dt_recover)
    return simulated / (time.perf_counter() - start)


class Served(NamedTuple):
    factor: float  # agent seconds per wall second, as the client saw them
    frames: int  # frames the client decoded
    client_busy: float  # share of the wall time the client spent decoding (near 1: it set the pace)
    per_server_cpu_s: float | None  # agent seconds per CPU second of the server process (Linux only)
    not_diving: int  # SAMPLEs the client saw in IDLE or SURFACING


def cpu_s(pid: int) -> float | None:
    """User + system CPU seconds of a process, from /proc (None where there is no /proc)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            fields = stat.read().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def served(preset_name: str, wall_s: float) -> Served:
    """What a client of `serve --speed max` that decodes every frame sees.

    On a shared machine the client and the agent compete for cores: the agent's speed per CPU second
    of its own process is the figure that does not depend on what else runs.
    """
    assert compiled.wait(300)  # the client decodes on the compiled path, as a warmed-up ground station does
    params = tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False)
    with params:
        params.write("low_batt_v = 3.0\n")
    proc = subprocess.Popen(
        [sys.executable, "-m", "simulator", "serve", "--tcp", "127.0.0.1:0", "--speed", "max", "--seed", "1",
         "--preset", preset_name, "--params", params.name], stdout=subprocess.PIPE, text=True, cwd=ROOT,
    )
    try:
        assert proc.stdout is not None
        host, port = proc.stdout.readline().strip().removeprefix("tcp://").rsplit(":", 1)
        # The client reads as the ground station's TCP link does (groundstation/links/tcp.py): its small receive
        # buffer set before connecting, reads of up to 64 KiB. With the kernel's default (autotuned to megabytes)
        # a client that falls behind reads half a megabyte at a time and decodes each frame 2.5x slower for it.
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
        sock.connect((host, int(port)))
        decoder = StreamDecoder()
        sample = messages.Sample
        sock.sendall(FrameEncoder().encode(messages.StartLearning()).wire)
        first: tuple[float, int] | None = None
        cpu_first: float | None = None
        last_t_us = 0
        frames = 0
        waiting_s = 0.0
        not_diving = 0  # SAMPLEs in IDLE or SURFACING
        while True:
            before = time.perf_counter()
            data = sock.recv(READ_BYTES)
            if not data:
                break
            now = time.perf_counter()
            if first is not None:
                waiting_s += now - before
            for frame in decoder.feed(data):
                frames += 1
                message = frame.message
                if type(message) is sample and message.mode in _NOT_DIVING:
                    not_diving += 1
                t_us = getattr(message, "t_us", None)
                if t_us is not None:
                    last_t_us = t_us
                    if first is None:
                        first = (now, t_us)
                        cpu_first = cpu_s(proc.pid)
            if first is not None and now - first[0] >= wall_s:
                break
        cpu_last = cpu_s(proc.pid)
        sock.close()
        assert first is not None, "no frame with agent time arrived"
        elapsed_s = time.perf_counter() - first[0]
        agent_s = (last_t_us - first[1]) / 1e6
        per_cpu = agent_s / (cpu_last - cpu_first) if cpu_first is not None and cpu_last is not None else None
        return Served(agent_s / elapsed_s, frames, 1.0 - waiting_s / elapsed_s, per_cpu, not_diving)
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=10)
        os.unlink(params.name)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=8.0, help="wall seconds per measurement")
    parser.add_argument("--preset", default="hardware")
    args = parser.parse_args()
    anchor = plant_alone(args.preset, min(args.seconds, 3.0))
    factor, frames, client_busy, per_cpu_s, not_diving = served(args.preset, args.seconds)
    print(f"plant alone (anchor)          : {anchor:10.0f} x real time")
    print(f"serve --speed max + TCP client: {factor:10.0f} x real time ({frames} frames decoded)")
    print(f"ratio served / plant alone    : {factor / anchor:10.3f}")
    print(f"client busy decoding          : {client_busy:10.0%} of the wall time (near 100%: the client sets the pace)")
    if per_cpu_s is not None:
        print(f"agent per server CPU second   : {per_cpu_s:10.0f} x (its speed with a core to itself)")
    print(f"SAMPLEs not diving            : {not_diving:10d} (IDLE or SURFACING: before CMD_START, or surfaced)")
    print(f"target 5000x (issue 16)       : {'met' if factor >= 5000 else 'NOT met'}")


if __name__ == "__main__":
    main()
