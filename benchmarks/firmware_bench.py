"""Firmware resources: the Teensy build's flash and RAM per learner; instructions per step on the emulated M4.

Run: .venv/bin/python benchmarks/firmware_bench.py [--episodes N] [--learner NAME ...]

Flash and RAM: the variants of `make -C firmware teensy`, whose learner storage fits the paper
learner (S = 101), the actuator-state learner (S = 301) and the shared-model learner with 13 actuator bins
(S = 1301), read by firmware/boards/teensy/image_size.sh from the linker script's own symbols (Berkeley
`size` counts .data as text in these images); RAM = USB buffers + .data + .bss, and what is left of the 64 KB
is the stack's and the heap's; the stack peak measured on the emulated board (the same core, painted stack)
shows whether that suffices.

Instructions: the QEMU build runs under `-icount shift=0` (one instruction = 1 ns of virtual time) and
times each agent step on the 25 MHz APB timer (40 instructions per tick); a calibration loop of a known
instruction count is the anchor, measured in the same run. `dive run` drives the learning episodes.
Shares of a period assume one instruction per cycle at 72 MHz (the MK20DX256's clock). Per episode: the
instructions of the steps that ran planning (recovery controller included), and the steps longer than
their period at 72 MHz ("late", counted by the board), which must stay 0.
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
from protocol.parameters import snapshot_ram_bytes
from simulator.serve.firmware_qemu import FIRMWARE_DIR, QemuAgent, QemuConfig, build_elf

CPU_HZ = 72e6
GOAL_RAM_BYTES = 32 * 1024
GOAL_FLASH_BYTES = 96 * 1024
TEENSY_STACK_BYTES = 4096  # what `make teensy` requires left free for the stack (its TEENSY_STACK_BYTES)
PERIOD_S = {Mode.LEARNING: 0.1, Mode.RECOVERING: 0.025, Mode.IDLE: 0.1, Mode.SURFACING: 0.1,
            Mode.HOVER: 0.025, Mode.PAUSED: 0.025}
# name -> (learner, `dive run` arguments that select it, the Teensy variant of `make teensy`)
LEARNERS: dict[str, tuple[LearnerConfig, list[str], str]] = {
    "paper (S = 101)": (LearnerConfig(), [], "paper"),
    "actuator3 (S = 301)": (learner_preset("actuator3"), ["--param", "act_bins=3"], "actuator3"),
    # Set in this order: shared_model first, so that every intermediate learner fits the arena.
    "shared-bins13-diff4 (S = 1301)": (learner_preset("shared-bins13-diff4"), [
        "--param", "shared_model=1", "--param", "in_place_sweeps=1", "--param", "p_explore_start=0",
        "--param", "vel_diff_steps=4", "--param", "act_bins=13"], "shared-bins13"),
    # The filter learner before filtered depth (docs/learners.md lists the learners and which one `hardware` names).
    "shared-z20-bins7-diff8-term100-vpen1 (S = 1401)": (learner_preset("shared-z20-bins7-diff8-term100-vpen1"), [
        "--param", "shared_model=1", "--param", "in_place_sweeps=1", "--param", "p_explore_start=0",
        "--param", "vel_diff_steps=8", "--param", "term_reward=-100", "--param", "vel_penalty=1",
        "--param", "act_bins=7", "--param", "z_cells=20"], "shared-z20"),
}
POLICY_BITS_PER_STATE = 2  # the shared learner's policy (firmware/src/shared.c), in whole words
_FIELDS = re.compile(r"(\w+)=(\d+)")


def arena_flags(config: LearnerConfig) -> str:
    """The learner's and the snapshot store's arenas sized for this learner (what its build would hold)."""
    s = n_states(config)
    if config.shared_model:  # in-place sweeps: no sweep buffer; the policy bits on top
        learner_bytes = learner_memory_bytes(config) + (-(-s * POLICY_BITS_PER_STATE // 8) + 3) // 4 * 4
    else:
        learner_bytes = learner_memory_bytes(config) + 4 * s  # + the Jacobi sweep buffer
    dumps_bytes = snapshot_ram_bytes(s, config.shared_model)
    return f"-DLEARNER_ARENA_BYTES={learner_bytes}u -DDUMPS_ARENA_BYTES={dumps_bytes}u"


@dataclass
class Sizes:
    flash: int
    ram: int
    usb: int
    data: int
    bss: int
    free: int  # RAM left for the stack and the heap


IMAGE_SIZE = FIRMWARE_DIR / "boards" / "teensy" / "image_size.sh"
_IMAGE_SIZE_LINE = re.compile(r"flash\s+(\d+) B .*RAM\s+(\d+) B .*USB (\d+), data (\d+), bss (\d+)\).*"
                              r"free for stack and heap\s+(\d+) B")


def image_size(elf: Path) -> Sizes:
    """One image's flash and RAM as the build's own check reads them (image_size.sh; stack need 0: report only)."""
    out = subprocess.run(["sh", str(IMAGE_SIZE), str(elf), elf.parent.name, "0"], capture_output=True, text=True,
                         check=True).stdout
    found = _IMAGE_SIZE_LINE.search(out)
    if found is None:
        raise SystemExit(f"image_size.sh printed an unexpected line for {elf}: {out.strip()}")
    return Sizes(*(int(g) for g in found.groups()))


def teensy_builds(build_dir: Path) -> dict[str, Sizes] | str:
    """Sizes of each Teensy variant of `make -C firmware teensy`, or why it could not be built."""
    done = subprocess.run(["make", "-s", "-C", str(FIRMWARE_DIR), "teensy", f"BUILD={build_dir}"],
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        lines = [x for x in (done.stderr or done.stdout).splitlines() if x.strip()]
        return lines[-1] if lines else "make teensy failed"
    return {elf.parent.name: image_size(elf) for elf in sorted((build_dir / "teensy").glob("*/agent.elf"))}


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
    late_steps: int
    plan_waits: int
    forced_plans: int
    plan_ticks: list[int]  # per episode: ticks of the steps that ran its planning
    sweeps: list[int]  # per episode


def qemu_run(config: LearnerConfig, run_args: list[str], episodes: int, work: Path) -> QemuRun:
    """Build for this learner, run `episodes` learning episodes under icount, parse UART1's counters."""
    elf = build_elf(work / "build", arena_flags(config))
    diag = work / "uart1.txt"
    with QemuAgent(QemuConfig(seed=1, bench=True, icount=True, diag_path=diag), elf) as agent:
        dive = [sys.executable, "-c", "import sys; sys.argv[0] = 'dive'; from groundstation.cli.app import main; main()"]  # noqa: E501
        done = subprocess.run([*dive, "run", agent.address, "--episodes", str(episodes), "--viewer", "none",
                               "--out", str(work / "run.mcap"), *run_args], capture_output=True, text=True,
                              timeout=900, check=False)
        if done.returncode != 0:
            raise SystemExit(f"dive run against QEMU failed: {done.stderr.strip().splitlines()[-1:]}")
    lines = diag.read_text().splitlines()
    cal = dict(_FIELDS.findall(next(x for x in lines if x.startswith("CAL"))))
    steps: dict[tuple[int, int], StepStats] = {}
    sweeps: dict[str, str] = {}
    plan_ticks: list[int] = []
    per_episode: list[int] = []
    for line in lines:
        fields = dict(_FIELDS.findall(line))
        if line.startswith("BENCH"):
            key = (int(fields["mode"]), int(fields["planning"]))
            steps[key] = StepStats(int(fields["steps"]), int(fields["sum_ticks"]), int(fields["max_ticks"]))
        elif line.startswith("SWEEPS"):
            sweeps = fields
            if int(fields["episode"]) > 0:  # episode 0: the plan on the empty model at boot
                plan_ticks.append(int(fields["plan_ticks"]))
                per_episode.append(int(fields["last"]))
    if not sweeps:
        raise SystemExit("the firmware printed no counters (no episode ended)")
    return QemuRun(int(cal["instructions"]) / int(cal["ticks"]), int(cal["ticks"]), steps, int(sweeps["max"]),
                   int(sweeps["stack_peak_bytes"]), int(sweeps["learner_bytes"]), int(sweeps["episode"]),
                   int(sweeps["late_steps"]), int(sweeps["plan_waits"]), int(sweeps["forced_plans"]), plan_ticks,
                   per_episode)


