"""Writes docs/foxglove/diving-agent-layout.json: the Foxglove layout for `dive` recordings.

    python scripts/foxglove_layout.py      # rewrites the file; tests/groundstation/test_foxglove_layout.py
                                           # checks that every topic and field it plots is recorded

Import it in Foxglove (Layouts > Import from file) and open any recording.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

OUT = Path(__file__).resolve().parent.parent / "docs" / "foxglove" / "diving-agent-layout.json"
BOUNDS_TOPIC = "/studio_script/depth_bounds"
# A Foxglove user script: the learning region's edges from each EPISODE_START (z positive down).
BOUNDS_SCRIPT = f"""// Learning-region bounds for the depth plot, from each episode's start message.
import {{ Input }} from "./types";

export const inputs = ["/agent/EPISODE_START"];
export const output = "{BOUNDS_TOPIC}";

type Bounds = {{ target_m: number; shallow_edge_m: number; deep_edge_m: number }};

export default function script(event: Input<"/agent/EPISODE_START">): Bounds {{
  const start = event.message as any;
  return {{
    target_m: start.target_depth_m,
    shallow_edge_m: start.target_depth_m - start.z_tol_m,
    deep_edge_m: start.target_depth_m + start.z_tol_m,
  }};
}}
"""


def _plot(title: str, paths: list[tuple[str, str]], x_axis: str = "timestamp", **extra: Any) -> dict[str, Any]:
    return {
        "title": title,
        "paths": [{"value": value, "enabled": True, "timestampMethod": "receiveTime", "label": label}
                  for value, label in paths],
        "showXAxisLabels": True, "showYAxisLabels": True, "showLegend": True, "legendDisplay": "floating",
        "showPlotValuesInLegend": True, "isSynced": x_axis == "timestamp", "xAxisVal": x_axis,
        "sidebarDimension": 240, **extra,
    }


Node = str | dict[str, Any]


def column(first: Node, second: Node, split: int) -> dict[str, Any]:
    """A mosaic node: first above second, split percent of the height for first."""
    return {"first": first, "second": second, "direction": "column", "splitPercentage": split}


def row(first: Node, second: Node, split: int) -> dict[str, Any]:
    """A mosaic node: first left of second."""
    return {"first": first, "second": second, "direction": "row", "splitPercentage": split}


def layout() -> dict[str, Any]:
    panels = {
        "Plot!depth": _plot("Depth [m] (down is deeper) with the learning region", [
            ("/agent/SAMPLE.depth_m", "depth"),
            (f"{BOUNDS_TOPIC}.target_m", "target"),
            (f"{BOUNDS_TOPIC}.shallow_edge_m", "shallow edge"),
            (f"{BOUNDS_TOPIC}.deep_edge_m", "deep edge"),
        ]),
        "Plot!velocity": _plot("Velocity [m/s] (observer estimate)", [("/agent/SAMPLE.velocity_mps", "velocity")]),
        "Plot!actuator": _plot("Actuator gear angle [deg]", [
            ("/agent/SAMPLE.actuator_deg", "angle"), ("/agent/SAMPLE.actuator_cmd_deg", "command")]),
        "Plot!action": _plot("Action (0 less volume, 1 more, 255 none) and mode", [
            ("/agent/SAMPLE.action", "action"), ("/agent/SAMPLE.mode", "mode")]),
        "Plot!reward": _plot("Reward per step", [("/agent/SAMPLE.reward", "reward")]),
        "Plot!curve": _plot("Learning curve: time held per episode [s]", [
            ("/agent/EPISODE_END.duration_s", "duration")], x_axis="index"),
        "Plot!link": _plot("Link: frames lost, rejects, backfilled, round trip [ms]", [
            ("/link.link.rx_lost", "lost"), ("/link.link.rx_rejects", "rejects"),
            ("/link.link.backfilled", "backfilled"), ("/link.link.rtt_median_ms", "RTT median")]),
        "Table!log": {"topicPath": "/agent/TEXT"},
        "RawMessages!events": {"topicPath": "/event", "diffEnabled": False, "diffMethod": "custom",
                               "diffTopicPath": "", "showFullMessageForDiff": False},
    }
    return {
        "configById": panels,
        "globalVariables": {},
        "userNodes": {"depth-bounds": {"name": "depth bounds", "sourceCode": BOUNDS_SCRIPT}},
        "playbackConfig": {"speed": 1},
        "layout": row(
            column(column("Plot!depth", "Plot!velocity", 60), column("Plot!actuator", "Plot!action", 50), 60),
            column(column("Plot!curve", "Plot!reward", 50),
                   column("Plot!link", row("Table!log", "RawMessages!events", 60), 45), 50),
            60,
        ),
    }


def main() -> None:
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(layout(), indent=2) + "\n")
    print(OUT)


if __name__ == "__main__":
    main()
