"""Firmware resources: the Teensy build's flash and RAM per learner; instructions per step on the emulated M4.

Run: .venv/bin/python benchmarks/firmware_bench.py [--episodes N]

Flash and RAM: `make -C firmware teensy` with the learner's arenas sized for the paper learner (S = 101)
and for the actuator-state learner (S = 301), read with arm-none-eabi-size; RAM = .data + .bss + the
stack peak measured on the emulated board (the same core, painted stack).

Instructions: the QEMU build runs under `-icount shift=0` (one instruction = 1 ns of virtual time) and
times each agent step on the 25 MHz APB timer (40 instructions per tick); a calibration loop of a known
instruction count is the anchor, measured in the same run. `dive run` drives the learning episodes.
Shares of a period assume one instruction per cycle at 72 MHz (the MK20DX256's clock).
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from rich.console import Console

from learning import LearnerConfig, learner_memory_bytes, n_states
from learning.presets import learner_preset
from protocol import Mode
from protocol.parameters import SNAPSHOT_BYTES_PER_STATE, SNAPSHOTS_HELD
from simulator.firmware_qemu import FIRMWARE_DIR, QemuAgent, QemuConfig, build_elf

CPU_HZ = 72e6
GOAL_RAM_BYTES = 32 * 1024
GOAL_FLASH_BYTES = 96 * 1024
GOAL_STEP_SHARE = 0.05
PERIOD_S = {Mode.LEARNING: 0.1, Mode.RECOVERING: 0.025, Mode.IDLE: 0.1, Mode.SURFACING: 0.1,
            Mode.HOVER: 0.025, Mode.PAUSED: 0.025}
LEARNERS: dict[str, tuple[LearnerConfig, list[str]]] = {
    "paper (S = 101)": (LearnerConfig(), []),
    "actuator3 (S = 301)": (learner_preset("actuator3"), ["--param", "act_bins=3"]),
}
_FIELDS = re.compile(r"(\w+)=(\d+)")
console = Console()


def arena_flags(config: LearnerConfig) -> str:
    """The learner's and the snapshot store's arenas sized for this learner (what its build would hold)."""
    s = n_states(config)
    learner_bytes = learner_memory_bytes(config) + 4 * s  # + the Jacobi sweep buffer
    return f"-DLEARNER_ARENA_BYTES={learner_bytes}u -DDUMPS_ARENA_BYTES={SNAPSHOTS_HELD * SNAPSHOT_BYTES_PER_STATE * s}u"


@dataclass
class Sizes:
    text: int
    data: int
    bss: int


def arm_size(elf: Path) -> Sizes:
    out = subprocess.run(["arm-none-eabi-size", str(elf)], capture_output=True, text=True, check=True).stdout
    text, data, bss = (int(x) for x in out.splitlines()[1].split()[:3])
    return Sizes(text, data, bss)


def teensy_build(flags: str, build_dir: Path) -> Sizes | str:
    """The Teensy ELF's sizes, or why it could not be built."""
    done = subprocess.run(["make", "-s", "-C", str(FIRMWARE_DIR), "teensy", f"BUILD={build_dir}",
                           f"TEENSY_EXTRA_CFLAGS={flags}"], capture_output=True, text=True, check=False)
    elves = sorted(build_dir.rglob("*.elf"))
    if done.returncode != 0 or not elves:
        lines = [x for x in (done.stderr or done.stdout).splitlines() if x.strip()]
        return lines[-1] if lines else "no ELF produced"
    return arm_size(elves[0])


@dataclass
class StepStats:
    steps: int
    sum_ticks: int
    max_ticks: int


@dataclass
class QemuRun:
    instructions_per_tick: float
    calibration_ticks: int
    steps: dict[tuple[int, int], StepStats]  # (mode, planning) -> totals since boot
    max_sweeps: int
    stack_peak_bytes: int
    learner_bytes: int
    episodes: int


