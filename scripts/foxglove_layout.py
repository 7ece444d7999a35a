"""Writes docs/foxglove/diving-agent-layout.json and live-layout.json: the Foxglove layouts for `dive` recordings
and for `dive run/view --foxglove` (live, with the Parameters panel and buttons for the controls).

    python scripts/foxglove_layout.py      # rewrites both; tests check that every topic and field the recording
                                           # layout plots is recorded, and that the live one calls only services
                                           # and shows only topics the server offers

Import one in Foxglove (Layouts > Import from file) and open a recording, or the connection ws://127.0.0.1:PORT.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

OUT = Path(__file__).resolve().parent.parent / "docs" / "foxglove" / "diving-agent-layout.json"
LIVE_OUT = OUT.with_name("live-layout.json")
LOG_TOPIC = "/log"  # groundstation/view/foxglove/console.py: foxglove.Log
BOUNDS_TOPIC = "/studio_script/depth_bounds"
# A Foxglove user script: the learning region's edges from each EPISODE_START, as z up = -depth like the plot.
BOUNDS_SCRIPT = f"""// Learning-region bounds for the depth plot (z up = -depth), from each episode's start message.
import {{ Input }} from "./types";

export const inputs = ["/agent/EPISODE_START"];
export const output = "{BOUNDS_TOPIC}";

type Bounds = {{ target_z_m: number; shallow_edge_z_m: number; deep_edge_z_m: number }};

export default function script(event: Input<"/agent/EPISODE_START">): Bounds {{
  const start = event.message as any;
  return {{
    target_z_m: -start.target_depth_m,
    shallow_edge_z_m: -(start.target_depth_m - start.z_tol_m),
    deep_edge_z_m: -(start.target_depth_m + start.z_tol_m),
  }};
}}
"""
VOLTS_TOPIC = "/studio_script/battery_v"
# A Foxglove user script: the battery in volts (HEARTBEAT carries mV; dive and the Rerun view say V everywhere).
VOLTS_SCRIPT = f"""// Battery voltage [V] from each heartbeat's battery_mv.
import {{ Input }} from "./types";

export const inputs = ["/agent/HEARTBEAT"];
export const output = "{VOLTS_TOPIC}";

export default function script(event: Input<"/agent/HEARTBEAT">): {{ battery_v: number }} {{
  return {{ battery_v: (event.message as any).battery_mv / 1000 }};
}}
"""
# Foxglove's Plot panel cannot flip its y axis: depth is plotted as z up = -depth (the message path's math modifier
# .@negative), so deeper is drawn lower, as the Rerun view and the value/policy images draw it.
DEPTH_TITLE = "Depth drawn downward: z up = -depth [m] (surface 0) with the learning region"


def _depth_plot() -> dict[str, Any]:
    return _plot(DEPTH_TITLE, [
        ("/agent/SAMPLE.depth_m.@negative", "z = -depth"),
        (f"{BOUNDS_TOPIC}.target_z_m", "target"),
        (f"{BOUNDS_TOPIC}.shallow_edge_z_m", "shallow edge"),
        (f"{BOUNDS_TOPIC}.deep_edge_z_m", "deep edge"),
    ])


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
        "Plot!depth": _depth_plot(),
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


# The modes as the Indicator panel names them (protocol/enums.py's Mode), the ones to watch in warm colours.
MODE_COLOURS = {"IDLE": "#7f7f7f", "LEARNING": "#2ca02c", "RECOVERING": "#bcbd22", "HOVER": "#1f77b4",
                "SURFACING": "#d62728", "PAUSED": "#ff7f0e"}
# The buttons: (service, label, colour, request); the services are groundstation/view/foxglove/services.py's. A
# request with a value (a depth, a marker's text) is the panel's to edit before the call.
BUTTONS = (("surface", "SURFACE (emergency)", "#d62728", {}), ("start", "start learning", "#2ca02c", {}),
           ("pause", "pause", "#ff7f0e", {}), ("resume", "resume", "#2ca02c", {}),
           ("stop", "stop (surfaces)", "#7f7f7f", {}), ("hover", "hover at depth_m", "#1f77b4", {"depth_m": 0.3}),
           ("target", "target depth_m", "#1f77b4", {"depth_m": 0.4}),
           ("mark", "mark", "#9467bd", {"text": "marked in Foxglove"}),
           ("dump", "dump values and policy", "#7f7f7f", {"kind": "both"}),
           ("ack", "acknowledge alarms", "#d62728", {}))
VALUE_IMAGE, POLICY_IMAGE = "/value_function/image", "/policy/image"  # groundstation/view/foxglove/images.py


def _button(service: str, label: str, colour: str, request: dict[str, Any]) -> dict[str, Any]:
    return {"serviceName": service, "requestPayload": json.dumps(request), "layout": "vertical", "buttonText": label,
            "buttonTooltip": f"call the {service} service: the agent's ACK and mode come back",
            "buttonColor": colour}


def live_layout() -> dict[str, Any]:
    from protocol import Mode

    panels: dict[str, Any] = {
        "Plot!depth": _depth_plot(),
        "Plot!battery": _plot("Battery [V]", [(f"{VOLTS_TOPIC}.battery_v", "battery")]),
        "Indicator!mode": {"path": "/agent/HEARTBEAT.mode", "style": "background", "fallbackColor": "#333333",
                           "fallbackLabel": "no heartbeat yet",
                           "rules": [{"operator": "=", "rawValue": str(int(mode)), "color": MODE_COLOURS[mode.name],
                                      "label": mode.name} for mode in Mode]},
        "Plot!curve": _plot("Learning curve: time held per episode [s]", [
            ("/agent/EPISODE_END.duration_s", "duration")], x_axis="index"),
        "Image!value": {"imageMode": {"imageTopic": VALUE_IMAGE}},
        "Image!policy": {"imageMode": {"imageTopic": POLICY_IMAGE}},
        "Parameters!agent": {"title": "The agent's parameters (a learner restart: set it twice to confirm)"},
        # the agent's log and the run's events (alarms, markers, commands) as foxglove.Log: each kept, none overwritten
        "RosOut!log": {"topicToRender": LOG_TOPIC, "searchTerms": [], "minLogLevel": 1},
    }
    buttons = [f"CallService!{service}" for service, _, _, _ in BUTTONS]
    for (service, label, colour, request), panel in zip(BUTTONS, buttons, strict=True):
        panels[panel] = _button(service, label, colour, request)
    button_row: Node = buttons[-1]
    for panel in reversed(buttons[:-1]):  # equal widths: each splits off its share of what is left
        button_row = row(panel, button_row, round(100 / (len(buttons) - buttons.index(panel))))
    return {
        "configById": panels,
        "globalVariables": {},
        "userNodes": {"depth-bounds": {"name": "depth bounds", "sourceCode": BOUNDS_SCRIPT},
                      "battery-volts": {"name": "battery volts", "sourceCode": VOLTS_SCRIPT}},
        "playbackConfig": {"speed": 1},
        "layout": column(
            button_row,
            row(column("Plot!depth", row("Plot!battery", "Indicator!mode", 60), 65),
                column(row("Image!value", "Image!policy", 50), row("Plot!curve", column(
                    "Parameters!agent", "RosOut!log", 50), 40), 55), 55),
            10,
        ),
    }


def main() -> None:
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(layout(), indent=2) + "\n")
    LIVE_OUT.write_text(json.dumps(live_layout(), indent=2) + "\n")
    print(OUT, LIVE_OUT)


if __name__ == "__main__":
    main()
