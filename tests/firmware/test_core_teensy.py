"""The Teensy 3.2 image as a user flashes it: `make -C firmware teensy` links every learner variant against
Teensyduino's own teensy3 core and Wire (found as the Makefile finds them: ../shared/vendor beside the repository,
PlatformIO, the Arduino IDE), and each agent.elf / agent.hex must fit the MK20DX256 with room for its stack, start
where the chip starts (vector table, reset handler, the flash configuration field that can lock a Teensy until it is
erased) and carry the real Arduino calls, no stub. Built once per test session (shared by the xdist workers)."""

from __future__ import annotations

import fcntl
import re
import shutil
import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.firmware.core_build import FIRMWARE, session_folder

pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]  # the first test waits for the session's build
FLASH_BYTES = 256 * 1024
RAM_BYTES = 64 * 1024
RAM_ORIGIN = 0x1FFF8000
VARIANTS = ("paper", "actuator3", "shared-bins13", "shared-z20")
TOOLS = ("arm-none-eabi-gcc", "arm-none-eabi-g++", "arm-none-eabi-nm", "arm-none-eabi-objcopy", "make", "cc")
# The C core's entry points a board calls (include/agent.h) and the sketch's two Arduino functions.
ENTRY_POINTS = ("setup", "loop", "agent_init", "agent_poll_link", "agent_step", "agent_link_up", "agent_surface")
# Every Arduino call the sketch makes: each must be the core's definition (compile_check/link_stubs.cpp had stubs).
ARDUINO_CALLS = ("micros", "delay", "pinMode", "digitalWrite", "digitalRead", "analogRead", "eeprom_read_block",
                 "eeprom_write_block", "_ZN7TwoWire5beginEv", "_ZN7TwoWire15endTransmissionEh",
                 "_ZN7TwoWire11requestFromEhhh", "_ZN7TwoWire5writeEPKhj", "serial_add_memory_for_write",
                 "usb_serial_write", "usb_serial_available", "serial_write", "serial_available")
STUB_ONLY = ("reset_handler", "vector_table")  # symbols only compile_check/link_stubs.cpp defines


@dataclass(frozen=True)
class Images:
    """The session's build: its folder, the core it was linked against, and the size lines `make teensy` printed."""

    build: Path
    core_dir: Path
    report: str

    def elf(self, variant: str) -> Path:
        return self.build / "teensy" / variant / "agent.elf"


def _core_dir() -> Path:
    """The teensy3 folder `make teensy` links against, or skip: without one it would link the stubs."""
    for tool in TOOLS:
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not on PATH: the Teensy image test is skipped")
    found = subprocess.run(["make", "-s", "-C", str(FIRMWARE), "teensy-core-dir"], capture_output=True, text=True,
                           check=True).stdout.strip()
    if not found:
        pytest.skip("no Teensyduino core (../shared/vendor/teensyduino, PlatformIO or the Arduino IDE): "
                    "the Teensy image test is skipped")
    return Path(found)