def qemu_run(config: LearnerConfig, run_args: list[str], episodes: int, work: Path) -> QemuRun:
    """Build for this learner, run `episodes` learning episodes under icount, parse UART1's counters."""
    elf = build_elf(work / "build", arena_flags(config))
    diag = work / "uart1.txt"
    with QemuAgent(QemuConfig(seed=1, bench=True, icount=True, diag_path=diag), elf) as agent:
        dive = [sys.executable, "-c", "import sys; sys.argv[0] = 'dive'; from groundstation.cli import main; main()"]
        done = subprocess.run([*dive, "run", agent.address, "--episodes", str(episodes), "--viewer", "none",
                               "--out", str(work / "run.mcap"), *run_args], capture_output=True, text=True,
                              timeout=900, check=False)
        if done.returncode != 0:
            raise SystemExit(f"dive run against QEMU failed: {done.stderr.strip().splitlines()[-1:]}")
    lines = diag.read_text().splitlines()
    cal = dict(_FIELDS.findall(next(x for x in lines if x.startswith("CAL"))))
    steps: dict[tuple[int, int], StepStats] = {}
    sweeps: dict[str, str] = {}
    for line in lines:
        fields = dict(_FIELDS.findall(line))
        if line.startswith("BENCH"):
            key = (int(fields["mode"]), int(fields["planning"]))
            steps[key] = StepStats(int(fields["steps"]), int(fields["sum_ticks"]), int(fields["max_ticks"]))
        elif line.startswith("SWEEPS"):
            sweeps = fields
    if not sweeps:
        raise SystemExit("the firmware printed no counters (no episode ended)")
    return QemuRun(int(cal["instructions"]) / int(cal["ticks"]), int(cal["ticks"]), steps, int(sweeps["max"]),
                   int(sweeps["stack_peak_bytes"]), int(sweeps["learner_bytes"]), int(sweeps["episode"]))


def share(instructions: float, period_s: float) -> float:
    return instructions / (CPU_HZ * period_s)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=8, help="learning episodes per learner on QEMU")
    args = parser.parse_args()
    for tool in ("arm-none-eabi-gcc", "arm-none-eabi-size", "qemu-system-arm", "make"):
        if shutil.which(tool) is None:
            raise SystemExit(f"{tool} not found: the firmware benchmark needs it")
    rows: list[str] = []
    step_rows: list[str] = []
    with tempfile.TemporaryDirectory(prefix="firmware-bench-") as scratch:
        for name, (config, run_args) in LEARNERS.items():
            work = Path(scratch) / name.split()[0]
            work.mkdir()
            with console.status(f"{name}: Teensy build"):
                teensy = teensy_build(arena_flags(config), work / "teensy")
            with console.status(f"{name}: {args.episodes} episodes on QEMU (icount)"):
                run = qemu_run(config, run_args, args.episodes, work)
            console.print(f"{name}: calibration loop 2,000,000 instructions = {run.calibration_ticks} ticks, "
                          f"{run.instructions_per_tick:.2f} instructions per tick (anchor: 40.00, ratio "
                          f"{run.instructions_per_tick / 40.0:.4f})")
            if isinstance(teensy, Sizes):
                flash = teensy.text + teensy.data
                ram = teensy.data + teensy.bss + run.stack_peak_bytes
                rows.append(f"| {name} | {flash} ({flash / GOAL_FLASH_BYTES:.0%} of the 96 KB goal) | "
                            f"{ram} = {teensy.data} data + {teensy.bss} bss + {run.stack_peak_bytes} stack peak "
                            f"({ram / GOAL_RAM_BYTES:.0%} of the 32 KB goal) | {run.learner_bytes} |")
            else:
                rows.append(f"| {name} | not built: {teensy} | - | {run.learner_bytes} |")
            ipt = run.instructions_per_tick
            for (mode, planning), st in sorted(run.steps.items()):
                period = PERIOD_S.get(Mode(mode), 0.1)
                mean = st.sum_ticks / st.steps * ipt
                peak = st.max_ticks * ipt
                what = Mode(mode).name + (" + planning slice" if planning else "")
                step_rows.append(
                    f"| {name} | {what} | {st.steps} | {mean:,.0f} | {peak:,.0f} | {period * 1e3:.0f} ms | "
                    f"{share(mean, period):.2%} | {share(peak, period):.2%} |")
            step_rows.append(f"| {name} | most sweeps in one planning run | {run.max_sweeps} | | | | | |")
    console.print("\n| Teensy build | flash B | RAM B | learner arrays B |\n|---|---|---|---|")
    for row in rows:
        console.print(row, markup=False)
    console.print("\n| learner | step | steps | instructions mean | instructions max | period | mean share at "
                  "72 MHz | max share |\n|---|---|---|---|---|---|---|---|", markup=False)
    for row in step_rows:
        console.print(row, markup=False)


if __name__ == "__main__":
    main()
