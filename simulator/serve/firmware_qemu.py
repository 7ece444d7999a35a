"""The C firmware on an emulated Cortex-M4 (QEMU mps2-an386): `dive sim --firmware qemu`.

The whole agent runs inside QEMU: the core, the learner, and the C port of the plant and sensor that
stand in for the water (firmware/boards/qemu). Its link is the board's UART0, a loopback TCP socket we
hand QEMU; the relay (qemu_relay.py) puts it on the address a ground station connects to and tells
the board about each new client on UART2. With --pty, QEMU's own pseudo-terminal is the link.
Agent time is the emulated plant's time: at speed "max" the agent runs as fast as the emulated CPU
goes; a speed factor paces it against QEMU's real clock.

Boot arguments (speed, seed, node id, bench mode, the plant's figures) reach the firmware through QEMU's
generic loader, written into a RAM block the linker script reserves (firmware/boards/qemu/bootargs.h): a plant
file reaches the C plant and sensor without a rebuild.
"""

from __future__ import annotations

import os
import re
import select
import shutil
import signal
import socket
import struct
import subprocess
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType

from simulator.errors import SimulatorError
from simulator.parameters import PlantParams
from simulator.serve.qemu_relay import LinkRelay

FIRMWARE_DIR = Path(__file__).resolve().parents[2] / "firmware"
ELF_ENV = "DIVE_FIRMWARE_ELF"  # a prebuilt QEMU ELF to run instead of building one
QEMU_ENV = "DIVE_QEMU"  # the qemu-system-arm to run
MACHINE = "mps2-an386"
BOOTARGS_ADDR = 0x20000000 + 4 * 1024 * 1024 - 512  # RAM end - BOOTARGS_BYTES (mps2_an386.ld, bootargs.h)
BOOTARGS_MAGIC = 0x41524753
KEY_BYTES = 32
HAS_PLANT_OFFSET, PLANT_OFFSET = 60, 64  # bootargs_raw_t: after the key, then one double per figure
# Every figure the C plant and sensor take, in bootargs.h's BOOTARGS_PLANT order (a test compares the two).
PLANT_FIELDS = (
    "mass_kg", "added_mass_kg", "water_density_kgpm3", "gravity_mps2", "trim_error_fraction",
    "compressibility_m3pm", "drag_kgpm", "floor_depth_m", "stroke_volume_m3", "alpha_max_deg",
    "alpha_rate_dps", "substep_s", "backlash_deg", "dead_band_deg", "control_jitter_s",
    "surface_pressure_pa", "pressure_noise_pa", "pressure_lsb_pa", "pressure_min_pa", "pressure_max_pa",
    "pressure_bias_pa", "pressure_drift_pa_per_s", "pressure_lag_s", "pressure_noise_corr_s",
    "depth_scale_error",
)
UART_BUFFER_BYTES = 16 * 1024  # QEMU's UART sockets' send buffer, ours to receive (Linux doubles both; see uart_pair)
START_TIMEOUT_S = 20.0  # QEMU up and its port listening
_PTY_LINE = re.compile(r"char device redirected to (\S+) \(label serial0\)")


class QemuError(SimulatorError):
    """QEMU or the cross compiler is missing, the firmware does not build, or QEMU did not start."""


@dataclass(frozen=True)
class QemuConfig:
    """How to run the emulated agent."""

    host: str = "127.0.0.1"
    port: int = 0  # 0: a free port
    pty: bool = False  # serve the link on a pseudo-terminal instead of TCP
    speed: float | None = None  # times real time; None = as fast as the emulated CPU goes
    seed: int | None = None  # sensor noise and the learner's tie-break stream (default: random)
    node_id: int = 0  # 0: the board's default
    key: bytes | None = field(default=None, repr=False)  # the 32-byte signing key: never printed
    bench: bool = False  # print instruction counts on UART1 (with icount)
    icount: bool = False  # -icount shift=0: virtual time counts instructions (1 ns each)
    diag_path: Path | None = None  # where UART1 (the board's diagnostics) goes; None = discarded
    plant: PlantParams | None = None  # its PLANT_FIELDS go to the C plant and sensor; None: the built-in preset


def qemu_binary() -> str:
    """The qemu-system-arm to run, or QemuError naming what is missing."""
    found = shutil.which(os.environ.get(QEMU_ENV, "qemu-system-arm"))
    if found is None:
        raise QemuError("qemu-system-arm not found: install qemu-system-arm (or set DIVE_QEMU)")
    return found


