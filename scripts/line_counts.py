"""The line-count table of docs/architecture.md: modules and lines per folder of groundstation/ and simulator/.

Run: `.venv/bin/python scripts/line_counts.py` (prints the Markdown table, then the three largest modules).
Modules are counted without `__init__.py`, lines with it; a folder's count includes its inner folders.
"""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("groundstation", "simulator")


def _lines(path: Path) -> int:
    return len(path.read_text().splitlines())


def rows() -> list[tuple[str, int, int]]:
    """(folder, modules, lines) per folder of each package, largest first, then the package's top level."""
    table: list[tuple[str, int, int]] = []
    for package in PACKAGES:
        root = ROOT / package
        folders = [p for p in root.iterdir() if (p / "__init__.py").is_file()]
        counted = []
        for folder in folders:
            files = list(folder.rglob("*.py"))
            modules = sum(1 for f in files if f.name != "__init__.py")
            counted.append((f"{package}/{folder.name}", modules, sum(_lines(f) for f in files)))
        table.extend(sorted(counted, key=lambda row: -row[2]))
        top = list(root.glob("*.py"))
        table.append((f"{package} (top level)", sum(1 for f in top if f.name != "__init__.py"),
                      sum(_lines(f) for f in top)))
    return table


def main() -> None:
    print("| folder | modules | lines |\n|---|---|---|")
    for folder, modules, lines in rows():
        print(f"| {folder} | {modules} | {lines:,} |".replace(",", " "))
    largest = sorted(((_lines(f), f.relative_to(ROOT).as_posix()) for package in PACKAGES
                      for f in (ROOT / package).rglob("*.py")), reverse=True)[:3]
    print("\nlargest: " + ", ".join(f"{name} {lines}" for lines, name in largest))


if __name__ == "__main__":
    main()
