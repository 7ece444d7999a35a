"""`python -m simulator serve`: parse the options, run the virtual agent, map errors to one line and exit code."""

from __future__ import annotations

import json
import os
import signal
import sys
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any

import typer

from learning import LearnerConfig, LearningError, learner_names, learner_preset
from protocol import SigningError
from protocol.parameters import BY_NAME
from protocol.signing import parse_key
from simulator.agent.mission import MissionConfig
from simulator.agent.params_table import Scope, binding, check_value
from simulator.agent.signing_mark import mark_path
from simulator.errors import ParamsError, SimulatorError, say_error
from simulator.parameters import PlantParams, preset, read_param_table, read_plant_table, with_overrides
from simulator.serve.build import BUILD_DELAY_ENV
from simulator.serve.faults import FaultConfig
from simulator.serve.firmware_qemu import PLANT_FIELDS, QemuConfig, serve_qemu
from simulator.serve.loop import FIRMWARES, AgentServer, ServeConfig

EXIT_BAD_ARGUMENT = 2
MIN_BAUD, MAX_BAUD = 1200, 10_000_000  # below 1200 not even a 1 Hz HEARTBEAT and IDLE SAMPLE fit comfortably


def parse_tcp(text: str) -> tuple[str, int]:
    """HOST:PORT (port 0 = any free port)."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ParamsError(f"--tcp wants HOST:PORT with a port 0-65535, got {text!r}")
    return host.strip("[]"), int(port)


def parse_speed(text: str) -> float | None:
    """A positive factor of real time, or "max" (None)."""
    if text.lower() == "max":
        return None
    try:
        speed = float(text)
    except ValueError:
        speed = -1.0
    if not speed > 0 or speed == float("inf"):
        raise ParamsError(f"--speed wants a positive number or 'max', got {text!r}")
    return speed


def _refuse_for_firmware(learner: str, params: Path | None, firmware: str = "c") -> None:
    """The C firmware starts from the real agent's parameter defaults: learner presets and agent parameters in a
    parameter file would be silently ignored, so they are refused (a ground sets them with PARAM_SET)."""
    if learner != "paper":
        raise ParamsError(f"--learner does not apply to --firmware {firmware}: set the agent's parameters with "
                          "PARAM_SET (dive run --param NAME=VALUE)")
    if params is not None:
        agent_names = sorted(set(read_param_table(params, "name")) & set(BY_NAME))
        if agent_names:
            raise ParamsError(f"{params}: agent parameters ({', '.join(agent_names)}) do not apply to --firmware "
                              f"{firmware}; set them with PARAM_SET (dive run --param NAME=VALUE)")


def with_plant_file(plant: PlantParams, path: Path | None) -> PlantParams:
    """plant with a plant file's figures (`--plant`: its [plant] table only)."""
    return plant if path is None else with_overrides(plant, read_plant_table(path))


def qemu_plant(params: Path | None, plant_file: Path | None) -> PlantParams | None:
    """The plant the QEMU board is given: the hardware preset (its built-in one) with the files' figures, or None.

    Only the figures the C plant and sensor have (PLANT_FIELDS) can reach it; any other is refused, not ignored.
    """
    if params is None and plant_file is None:
        return None
    _refuse_for_firmware("paper", params, "qemu")
    figures = read_param_table(params) if params is not None else {}
    if plant_file is not None:
        figures |= read_plant_table(plant_file)
    plant = with_overrides(preset("hardware"), figures)  # unknown names and figures that cannot work, first
    foreign = sorted(set(figures) - set(PLANT_FIELDS))
    if foreign:
        raise ParamsError(f"the QEMU board's C plant takes hull, actuator and pressure-sensor figures only: "
                          f"{', '.join(foreign)} do not apply to --firmware qemu")
    return plant


def build_delay_s() -> float:
    """$DIVE_SIM_BUILD_DELAY_S, for tests only: the program's build waits this long first, as a cold compile cache
    makes it, so a test sees the starting agent (serve/starting.py) without compiling anything."""
    text = os.environ.get(BUILD_DELAY_ENV, "")
    try:
        delay = float(text) if text else 0.0
    except ValueError:
        delay = -1.0
    if not 0.0 <= delay <= 3600.0:
        raise ParamsError(f"{BUILD_DELAY_ENV} wants seconds 0-3600, got {text!r}")
    return delay


