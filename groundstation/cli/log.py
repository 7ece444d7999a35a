"""`dive log`: inspect, export and repair recordings."""

from __future__ import annotations

import json
import os
import subprocess
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from groundstation.cli.common import existing, one_line_errors, out
from groundstation.cli.validate import UsageError
from groundstation.errors import GroundStationError
from groundstation.recording.safe_files import replaced_atomically, unused_name

if TYPE_CHECKING:
    from groundstation.recording.files import RecordingParts

log_app = typer.Typer(help="Inspect, export and repair recordings.", no_args_is_help=True,
                      context_settings={"help_option_names": ["-h", "--help"]})


@log_app.command("info")
@one_line_errors
def log_info(files: Annotated[list[Path], typer.Argument(help="recordings, or folders of them")],
             as_json: Annotated[bool, typer.Option("--json", help="machine-readable")] = False,
             plant: Annotated[Path | None, typer.Option(
                 help="a fitted plant file (dive fit): how far each recording is from it (residual RMS)")] = None,
             ) -> None:
    """Sessions, duration, episodes with outcome and length, samples, loss, backfill and missing samples."""
    from groundstation.cli.bar import SlowBar
    from groundstation.recording.files import being_recorded, group_recordings, json_summary
    from groundstation.recording.info import format_summary
    from groundstation.recording.summaries import combine, format_combined, summarize_files

    if plant is not None and not plant.is_file():
        raise GroundStationError(f"no such plant file: {plant}")
    paths = _expand_saying(files)
    with SlowBar(f"summarising {len(paths)} file(s)") as bar:
        done = summarize_files(paths, bar.update)
    summaries = [(s, None if s.complete else being_recorded(Path(s.path))) for s in done]
    residuals = [plant_residual(path, plant) for path in paths] if plant is not None else []
    if as_json:
        rows = [{**json_summary(s.as_dict()), "being_recorded_by": w} for s, w in summaries]
        for row, residual in zip(rows, residuals, strict=False):
            row["plant_residual"] = residual
        # Plain json.dumps, not rich's print_json: rich re-parses and highlights the text line by line, 3 of the 4 s
        # CPU a 16-file folder's 260 KB took (benchmarks/loginfo_bench.py --folder). JSON escapes control characters.
        typer.echo(json.dumps(rows[0] if len(rows) == 1 else rows, indent=2))
        return
    for i, (summary, writer) in enumerate(summaries):
        text = format_summary(summary)
        if writer is not None:  # no footer yet because it is still being written, not because it was cut short
            text = text.replace("  (truncated: run `dive log recover`)", f"  (being recorded by {writer})", 1)
        out.print(text)
        if residuals:
            r = residuals[i]
            out.print(f"fit residual against {r['plant']}: {1000 * r['residual_rms_m']:.3f} mm RMS over "
                      f"{r['windows']} windows of up to {r['window_s']:g} s (worst {1000 * r['worst_window_rms_m']:.3f}"
                      f" mm; {r['residual_rms_m'] / r['noise_rms_m']:.1f}x the plant's sensor noise)", soft_wrap=True)
    if len(paths) > 1:
        for line in combine(done, [[str(f) for f in r.files] for r in group_recordings(paths)]):
            out.print(format_combined(line))


def _expand_saying(files: list[Path]) -> list[Path]:
    """The recordings the files and folders given hold, and on stderr the line naming what the folders held."""
    from groundstation.cli.common import err
    from groundstation.recording.files import expand, read_line

    paths = expand(files)
    line = read_line(files, paths)
    if line is not None:
        err.print(line, style="dim", soft_wrap=True, highlight=False)
    return paths