def share(instructions: float, period_s: float) -> float:
    return instructions / (CPU_HZ * period_s)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=8, help="learning episodes per learner on QEMU")
    parser.add_argument("--learner", action="append", choices=[n.split()[0] for n in LEARNERS],
                        help="only these learners (repeatable; default all)")
    args = parser.parse_args()
    chosen = {n: v for n, v in LEARNERS.items() if not args.learner or n.split()[0] in args.learner}
    for tool in ("arm-none-eabi-gcc", "arm-none-eabi-size", "arm-none-eabi-nm", "qemu-system-arm", "make"):
        if shutil.which(tool) is None:
            raise SystemExit(f"{tool} not found: the firmware benchmark needs it")
    console = Console(stderr=True)
    rows: list[str] = []
    step_rows: list[str] = []
    plan_rows: list[str] = []
    with tempfile.TemporaryDirectory(prefix="firmware-bench-") as scratch:
        with console.status("make -C firmware teensy"):
            teensy_sizes = teensy_builds(Path(scratch) / "teensy-build")
        for name, (config, run_args, variant) in chosen.items():
            work = Path(scratch) / name.split()[0]
            work.mkdir()
            teensy = teensy_sizes if isinstance(teensy_sizes, str) else teensy_sizes.get(variant, "no such variant")
            with console.status(f"{name}: {args.episodes} episodes on QEMU (icount)"):
                run = qemu_run(config, run_args, args.episodes, work)
            print(f"{name}: calibration loop 2,000,000 instructions = {run.calibration_ticks} ticks, "
                          f"{run.instructions_per_tick:.2f} instructions per tick (anchor: 40.00, ratio "
                          f"{run.instructions_per_tick / 40.0:.4f})")
            if isinstance(teensy, Sizes):
                rows.append(f"| {name} | {teensy.flash:,} ({teensy.flash / GOAL_FLASH_BYTES:.0%} of the 96 KB goal) | "
                            f"{teensy.ram:,} = {teensy.usb:,} USB + {teensy.data:,} data + {teensy.bss:,} bss "
                            f"({teensy.ram / GOAL_RAM_BYTES:.0%} of the 32 KB goal) | {teensy.free:,} "
                            f"(needs {TEENSY_STACK_BYTES:,}) | {run.stack_peak_bytes:,} | {run.learner_bytes:,} |")
            else:
                rows.append(f"| {name} | not built: {teensy} | - | - | {run.stack_peak_bytes:,} | "
                            f"{run.learner_bytes:,} |")
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
            instr = [t * ipt for t in run.plan_ticks]
            mean_instr = sum(instr) / len(instr) if instr else 0.0
            mean_sweeps = sum(run.sweeps) / max(len(run.sweeps), 1)
            plan_rows.append(
                f"| {name} | {run.episodes} | {mean_sweeps:.1f} / {max(run.sweeps, default=0)} | "
                f"{mean_instr:,.0f} / {max(instr, default=0):,.0f} | {mean_instr / CPU_HZ:.2f} s / "
                f"{max(instr, default=0) / CPU_HZ:.2f} s | {run.plan_waits} | {run.forced_plans} | "
                f"**{run.late_steps}** |")
    # Plain prints: the tables go into docs/firmware.md as they are (rich would wrap them).
    print("\n| Teensy build | flash B | RAM B | free for stack and heap B | stack peak B (QEMU) | learner arrays B |"
          "\n|---|---|---|---|---|---|")
    print("\n".join(rows))
    print("\n| learner | step | steps | instructions mean | instructions max | period | mean share at 72 MHz | "
          "max share |\n|---|---|---|---|---|---|---|---|")
    print("\n".join(step_rows))
    print("\n| learner | episodes | sweeps per plan mean / max | instructions of the planning steps per episode mean "
          "/ max | at 72 MHz | recovery steps waiting for a plan | forced plans | late steps |\n"
          "|---|---|---|---|---|---|---|---|")
    print("\n".join(plan_rows))


if __name__ == "__main__":
    main()