def build_elf(build_dir: Path | None = None, arenas: str = "") -> Path:
    """firmware/build/qemu/agent.elf (or under build_dir), made with `make -C firmware qemu` when stale.

    arenas: -D flags sizing the learner and snapshot arenas (default: qemu.mk's, those of the host build).
    """
    prebuilt = os.environ.get(ELF_ENV)
    if prebuilt and build_dir is None and not arenas:
        if not Path(prebuilt).is_file():
            raise QemuError(f"{ELF_ENV}={prebuilt} is not a file")
        return Path(prebuilt)
    if shutil.which("arm-none-eabi-gcc") is None:
        raise QemuError("arm-none-eabi-gcc not found: install gcc-arm-none-eabi and libnewlib-arm-none-eabi")
    if shutil.which("make") is None:
        raise QemuError("make not found: it builds the firmware")
    out = build_dir if build_dir is not None else FIRMWARE_DIR / "build" / "qemu"
    cmd = ["make", "-s", "-C", str(FIRMWARE_DIR), "qemu", f"QEMU_BUILD_DIR={out}"]
    if arenas:
        cmd.append(f"QEMU_ARENAS={arenas}")
    # make must be able to wait for its compilers even where our parent ignored SIGCHLD (inherited).
    done = subprocess.run(cmd, capture_output=True, text=True, check=False,
                          preexec_fn=lambda: signal.signal(signal.SIGCHLD, signal.SIG_DFL))
    if done.returncode != 0:
        lines = [x for x in (done.stderr or done.stdout).splitlines() if x.strip()]
        raise QemuError(f"the QEMU firmware does not build: {lines[-1] if lines else 'make failed'}")
    return out / "agent.elf"


def uart_pair() -> tuple[socket.socket, socket.socket]:
    """A connected loopback TCP pair: (ours, QEMU's end to hand it by fd), both with small fixed buffers.

    Flow control at speed max (qemu_relay.py): QEMU's end holds at most UART_BUFFER_BYTES unsent, so the firmware
    waits once we stop reading. Served by QEMU itself (-serial tcp:...,server=on) the socket was QEMU's to size,
    and Linux autotuned its send buffer to a megabyte and more on loopback: ten minutes of agent time. 16 KiB:
    4 KiB (each of QEMU's one-byte writes is a segment of its own until the queue backs up) ran the firmware at a
    tenth of its speed, a Unix socket (a few hundred bytes of one-byte writes) at about two thirds. The listener
    lives a moment on loopback only, and a connection from anyone but us is refused.
    """
    with socket.create_server(("127.0.0.1", 0)) as listener:
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, UART_BUFFER_BYTES)
        ours = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        ours.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, UART_BUFFER_BYTES)  # before the handshake (window)
        ours.connect(listener.getsockname())
        while True:
            qemu_end, peer = listener.accept()
            if peer == ours.getsockname():
                break
            qemu_end.close()
    for s in (ours, qemu_end):
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    qemu_end.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, UART_BUFFER_BYTES)  # and no autotuning
    return ours, qemu_end


def _bootargs(config: QemuConfig) -> list[str]:
    seed = config.seed if config.seed is not None else int.from_bytes(os.urandom(8), "little")
    speed_milli = 0 if config.speed is None else max(1, round(config.speed * 1000))
    words = [BOOTARGS_MAGIC, config.node_id, seed & 0xFFFFFFFF, (seed >> 32) & 0xFFFFFFFF, speed_milli,
             int(config.bench), int(config.key is not None)]
    if config.key is not None:
        if len(config.key) != KEY_BYTES:
            raise QemuError(f"the signing key must be {KEY_BYTES} bytes")
        words += [int.from_bytes(config.key[i:i + 4], "little") for i in range(0, KEY_BYTES, 4)]
    args: list[str] = []
    for i, word in enumerate(words):
        args += ["-device", f"loader,addr={BOOTARGS_ADDR + 4 * i:#x},data={word:#x},data-len=4"]
    if config.plant is not None:
        args += ["-device", f"loader,addr={BOOTARGS_ADDR + HAS_PLANT_OFFSET:#x},data=0x1,data-len=4"]
        for i, name in enumerate(PLANT_FIELDS):
            # the double's bytes as a little-endian 64-bit word: the loader writes them as they are
            bits = struct.unpack("<Q", struct.pack("<d", float(getattr(config.plant, name))))[0]
            args += ["-device", f"loader,addr={BOOTARGS_ADDR + PLANT_OFFSET + 8 * i:#x},data={bits:#x},data-len=8"]
    return args


