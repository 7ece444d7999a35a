"""firmware/generated/ is what `python -m protocol.gen_c` writes now: the C tables never drift from protocol/."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocol import definitions_hash
from protocol.gen_c import DEFAULT_DIR, generated_files
from protocol.parameters import PARAM_COUNT, RAM_BUDGET_BYTES


def test_checked_in_files_are_current() -> None:
    files = generated_files()
    stale = [name for name, text in files.items()
             if not (DEFAULT_DIR / name).is_file() or (DEFAULT_DIR / name).read_text() != text]
    assert not stale, f"stale generated C files {stale}: run `python -m protocol.gen_c` and commit them"
    on_disk = {p.relative_to(DEFAULT_DIR).as_posix() for p in DEFAULT_DIR.rglob("*") if p.is_file()}
    assert on_disk == set(files), "firmware/generated/ holds files gen_c no longer writes"


def test_tables_carry_the_protocol_figures() -> None:
    files = generated_files()
    assert f"#define PROTO_DEFINITIONS_HASH 0x{definitions_hash():08X}u" in files["proto_messages.h"]
    assert f"#define PARAM_COUNT {PARAM_COUNT}u" in files["proto_params.h"]
    assert f"#define PARAM_RAM_BUDGET_BYTES {RAM_BUDGET_BYTES}u" in files["proto_params.h"]


def test_write_to_a_folder(tmp_path: Path) -> None:
    from protocol.gen_c import main

    assert main([str(tmp_path)]) == 0
    assert (tmp_path / "proto_messages.h").read_text() == generated_files()["proto_messages.h"]


def test_help_and_a_wrong_option_write_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from protocol.gen_c import main

    monkeypatch.chdir(tmp_path)
    for argv, code in ((["--help"], 0), (["--out", "x"], 2)):
        with pytest.raises(SystemExit) as stop:
            main(argv)
        assert stop.value.code == code
    assert list(tmp_path.iterdir()) == []