def plant_residual(path: Path, plant: Path) -> dict[str, Any]:
    """How far a recording is from a fitted plant: the simulator's `fit --check` (a process: dive never imports it)."""
    from groundstation.simulator_process import simulator_command

    done = subprocess.run(simulator_command(["fit", str(path), "--check", str(plant), "--json"]),
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        lines = done.stderr.strip().splitlines()
        raise GroundStationError(f"{path}: no fit residual: {lines[-1] if lines else 'the simulator failed'}")
    try:
        result: dict[str, Any] = json.loads(done.stdout)
    except ValueError:
        raise GroundStationError(f"{path}: no fit residual: the simulator's answer is not JSON") from None
    return result


class ExportFormat(StrEnum):
    csv = "csv"
    npz = "npz"
    minari = "minari"
    parquet = "parquet"


@log_app.command("export")
@one_line_errors
def log_export(files: Annotated[list[Path], typer.Argument(help="recordings, or folders of them")],
               format: Annotated[ExportFormat, typer.Option(
                   help="csv: samples; npz: offline-RL transitions; minari: a Minari dataset per environment; "
                   "parquet: a table per topic, a folder of recordings as one dataset (FILE may be a folder)")]
               = ExportFormat.csv,
               out_text: Annotated[str | None, typer.Option(
                   "--out", help="output file (one recording only) or a folder for the outputs (a name ending in / "
                   "is a folder, made if missing); for minari the datasets folder (default: Minari's own)")] = None,
               ) -> None:
    """Export samples as CSV, (s, a, r, s', terminated, truncated) transitions as .npz, a Minari dataset, or Parquet
    tables (one per topic, with link statistics, agent time on markers and events, labelled modes and actions) for
    DuckDB, polars and pandas.

    Several recordings (or a folder, its subfolders too) give one output file each, beside each recording.

    The parts of a split recording given together make one (NAME.csv beside NAME-part001.mcap), episodes whole.
    """
    from groundstation.cli.bar import SlowBar
    from groundstation.recording.export import export_csv, export_npz
    from groundstation.recording.files import group_recordings

    if format == ExportFormat.minari:
        if len(files) != 1:
            raise UsageError("minari exports one recording or one folder at a time")
        _export_minari(files[0], None if out_text is None else Path(out_text))
        return
    out_path = None if out_text is None else Path(out_text)
    recordings = group_recordings(_expand_saying(files))
    if format == ExportFormat.parquet:
        _export_parquet(recordings, out_path or recordings[0].files[0].parent / "parquet")
        return
    folder = out_path if out_path is not None and out_path.is_dir() else None  # as cp does: the usual names, in it
    if out_text is not None and out_path is not None and out_text.endswith(("/", os.sep)) and folder is None:
        try:
            out_path.mkdir(parents=True)
        except OSError as e:
            raise GroundStationError(f"cannot make the folder {out_text}: {e.strerror or e}") from e
        folder = out_path
    if out_path is not None and folder is None and len(recordings) > 1:
        raise UsageError(f"--out names one file, but {len(recordings)} recordings were given (or name a folder)")
    with SlowBar(f"exporting {len(recordings)} recording(s)", unit="recordings") as bar:
        for done, recording in enumerate(recordings):
            bar.update(done, len(recordings), f"exporting {recording.files[0].name}")
            first = recording.files[0]
            name = first.stem if len(recording.files) == 1 else recording.name
            target = first.with_name(f"{name}.{format.value}")
            if folder is not None:
                target = folder / target.name
            elif out_path is not None:
                target = out_path
            with replaced_atomically(target, source=first) as temporary:
                rows = (export_csv if format == ExportFormat.csv else export_npz)(recording.files, temporary)
            out.print(f"{target} ({rows} rows)")


def _export_parquet(recordings: list[RecordingParts], folder: Path) -> None:
    """Each recording's tables into `folder` (made if missing), one file per recording in each table's folder."""
    from groundstation.cli.bar import SlowBar
    from groundstation.recording.parquet_export import export_parquet
    from groundstation.recording.tables import open_recording

    if folder.exists() and not folder.is_dir():
        raise UsageError(f"--out {folder} is a file: parquet tables go into a folder")
    with SlowBar(f"exporting {len(recordings)} recording(s) to Parquet", unit="recordings") as bar:
        for done, recording in enumerate(recordings):
            bar.update(done, len(recordings), f"exporting {recording.files[0].name}")
            name = recording.files[0].stem if len(recording.files) == 1 else recording.name
            written = export_parquet(open_recording(*recording.files), name, folder)
            out.print(f"{folder}: {name} ({written.get('samples', 0)} samples, {written.get('episodes', 0)} "
                      f"episodes, {len(written)} tables)", markup=False, soft_wrap=True)
    out.print(f"query it: duckdb -c \"FROM '{folder}/episodes/*.parquet'\"", markup=False, soft_wrap=True)


def _export_minari(file: Path, root: Path | None) -> None:
    """One dataset per environment among the recordings (a folder may hold paper, hardware and firmware runs)."""
    from groundstation.cli.bar import SlowBar
    from groundstation.recording.files import expand, group_recordings
    from groundstation.recording.minari_export import export_minari, plan_groups
    from groundstation.recording.tables import open_recording

    if not file.exists():
        raise GroundStationError(f"no such recording: {file}")
    groups, differ = plan_groups(group_recordings(expand([file])), file.stem)
    if differ:
        out.print(f"{len(groups)} environments among the recordings ({'; '.join(differ)}): one dataset each",
                  markup=False, soft_wrap=True)
    with SlowBar(f"exporting {len(groups)} Minari dataset(s)", unit="datasets") as bar:
        for done, group in enumerate(groups):
            bar.update(done, len(groups), f"exporting {group.dataset_id}")
            files = [f for r in group.recordings for f in r.files]
            result = export_minari(open_recording(*files), group.dataset_id, root)
            left = f", {result.left_out} left out (holes or no end)" if result.left_out else ""
            out.print(f"Minari dataset {result.dataset_id} in {result.root}: {result.episodes} episodes, "
                      f"{result.steps} steps{left}", markup=False, soft_wrap=True)
    root_hint = f"MINARI_DATASETS_PATH={result.root} " if root is not None else ""
    out.print(f"load it: {root_hint}python -c \"import minari; minari.load_dataset('{result.dataset_id}')\"",
              markup=False, soft_wrap=True)


@log_app.command("recover")
@one_line_errors
def log_recover(
    file: Annotated[Path, typer.Argument(help="the truncated recording (it is read, never changed)",
                                         show_default=False)],
    out_path: Annotated[Path | None, typer.Option(
        "--out", help="output file (default: FILE-recovered.mcap beside it)")] = None,
) -> None:
    """Rewrite a truncated recording (after a crash or kill) into a finished, indexed one."""
    from groundstation.mcap_io import recover

    target = out_path or unused_name(existing(file).with_name(file.stem + "-recovered.mcap"))
    with replaced_atomically(target, source=existing(file)) as temporary:
        count, truncated = recover(file, temporary)
    note = "was truncated" if truncated else "was already complete"
    out.print(f"{target} ({count} messages; the original {note})")