class QemuAgent:
    """One QEMU process running the firmware; `address` is what a ground station connects to."""

    def __init__(self, config: QemuConfig, elf: Path | None = None) -> None:
        self.config = config
        self.elf = elf
        self.address = ""
        self._process: subprocess.Popen[bytes] | None = None
        self._output_lines: list[str] = []
        # UART0 (the link) and UART2 (link events) reach QEMU as sockets we made and hand it (see uart_pair).
        self._sockets: list[socket.socket] = []
        self._relay: LinkRelay | None = None

    def start(self) -> str:
        """Build if needed, start QEMU, wait until its link is reachable; returns the address."""
        binary = qemu_binary()
        elf = self.elf if self.elf is not None else build_elf()
        c = self.config
        diag = f"file:{c.diag_path}" if c.diag_path is not None else "null"
        theirs: list[socket.socket] = []
        if c.pty:
            serials = ["pty", diag, "null"]
        else:
            pairs = [uart_pair(), uart_pair()]
            self._sockets = [ours for ours, _ in pairs]
            theirs = [qemu_end for _, qemu_end in pairs]
            serials = [f"chardev:uart{i}" for i in range(len(theirs))]
            serials.insert(1, diag)
        cmd = [binary, "-M", MACHINE, "-nographic", "-monitor", "none", "-kernel", str(elf), *_bootargs(c)]
        for i, qemu_end in enumerate(theirs):
            cmd += ["-chardev", f"socket,id=uart{i},fd={qemu_end.fileno()},server=off"]
        for serial in serials:
            cmd += ["-serial", serial]
        if c.icount:
            cmd += ["-icount", "shift=0"]
        try:
            # One pipe for both: QEMU 7 says where the pty is on stdout ("char device redirected to ..."), its
            # errors on stderr; no UART goes to stdio here.
            self._process = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                             stderr=subprocess.STDOUT, pass_fds=[x.fileno() for x in theirs])
        except OSError as e:
            self.stop()
            raise QemuError(f"cannot start {binary}: {e}") from e
        finally:
            for qemu_end in theirs:
                qemu_end.close()  # QEMU has its copy
        threading.Thread(target=self._read_output, daemon=True).start()
        self._wait_ready()
        if not c.pty:
            link, events = self._sockets
            try:
                self._relay = LinkRelay(c.host, c.port, link, events)
            except OSError as e:
                self.stop()
                raise QemuError(f"cannot listen on {c.host}:{c.port}: {e.strerror or e}") from e
            self.address = self._relay.address
        return self.address

    def _read_output(self) -> None:
        process = self._process
        assert process is not None and process.stdout is not None
        for raw in process.stdout:
            line = raw.decode(errors="replace").strip()
            self._output_lines.append(line)
            found = _PTY_LINE.search(line)
            if found:
                self.address = found.group(1)

    def _wait_ready(self) -> None:
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            if self._process is not None and self._process.poll() is not None:
                why = self._output_lines[-1] if self._output_lines else f"exit code {self._process.returncode}"
                raise QemuError(f"QEMU stopped at start: {why}")
            if self.config.pty:
                if self.address:
                    return
            elif self._link_ready():
                return
            time.sleep(0.05)
        self.stop()
        raise QemuError(f"QEMU's link was not up within {START_TIMEOUT_S:.0f} s")

    def _link_ready(self) -> bool:
        """True once QEMU runs the firmware: its first bytes (HELLO) wait on the link, for the relay to read."""
        return bool(select.select([self._sockets[0]], [], [], 0.0)[0])

    @property
    def running(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def wait(self, timeout_s: float | None = None) -> int | None:
        """QEMU's exit code, or None if it is still running after timeout_s."""
        if self._process is None:
            return None
        try:
            return self._process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            return None

    def stop(self) -> None:
        if self._relay is not None:
            self._relay.close()
            self._relay = None
        for s in self._sockets:
            s.close()
        self._sockets = []
        process, self._process = self._process, None
        if process is None:
            return
        if process.poll() is None:
            process.terminate()
            try:
                process.wait(5.0)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(5.0)

    def __enter__(self) -> QemuAgent:
        self.start()
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()


def serve_qemu(config: QemuConfig) -> None:
    """`serve --firmware qemu`: print the address, run until SIGINT/SIGTERM or QEMU's end."""
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    with QemuAgent(config) as agent:
        print(agent.address, flush=True)
        while not stop.is_set() and agent.running:
            stop.wait(0.2)
    if not stop.is_set():
        raise QemuError("QEMU stopped")
