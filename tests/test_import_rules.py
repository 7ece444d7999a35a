"""The import rules of style.md, checked by walking every module's AST."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from collections.abc import Iterable, Mapping
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
# Folders inside a folder that only the listed folders may import: the rest of their parent never does.
INNER_ROOMS: dict[str, set[str]] = {
    "groundstation/view/foxglove": {"groundstation/cli"},  # the Foxglove server: started by `dive run` / `dive view`
}


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


def _inner_rooms_of(path: Path) -> set[str]:
    """The INNER_ROOMS a module imports, by folder path."""
    found = set()
    for module in _imported_modules(path):
        folder = module.replace(".", "/")
        found.update(room for room in INNER_ROOMS if folder == room or folder.startswith(room + "/"))
    return found


@pytest.mark.parametrize("room", sorted(INNER_ROOMS))
def test_inner_rooms_are_imported_only_by_their_users(room: str) -> None:
    assert (ROOT / room / "__init__.py").is_file(), f"{room}/ is not a package"
    allowed = INNER_ROOMS[room] | {room}
    for package in ALLOWED:
        for path in _modules(package):
            relative = path.relative_to(ROOT).as_posix()
            if room in _inner_rooms_of(path):
                assert any(relative.startswith(user + "/") for user in allowed), f"{relative} imports {room}"


# ---------------------------------------------------------------- circles


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imported_modules(path: Path) -> set[str]:
    """Every module name a file imports, wherever the import stands: at the top, under TYPE_CHECKING or inside a
    function (a lazy import is still an arrow: it is how the protocol's compiled path once closed a circle)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = _module_name(path) if path.name == "__init__.py" else _module_name(path).rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            # "base.name": a submodule where one exists, else a name of base (resolved to the longest module)
            found.update(f"{base}.{alias.name}" for alias in node.names)
    return found


def _python_import_graph() -> dict[str, set[str]]:
    """Module -> the modules of ours it imports (a name resolved to the longest module that exists)."""
    files = {_module_name(p): p for package in ALLOWED for p in _modules(package)}

    def resolve(name: str) -> str | None:
        while name and name not in files:
            name = name.rpartition(".")[0]
        return name or None

    graph = {}
    for name, path in files.items():
        targets = {resolve(imported) for imported in _imported_modules(path)}
        graph[name] = {t for t in targets if t is not None and t != name}
    return graph


def _circles(graph: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, successors = work[-1]
            advanced = False
            for nxt in successors:
                if nxt not in graph:
                    continue
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(sorted(graph[nxt]))))
                    advanced = True
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    circles.append(sorted(component))
    return circles


def test_the_circle_finder_finds_a_circle() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _circles(graph) == [["a", "b", "c"]]
    assert _circles({"a": {"b"}, "b": set()}) == []


def test_no_python_module_imports_itself_around_a_circle() -> None:
    graph = _python_import_graph()
    assert "groundstation.view.foxglove.live" in graph, "the graph misses the Foxglove folder"
    circles = _circles(graph)
    assert not circles, "import circles: " + "; ".join(" -> ".join(c) for c in circles)


FIRMWARE_SOURCES = ROOT / "firmware" / "src"


def _defined_and_used(objects: Path) -> tuple[dict[str, str], dict[str, set[str]]]:
    """From each object file's symbol table: which file defines each global symbol, and which each file uses."""
    defined: dict[str, str] = {}
    used: dict[str, set[str]] = {}
    for obj in sorted(objects.glob("*.o")):
        table = subprocess.run(["nm", str(obj)], capture_output=True, text=True, check=True).stdout
        used[obj.stem] = set()
        for line in table.splitlines():
            fields = line.split()
            if len(fields) == 2 and fields[0] == "U":
                used[obj.stem].add(fields[1])
            elif len(fields) == 3 and fields[1] in "TDBRCG":
                defined[fields[2]] = obj.stem
    return defined, used


def test_no_firmware_file_calls_back_into_a_file_that_calls_it(tmp_path: Path) -> None:
    """The core's C files, by the symbols each defines and each uses: no two files lean on each other."""
    compiler = shutil.which("cc")
    if compiler is None or shutil.which("nm") is None:
        pytest.skip("no host C compiler or nm: the firmware's circles are not checked")
    firmware = ROOT / "firmware"
    includes = [f"-I{firmware / d}" for d in ("include", "src", "generated")]
    for source in sorted(FIRMWARE_SOURCES.glob("*.c")) + sorted((firmware / "generated").glob("*.c")):
        obj = tmp_path / f"{source.stem}.o"
        subprocess.run([compiler, "-std=c99", "-c", *includes, "-o", str(obj), str(source)], check=True)
    defined, used = _defined_and_used(tmp_path)
    assert "learner_plan" in used and "learner" in used, "the learner's files were not compiled"
    graph = {name: {defined[s] for s in symbols if s in defined} - {name} for name, symbols in used.items()}
    circles = _circles(graph)
    assert not circles, "firmware circles: " + "; ".join(" <-> ".join(c) for c in circles)