def parse_firmware(text: str) -> str:
    """One of FIRMWARES."""
    if text not in FIRMWARES:
        raise ParamsError(f"--firmware wants one of {', '.join(FIRMWARES)}, got {text!r}")
    return text


def read_key_file(path: Path) -> bytes:
    """The signing key in a key file (64 hex digits, as `dive keygen` writes); refused if others may read it (then
    it is no secret: the ground refuses such a file too, groundstation/session/keys.py)."""
    try:
        mode = path.stat().st_mode
        if mode & 0o077:
            raise ParamsError(f"key file {path} is readable by others (mode {mode & 0o777:03o}); run: chmod 600 {path}")
        return parse_key(path.read_text(encoding="ascii"))
    except (OSError, UnicodeDecodeError, SigningError) as e:
        raise ParamsError(f"cannot read key file {path}: {e}") from e


def apply_param_file(
    path: Path, plant: PlantParams, learner: LearnerConfig, mission: MissionConfig
) -> tuple[PlantParams, LearnerConfig, MissionConfig]:
    """Agent parameter names (PARAM_LIST names) set those; any other key must be a PlantParams field."""
    changes: dict[Scope, dict[str, Any]] = {scope: {} for scope in Scope}
    plant_rest: dict[str, Any] = {}
    for key, value in read_param_table(path, "name").items():
        definition = BY_NAME.get(key)
        if definition is None:
            plant_rest[key] = value
            continue
        if not isinstance(value, int | float):
            raise ParamsError(f"parameter {key!r} must be a number or true/false")
        stored = check_value(definition, float(value))
        where = binding(definition)
        if where.inverted:
            stored = 1.0 - stored
        kind = type(getattr({Scope.LEARNER: learner, Scope.PLANT: plant, Scope.MISSION: mission}[where.scope],
                            where.field))
        changes[where.scope][where.field] = kind(stored)
    plant = with_overrides(replace(plant, **changes[Scope.PLANT]), plant_rest)
    try:
        learner = replace(learner, **changes[Scope.LEARNER])
    except LearningError as e:
        raise ParamsError(f"{path}: {e}") from e
    return plant, learner, replace(mission, **changes[Scope.MISSION])


def serve_on_qemu(tcp: str, pty: bool, speed: str, seed: int | None, key_file: Path | None,
                  refused: list[str], params: Path | None, plant_file: Path | None) -> None:
    """`serve --firmware qemu`: the whole firmware on QEMU, its own C plant; QEMU serves the link."""
    try:
        if refused:
            raise ParamsError(f"--firmware qemu runs its own C plant: {', '.join(refused)} do not apply")
        host, port = parse_tcp(tcp)
        config = QemuConfig(host=host, port=port, pty=pty, speed=parse_speed(speed), seed=seed,
                            key=read_key_file(key_file) if key_file is not None else None,
                            plant=qemu_plant(params, plant_file))
    except SimulatorError as e:
        say_error(str(e))
        raise typer.Exit(EXIT_BAD_ARGUMENT) from None
    try:
        serve_qemu(config)
    except SimulatorError as e:
        say_error(str(e))
        raise typer.Exit(1) from None


