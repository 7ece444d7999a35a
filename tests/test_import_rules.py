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


# The folders of each package (docs/architecture.md) and which other folders each may import. A folder imports
# only downwards: what is listed here. The modules at a package's top level are its base (errors, safe output,
# parameters): every folder may import them, and they import no folder, except the entry points listed below.
ROOMS: dict[str, dict[str, set[str]]] = {
    "groundstation": {
        "cli": {"run", "view", "recording", "check", "session", "links", "mcap_io"},
        "run": {"recording", "session", "links", "mcap_io"},
        "view": {"recording", "session", "links", "mcap_io"},
        "check": {"session", "links"},
        "recording": {"session", "links", "mcap_io"},
        "session": {"links"},
        "links": set(),
        "mcap_io": set(),
    },
    "simulator": {
        "serve": {"agent", "plant"},
        "study": {"plant"},
        "fit": {"plant"},
        "gym": {"plant"},
        "agent": {"plant"},
        "plant": set(),
    },
}
# Top-level modules that are entry points into the folders, with the folders each reaches.
ENTRY_POINTS: dict[str, set[str]] = {
    "groundstation/__init__.py": {"recording"},  # `from groundstation import open_recording`, loaded lazily
    "simulator/cli.py": {"serve", "study", "fit"},  # `python -m simulator serve | study | fit`
    "simulator/gym_env.py": {"gym"},  # the old path of simulator.gym.env, kept for one release
}
TOP_LEVEL_BASE_LIMIT = 4  # modules beside __init__, __main__ and errors


def _room(package: str, path: Path) -> str | None:
    """The folder a module lives in, or None for a top-level module."""
    relative = path.relative_to(ROOT / package)
    return relative.parts[0] if len(relative.parts) > 1 else None


def _rooms_imported(package: str, path: Path) -> set[str]:
    """The folders of `package` that a module imports (any import of package.FOLDER or package.FOLDER.x)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    modules: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            modules.extend(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            modules.append(node.module)
            modules.extend(f"{node.module}.{alias.name}" for alias in node.names)
    rooms = set()
    for module in modules:
        parts = module.split(".")
        if parts[0] == package and len(parts) > 1 and (ROOT / package / parts[1]).is_dir():
            rooms.add(parts[1])
    return rooms


@pytest.mark.parametrize("package", sorted(ROOMS))
def test_every_folder_has_an_import_rule(package: str) -> None:
    folders = {p.parent.name for p in (ROOT / package).glob("*/__init__.py")}
    assert folders == set(ROOMS[package]), f"{package}: folders without a rule or rules without a folder"


@pytest.mark.parametrize("package", sorted(ROOMS))
def test_folders_import_only_downwards(package: str) -> None:
    for path in _modules(package):
        room = _room(package, path)
        relative = path.relative_to(ROOT).as_posix()
        if room is None:
            allowed = ENTRY_POINTS.get(relative, set())
        else:
            allowed = ROOMS[package][room] | {room}
        forbidden = _rooms_imported(package, path) - allowed
        assert not forbidden, f"{relative} imports {sorted(forbidden)}"


@pytest.mark.parametrize("package", sorted(ROOMS))
def test_the_top_level_holds_only_the_base(package: str) -> None:
    top = {p.name for p in (ROOT / package).glob("*.py")} - {"__init__.py", "__main__.py", "errors.py"}
    assert len(top) <= TOP_LEVEL_BASE_LIMIT, f"{package}/ holds {sorted(top)} at its top level"


@pytest.mark.parametrize("package", sorted(ROOMS))
def test_no_file_repeats_its_folders_name(package: str) -> None:
    for path in _modules(package):
        folder = path.parent.name
        if path.parent != ROOT / package:
            assert not path.stem.startswith(folder), f"{path.relative_to(ROOT)}: the folder says {folder!r} already"


@pytest.mark.parametrize("library", SINGLE_OWNER)
def test_each_foreign_io_library_has_one_owner_in_groundstation(library: str) -> None:
    owners = {_owner(p) for p in _modules("groundstation") if library in _imports(p)}
    assert len(owners) <= 1, f"{library} is imported by {sorted(owners)}"


def test_nothing_imports_groundstation() -> None:
    for package in ("protocol", "learning", "simulator"):
        for path in _modules(package):
            assert "groundstation" not in _imports(path), f"{path.relative_to(ROOT)} imports groundstation"


def test_tests_import_no_test_module_and_no_private_name() -> None:
    """What tests share lives in helper modules with public names (tests/groundstation/hub_helpers.py, ...): a test
    module is never imported by another, and no test imports a private name (a leading underscore) of any module."""
    found = []
    for path in _modules("tests"):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom) or node.level != 0 or not node.module:
                continue
            where = f"{path.relative_to(ROOT)}:{node.lineno}"
            if node.module.split(".")[-1].startswith("test_"):
                found.append(f"{where} imports the test module {node.module}")
            private = [a.name for a in node.names if a.name.startswith("_") and not a.name.startswith("__")]
            if private:
                found.append(f"{where} imports {private} from {node.module}")
    assert not found, "\n".join(found)