@pytest.fixture(scope="session")
def images(tmp_path_factory: pytest.TempPathFactory) -> Images:
    """`make -j2 teensy` once for the whole session: the first xdist worker builds under a lock, the other reuses."""
    core_dir = _core_dir()
    shared = session_folder(tmp_path_factory, "teensy")
    build = shared / "build"
    report = shared / "make-teensy.txt"
    with open(shared / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not report.exists():
            done = subprocess.run(["make", "-s", "-j2", "-C", str(FIRMWARE), "teensy", f"BUILD={build}"],
                                  capture_output=True, text=True, timeout=600, check=False)
            assert done.returncode == 0, done.stderr + done.stdout
            report.write_text(done.stdout)
    return Images(build, core_dir, report.read_text())


def _symbols(elf: Path) -> dict[str, tuple[int, str]]:
    """Name -> (address, nm type letter) of every symbol of the image."""
    out = subprocess.run(["arm-none-eabi-nm", str(elf)], capture_output=True, text=True, check=True).stdout
    table: dict[str, tuple[int, str]] = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3:
            table[parts[2]] = (int(parts[0], 16), parts[1])
    return table


def _loadable_bytes(elf: Path) -> dict[int, int]:
    """Address -> byte of what a loader writes: the file bytes of every PT_LOAD segment at its physical (load)
    address (.data sits in flash after the code and is copied to RAM at reset). ELF32 little-endian, as ARM emits."""
    data = elf.read_bytes()
    assert data[:4] == b"\x7fELF" and data[4] == 1 and data[5] == 1, "not a 32-bit little-endian ELF"
    (phoff,) = struct.unpack_from("<I", data, 28)
    phentsize, phnum = struct.unpack_from("<HH", data, 42)
    image: dict[int, int] = {}
    for index in range(phnum):
        p_type, offset, _vaddr, paddr, filesz = struct.unpack_from("<5I", data, phoff + index * phentsize)
        if p_type == 1 and filesz:  # PT_LOAD
            image.update(zip(range(paddr, paddr + filesz), data[offset:offset + filesz], strict=True))
    return image


def _hex_bytes(path: Path) -> dict[int, int]:
    """Address -> byte of an Intel HEX file (record types 00 data, 01 end, 02/04 address bases, 03/05 start address),
    every record's checksum checked; a byte written twice fails."""
    image: dict[int, int] = {}
    base = 0
    ended = False
    for number, line in enumerate(path.read_text().splitlines(), 1):
        assert line.startswith(":") and not ended, f"line {number}: not a record, or after the end record"
        record = bytes.fromhex(line[1:])
        count, address, kind = record[0], int.from_bytes(record[1:3], "big"), record[3]
        payload = record[4:4 + count]
        assert len(record) == count + 5 and sum(record) % 256 == 0, f"line {number}: bad length or checksum"
        if kind == 0:
            for i, byte in enumerate(payload):
                assert base + address + i not in image, f"line {number}: address written twice"
                image[base + address + i] = byte
        elif kind == 1:
            ended = True
        elif kind == 2:
            base = int.from_bytes(payload, "big") << 4
        elif kind == 4:
            base = int.from_bytes(payload, "big") << 16
        else:
            assert kind in (3, 5), f"line {number}: unknown record type {kind}"
    assert ended, "no end-of-file record"
    return image


def _core_flash_config(core_dir: Path) -> bytes:
    """The 16 bytes Teensyduino's startup (mk20dx128.c, `flashconfigbytes`) puts in the flash configuration field,
    its FSEC / FOPT macros resolved, after checking that its linker script places that section at 0x400."""
    script = (core_dir / "mk20dx256.ld").read_text()
    assert re.search(r"\.\s*=\s*0x400;\s*KEEP\(\*\(\.flashconfig\*?\)\)", script), "mk20dx256.ld moved .flashconfig"
    startup = (core_dir / "mk20dx128.c").read_text()
    body = re.search(r"flashconfigbytes\[16\]\s*=\s*\{([^}]*)\}", startup)
    assert body is not None, "mk20dx128.c has no flashconfigbytes[16]"
    defines = dict(re.findall(r"^#define\s+(\w+)\s+(0x[0-9A-Fa-f]+)", startup, re.MULTILINE))
    return bytes(int(defines.get(token, token), 16) for token in (t.strip() for t in body.group(1).split(",")))


def _report_line(images: Images, variant: str) -> tuple[int, int, int]:
    """(flash, RAM, free) as `make teensy` printed them for this variant."""
    match = re.search(rf"^{re.escape(variant)}\s+flash\s+(\d+) B.*RAM\s+(\d+) B.*stack and heap\s+(\d+) B$",
                      images.report, re.MULTILINE)
    assert match is not None, images.report
    flash, ram, free = (int(g) for g in match.groups())
    return flash, ram, free


@pytest.mark.parametrize("variant", VARIANTS)
def test_the_image_fits_the_mk20dx256_with_room_for_its_stack(images: Images, variant: str) -> None:
    flash, ram, free = _report_line(images, variant)
    symbols = _symbols(images.elf(variant))
    etext, ebss, estack = (symbols[name][0] for name in ("_etext", "_ebss", "_estack"))
    assert etext < flash <= FLASH_BYTES  # the code, then .data's initial values after it
    assert ram == ebss - RAM_ORIGIN and free == estack - ebss and ram + free == RAM_BYTES
    assert free >= 4096, f"{variant}: {free} B for stack and heap, less than TEENSY_STACK_BYTES"
    # Teensyduino's USB serial buffers are counted: they are in RAM below the agent's own data.
    assert RAM_ORIGIN <= symbols["usb_buffer_memory"][0] < ebss


def test_the_variants_differ_only_in_their_learner_storage(images: Images) -> None:
    sizes = {variant: _report_line(images, variant) for variant in VARIANTS}
    assert len({flash for flash, _, _ in sizes.values()}) == 1  # the same code in every variant
    ram = {variant: sizes[variant][1] for variant in VARIANTS}
    # S = 101 < S = 1401 (learner 11 732 B + snapshots 22 416 B) < S = 1301 (16 096 + 20 816 B) < S = 301 (34 013 +
    # 9 632 B: the per-state model's slots)
    assert ram["paper"] < ram["shared-z20"] < ram["shared-bins13"] < ram["actuator3"]


@pytest.mark.parametrize("variant", VARIANTS)
def test_the_image_starts_as_the_chip_starts_it(images: Images, variant: str) -> None:
    elf = images.elf(variant)
    flash = _hex_bytes(elf.with_suffix(".hex"))
    symbols = _symbols(elf)
    assert symbols["_VectorsFlash"][0] == 0  # the vector table at 0, where the MK20DX256 reads it at reset
    initial_sp, reset = struct.unpack("<II", bytes(flash[a] for a in range(8)))
    assert initial_sp == symbols["_estack"][0] == RAM_ORIGIN + RAM_BYTES
    assert reset & 1, "the reset vector must have the Thumb bit"
    assert reset & ~1 == symbols["ResetHandler"][0] and reset & ~1 < symbols["_etext"][0]  # inside the image's flash
    field = bytes(flash[a] for a in range(0x400, 0x410))
    assert field == _core_flash_config(images.core_dir)  # a wrong FSEC here locks the chip until a mass erase
    assert field[12] == 0xDE  # FSEC: unsecured, mass erase enabled (0xDC would lock it)


@pytest.mark.parametrize("variant", VARIANTS)
def test_the_agent_and_the_real_arduino_calls_are_linked_no_stub(images: Images, variant: str) -> None:
    symbols = _symbols(images.elf(variant))
    for name in ENTRY_POINTS:
        assert symbols.get(name, (0, "?"))[1] == "T", f"{name} not linked"
    archive = subprocess.run(["arm-none-eabi-nm", "--defined-only", str(images.build / "teensy" / "core.a")],
                             capture_output=True, text=True, check=True).stdout
    core_defines = {line.split()[2] for line in archive.splitlines() if len(line.split()) == 3}
    for name in ARDUINO_CALLS:
        assert name in symbols and name in core_defines, f"{name}: not Teensyduino's definition"
    for name in STUB_ONLY:
        assert name not in symbols, f"{name}: a compile_check stub was linked"
    assert not list((images.build / "teensy" / variant).glob("link_stubs*"))


@pytest.mark.parametrize("variant", VARIANTS)
def test_the_hex_holds_exactly_the_elfs_loadable_bytes(images: Images, variant: str) -> None:
    elf = images.elf(variant)
    from_hex = _hex_bytes(elf.with_suffix(".hex"))
    assert from_hex == _loadable_bytes(elf)
    assert max(from_hex) < FLASH_BYTES  # nothing for RAM or the EEPROM: the Teensy Loader writes flash only


@pytest.mark.parametrize("variant", VARIANTS)
def test_the_image_uses_no_fpu_instruction(images: Images, variant: str) -> None:
    """Built with the Cortex-M4 soft-float ABI: the MK20DX256 has no FPU, one VFP instruction is a HardFault."""
    attributes = subprocess.run(["arm-none-eabi-readelf", "-A", str(images.elf(variant))],
                                capture_output=True, text=True, check=True).stdout
    assert "Tag_CPU_name: \"7E-M\"" in attributes or "Cortex-M4" in attributes, attributes
    assert "Tag_FP_arch" not in attributes and "Tag_ABI_VFP_args" not in attributes
