"""What a fit writes: the TOML plant file every --params takes, and the lines and JSON it reports."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from simulator.fit.estimate import HANDOVER, NEUTRAL, REPORTED_ONLY, Estimate, FitResult
from simulator.fit.model import NON_NEGATIVE

PLANT_TABLE = "plant"  # not agent parameters: `dive run --params` hands this table to the simulator it starts
_UNITS = {"added_mass_kg": "kg", "drag_kgpm": "kg/m", "trim_error_fraction": "of V0", "compressibility_m3pm": "m^3/m",
          "alpha_rate_dps": "deg/s", "pressure_noise_pa": "Pa", NEUTRAL: "deg", "dead_band_deg": "deg",
          "backlash_deg": "deg", "pressure_lag_s": "s", "pressure_noise_corr_s": "s", HANDOVER: "deg"}
# Physically >= 0: an interval reaching below 0 is cut there.
_NON_NEGATIVE = NON_NEGATIVE | {"dead_band_deg", "pressure_noise_pa", "pressure_noise_corr_s"}


def _interval(e: Estimate) -> str:
    unit = _UNITS.get(e.name, "")
    if e.name in _NON_NEGATIVE and e.value - e.half_width < 0.0:
        return f"+/- {e.half_width:.3g} {unit} (95 %, cut at 0: {0.0:g} .. {e.value + e.half_width:.3g})"
    return f"+/- {e.half_width:.3g} {unit} (95 %)".rstrip()


def diagnostic_lines(result: FitResult) -> list[str]:
    """The residuals' checks, one line each, and the warning when one fails."""
    lines = [f"{d.line} [{'ok' if d.passed else 'FAILED'}]" for d in result.diagnostics]
    if result.warning:
        lines.append(result.warning)
    return lines


def plant_toml(result: FitResult, base_label: str, base_fields: dict[str, Any]) -> str:
    """The fitted figures (and those of the base file the fit assumed) as a [plant] table, sources in comments."""
    windows = result.windows
    lines = [
        f"# Plant fitted by `dive fit` to {len(result.files)} recording(s): {windows.seconds:.0f} s of agent time "
        f"in {windows.count} windows, {len(windows.t_s)} samples.",
        *(f"#   {path}" for path in result.files),
        f"# Fit quality: depth residual RMS {1000 * result.residual_rms_m:.3f} mm; 95 % intervals: the wider of the "
        f"fit's Jacobian and the sandwich over its {windows.count} windows, with every depth-scale error within the "
        f"bound{' (a diagnostic failed)' if result.robust else ''}.",
        *(f"# {line}" for line in diagnostic_lines(result)),
        f"# Base (the figures not fitted): {base_label}.",
    ]
    missing = [e for e in result.estimates if not e.identified and e.name != NEUTRAL]
    if missing:
        lines.append("# Not identified by these recordings (the base's value stays):")
        lines.extend(f"#   {e.name}: {e.needs}" for e in missing)
    lines += [
        "# Read by `dive sim --params`, `dive study --params` and `dive run --params` (which hands this table to the",
        "# simulator of a sim:// run: these are not agent parameters).",
        f"[{PLANT_TABLE}]",
    ]
    fitted = {e.name for e in result.estimates if e.identified}
    for name, value in base_fields.items():
        if name not in fitted:
            lines.append(f"{name} = {_toml_value(value)}  # from the base file")
    for e in result.estimates:
        if e.identified and e.name not in REPORTED_ONLY:
            lines.append(f"{e.name} = {e.value!r}  # {_interval(e)}")
        elif e.in_fit:
            lines.append(f"{e.name} = {e.value!r}  # NOT identified: {e.needs}")
    neutral = result.estimate(NEUTRAL)
    if neutral.identified:
        lines.append(f"# {NEUTRAL} = {neutral.value:.3f}  # {_interval(neutral)}, from the trim (not a parameter)")
    handover = result.estimate(HANDOVER)
    if handover.identified:
        lines.append(f"# {HANDOVER} = {handover.value:.3f}  # {_interval(handover)}: the learning episodes' window "
                     "centres against the neutral angle (the recovery controller's own error included: not "
                     "start_trim_error_deg, which a study adds to the controller it simulates)")
    return "\n".join(lines) + "\n"


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value)


def report_lines(result: FitResult) -> list[str]:
    """One line per figure, then the figures not identified and what would identify them."""
    lines = []
    for e in result.estimates:
        if e.identified:
            lines.append(f"{e.name:22} {e.value:.6g} {_interval(e)}")
    for e in result.estimates:
        if not e.identified and e.name != NEUTRAL:
            lines.append(f"not identified: {e.name} ({e.needs})")
    lines.extend(diagnostic_lines(result))
    lines.append(f"depth residual RMS {1000 * result.residual_rms_m:.3f} mm over {result.windows.count} windows "
                 f"({result.windows.seconds:.0f} s); fit took {result.wall_s:.1f} s")
    return lines


def result_json(result: FitResult) -> dict[str, Any]:
    """The fit as numbers (nan as null)."""
    def number(x: float) -> float | None:
        return None if math.isnan(x) else x

    return {
        "recordings": [str(p) for p in result.files],
        "estimates": {e.name: {"value": e.value, "half_width_95": number(e.half_width), "identified": e.identified,
                               "needs": e.needs or None} for e in result.estimates},
        "residual_rms_m": result.residual_rms_m,
        "windows": result.windows.count,
        "seconds": result.windows.seconds,
        "samples": len(result.windows.t_s),
        "wall_s": result.wall_s,
        "notes": result.notes,
        "diagnostics": {d.name: {"passed": d.passed, "line": d.line} for d in result.diagnostics},
        # Every interval is the wider of the Jacobian's and the sandwich's now; what remains to say is the warning.
        "misfit_warning": result.warning or None,
    }


def write_text(path: Path, text: str) -> None:
    """Write a file whole (a temporary beside it, renamed), so a failed write leaves no half file."""
    temporary = path.with_name(path.name + ".part")
    temporary.write_text(text)
    temporary.replace(path)
