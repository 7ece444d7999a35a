"""The import rules of style.md, checked by walking every module's AST."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
OURS = {"protocol", "learning", "simulator", "groundstation", "tests", "benchmarks", "recordings"}
ALLOWED: dict[str, set[str]] = {
    "protocol": set(),
    "learning": set(),
    "simulator": {"protocol", "learning"},
    "groundstation": {"protocol", "learning"},
}
# Inside groundstation each of these foreign libraries is imported by one module (or one subpackage) only.
SINGLE_OWNER = ("mcap", "rerun", "serial")


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def _modules(package: str) -> list[Path]:
    return sorted((ROOT / package).rglob("*.py"))


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_package_imports_only_what_the_layout_allows(package: str) -> None:
    for path in _modules(package):
        ours = (_imports(path) & OURS) - {package}
        forbidden = ours - ALLOWED[package]
        assert not forbidden, f"{path.relative_to(ROOT)} imports {sorted(forbidden)}"


# The compiled fast path beside the stdlib codec: imported only where a decoder or encoder first runs, and
# only if numba is installed (the protocol works without it).
PROTOCOL_COMPILED = {"fast_frames.py": {"numba", "numpy"}}


def test_protocol_uses_the_standard_library_only() -> None:
    for path in _modules("protocol"):
        allowed = PROTOCOL_COMPILED.get(path.name, set())
        foreign = {n for n in _imports(path) if n not in sys.stdlib_module_names and n != "protocol"} - allowed
        assert not foreign, f"{path.relative_to(ROOT)} imports {sorted(foreign)}"


def test_the_compiled_protocol_path_is_imported_lazily() -> None:
    """No protocol module imports fast_frames at its top level: `import protocol` never loads numba."""
    for path in _modules("protocol"):
        tree = ast.parse(path.read_text(), filename=str(path))
        top = {node.module for node in tree.body if isinstance(node, ast.ImportFrom)}
        assert "protocol.fast_frames" not in top, f"{path.relative_to(ROOT)} imports fast_frames at import time"


def _owner(path: Path) -> Path:
    """A module directly in groundstation/ owns itself; a subpackage (groundstation/mcap_io/) is one owner."""
    relative = path.relative_to(ROOT / "groundstation")
    return relative if len(relative.parts) == 1 else Path(relative.parts[0])


@pytest.mark.parametrize("library", SINGLE_OWNER)
def test_each_foreign_io_library_has_one_owner_in_groundstation(library: str) -> None:
    owners = {_owner(p) for p in _modules("groundstation") if library in _imports(p)}
    assert len(owners) <= 1, f"{library} is imported by {sorted(owners)}"


def test_nothing_imports_groundstation() -> None:
    for package in ("protocol", "learning", "simulator"):
        for path in _modules(package):
            assert "groundstation" not in _imports(path), f"{path.relative_to(ROOT)} imports groundstation"
