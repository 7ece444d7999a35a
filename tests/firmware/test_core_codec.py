"""The C frame codec against the golden vectors, both ways: decode wire_hex to the vector's fields, encode
the inner frame's fields back to wire_hex; the HMAC of the signed vectors; reject counters by cause."""

from __future__ import annotations

import json
import struct
import subprocess
from pathlib import Path
from typing import Any

import pytest

from protocol import FrameFlag, message_class_by_name
from tests.firmware.core_build import ROOT, compile_program

VECTORS = ROOT / "tests" / "vectors"
HARNESS_SOURCES = [
    Path("tests/firmware/codec_harness.c"), *[Path(f"firmware/src/{m}.c") for m in
                                              ("frame", "cobs", "crc", "wire", "hmac", "sha256")],
    Path("firmware/generated/proto_messages.c"), Path("firmware/generated/test/proto_fields.c"),
]


@pytest.fixture(scope="module")
def harness(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return compile_program(HARNESS_SOURCES, tmp_path_factory.mktemp("codec") / "codec_harness")


def run(harness: Path, lines: list[str]) -> list[str]:
    result = subprocess.run([str(harness)], input="\n".join(lines) + "\n", capture_output=True, text=True,
                            check=True, timeout=60)
    return result.stdout.splitlines()


def load(name: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (VECTORS / name).read_text().splitlines() if line.strip()]


def expected_field(spec: str, value: Any) -> str:
    """A vector's field value as the harness prints it."""
    if spec == "f32":
        return str(struct.unpack("<I", struct.pack("<f", value))[0])
    if spec == "f64":
        return str(struct.unpack("<Q", struct.pack("<d", value))[0])
    if spec == "char[24]":
        return value.encode().ljust(24, b"\0").hex()
    if spec == "text[]":
        return value.encode().hex()
    if spec == "bytes[]":
        return str(value)
    return str(value)


def decoded(output: list[str]) -> list[tuple[str, dict[str, str], str]]:
    """(frame line, fields, repack) per decoded frame."""
    frames: list[tuple[str, dict[str, str], str]] = []
    for line in output:
        if line.startswith("F "):
            frames.append((line, {}, ""))
        elif line.startswith("  repack="):
            frames[-1] = (frames[-1][0], frames[-1][1], line.split("=", 1)[1])
        elif line.startswith("  "):
            name, value = line.strip().split("=", 1)
            frames[-1][1][name] = value
    return frames


@pytest.mark.parametrize("file", ["frames.jsonl", "signed.jsonl"])
def test_decode_vectors(harness: Path, file: str) -> None:
    vectors = load(file)
    frames = decoded(run(harness, [f"D {v['wire_hex']}" for v in vectors]))
    assert len(frames) == len(vectors)
    for vector, (line, fields, repack) in zip(vectors, frames, strict=True):
        cls = message_class_by_name(vector["name"])
        inner = bytes.fromhex(vector["inner_hex"])
        end = len(inner) - 2 - (13 if vector["flags"] & FrameFlag.SIGNED else 0)
        assert line == f"F {vector['flags']} {vector['seq']} {cls.MSG_ID} {inner[5:end].hex()}", vector["name"]
        for f in cls.DEFINITION.fields:
            assert fields[f.name] == expected_field(f.wire.spec_name, vector["fields"].get(f.name, "")), f.name
        assert repack in ("ok", ""), vector["name"]


@pytest.mark.parametrize("file", ["frames.jsonl", "signed.jsonl"])
def test_encode_vectors(harness: Path, file: str) -> None:
    vectors = load(file)
    lines = []
    for v in vectors:
        inner = bytes.fromhex(v["inner_hex"])
        lines.append(f"E {inner[1]} {v['seq']} {inner[4]} {inner[5:-2].hex()}")  # a signed trailer is payload here
    out = run(harness, lines)
    assert out == [f"W {v['wire_hex']}" for v in vectors]


def test_hmac_of_signed_vectors(harness: Path) -> None:
    vectors = load("signed.jsonl")
    lines = [f"H {v['key_hex']} {v['inner_hex']}" for v in vectors]
    tampered = bytearray.fromhex(vectors[0]["inner_hex"])
    tampered[5] ^= 1
    lines.append(f"H {vectors[0]['key_hex']} {tampered.hex()}")
    assert run(harness, lines) == ["H valid"] * len(vectors) + ["H bad"]


def test_rejects_counted_by_cause(harness: Path) -> None:
    good = load("frames.jsonl")[0]["wire_hex"]
    hello = bytes.fromhex(load("frames.jsonl")[0]["inner_hex"])

    def wire(inner: bytes) -> str:
        from protocol.cobs import cobs_encode
        from protocol.crc import crc16_ccitt_false

        body = inner + crc16_ccitt_false(inner).to_bytes(2, "big")
        return (cobs_encode(body) + b"\0").hex()

    unknown = wire(bytes([1, 0, 1, 0, 0x30]))       # id 0x30: unknown, outside the command range
    command = wire(bytes([1, 1, 2, 0, 0xEE]))       # id 0xEE: unknown command -> handed up (ACK UNSUPPORTED)
    incompatible = wire(bytes([2, 0, 3, 0, 1]))     # version 2
    malformed = wire(bytes([1, int(FrameFlag.SIGNED), 4, 0, 5]))  # signed TEXT too short for a trailer
    lines = [
        "D " + "01" * 300 + "00",                    # oversize
        "D 0300" + "00",                             # COBS error: code points past the end
        "D 0201" + "00",                             # runt (one byte)
        "D " + good[:-4] + "ff00",                   # CRC error (last CRC byte changed)
        "D " + incompatible, "D " + unknown, "D " + command, "D " + malformed,
        "D 00000000",                                # empty chunks: ignored
    ]
    out = [line for line in run(harness, lines) if line.startswith("R ")]
    assert out[-1].split()[1:8] == ["1", "1", "1", "1", "1", "1", "1"]
    assert out[-1].split()[10] == "1"  # only the unknown command was handed to the program
    assert hello  # the vector the CRC-error chunk was made from