def serve(
    tcp: Annotated[str, typer.Option(help="HOST:PORT to listen on (port 0 = a free one).")] = "127.0.0.1:2323",
    pty: Annotated[bool, typer.Option("--pty", help="Serve on a new pseudo-terminal instead of TCP.")] = False,
    speed: Annotated[str, typer.Option(help="Times real time, or 'max'. Agent time is in every frame.")] = "1",
    seed: Annotated[int | None, typer.Option(help="Seed of every random stream (default: random).")] = None,
    preset_name: Annotated[str, typer.Option("--preset", help=(
        "Plant preset: paper (learns, as in the paper's simulation) or hardware (firmware figures, observer in "
        "the loop: much harder)."))] = "paper",
    learner: Annotated[str, typer.Option(help=f"Learner preset: {', '.join(learner_names())}.")] = "paper",
    params: Annotated[Path | None, typer.Option(help="TOML/JSON table of agent parameters and plant figures.")] = None,
    plant_file: Annotated[Path | None, typer.Option("--plant", help=(
        "A plant file (`dive fit --out`): only its \\[plant] table, applied after --params. `dive run --params FILE` "
        "hands its file's \\[plant] table over this way."))] = None,
    drop: Annotated[float, typer.Option(help="Probability of losing a whole frame, each direction.")] = 0.0,
    corrupt: Annotated[float, typer.Option(help="Probability that one byte of a frame is changed.")] = 0.0,
    delay: Annotated[float, typer.Option(help="Latency added each direction, ms of wall time.")] = 0.0,
    disconnect_every: Annotated[
        float, typer.Option(help="Close the connection every S seconds of AGENT time (0 = never).")
    ] = 0.0,
    blackout_below: Annotated[
        float | None, typer.Option(help="The link works only shallower than this depth, m (like the radio).")
    ] = None,
    key_file: Annotated[
        Path | None, typer.Option(help="Signing key file (dive keygen): commands must then be signed.")
    ] = None,
    state_dir: Annotated[
        Path | None, typer.Option(help="Where the signing mark survives restarts (default: beside the key file).")
    ] = None,
    firmware: Annotated[str, typer.Option(help=(
        "The on-board program: python (the reference in simulator/) or c (the C firmware of firmware/, its host "
        "build, made on demand; it starts from the real agent's parameter defaults) or qemu (the whole firmware "
        "with a C port of the hardware plant on an emulated Cortex-M4; only --tcp, --pty, --speed, --seed, "
        "--key-file and the plant's figures of --params and --plant apply)."))] = "python",
    report: Annotated[
        Path | None, typer.Option(help="At exit, write what the faults did and the samples produced (JSON).")
    ] = None,
    baud: Annotated[int | None, typer.Option(help=(
        "Pace the bytes to the ground at a UART's rate, 10 bits a byte (115200: the ESP8266 bridge's serial), "
        "so dumps and log replays compete with SAMPLEs as on the real agent."))] = None,
) -> None:
    """Serve a virtual diving agent over TCP or a pseudo-terminal; prints what to connect to first."""
    if firmware == "qemu":
        refused = {"--preset": preset_name != "paper", "--learner": learner != "paper",
                   "--report": report is not None, "--baud": baud is not None,
                   "fault options": bool(drop or corrupt or delay or disconnect_every)
                   or blackout_below is not None}
        serve_on_qemu(tcp, pty, speed, seed, key_file, [name for name, given in refused.items() if given],
                      params, plant_file)
        return
    try:
        if firmware == "c":
            _refuse_for_firmware(learner, params)
        host, port = parse_tcp(tcp)
        if baud is not None and not MIN_BAUD <= baud <= MAX_BAUD:
            raise ParamsError(f"--baud wants {MIN_BAUD}-{MAX_BAUD} (10 bits a byte), got {baud}")
        plant = preset(preset_name)
        learner_config = learner_preset(learner)
        mission = MissionConfig()
        if params is not None:
            plant, learner_config, mission = apply_param_file(params, plant, learner_config, mission)
        plant = with_plant_file(plant, plant_file)
        config = ServeConfig(
            plant=plant, learner=learner_config, mission=mission,
            faults=FaultConfig(drop, corrupt, delay, disconnect_every, blackout_below),
            host=host, port=port, pty=pty, speed=parse_speed(speed), seed=seed,
            key=read_key_file(key_file) if key_file is not None else None,
            mark_file=mark_path(key_file, state_dir) if key_file is not None else None,
            firmware=parse_firmware(firmware), baud=baud, build_delay_s=build_delay_s(),
        )
        server = AgentServer(config)
    except (SimulatorError, LearningError) as e:
        say_error(str(e))
        raise typer.Exit(EXIT_BAD_ARGUMENT) from None
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: server.stop())
    print(server.address, flush=True)
    try:
        server.serve_forever()
    except (SimulatorError, LearningError) as e:  # the program is built in there (serve/build.py)
        say_error(str(e))
        raise typer.Exit(1) from None
    finally:
        if report is not None:
            try:
                report.write_text(json.dumps(server.report()))
            except OSError as e:
                say_error(f"cannot write report {report}: {e.strerror or e}")
    sys.stdout.flush()
