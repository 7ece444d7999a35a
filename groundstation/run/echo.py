"""The run pane's echo of an operator's command: one line saying who sent what through the hub and the answer.

A tank day has several tools on one run (a `dive target` in one pane, Foxglove's buttons in a browser): the run's
pane says each command, as MAVProxy's console does, so the operator watching it knows why the agent changed. Reads
(PARAM_GET, PARAM_LIST) and a dump's chunk requests are not commands anybody needs to see: they are not echoed.
"""

from __future__ import annotations

from typing import Any

from groundstation.safe_output import one_line
from protocol import AckResult, DumpKind, Message, Mode
from protocol import messages as m


def command_text(message: Message) -> str | None:
    """What an operator would have typed for `message` ("target 0.6 m"), or None for one not echoed."""
    if isinstance(message, m.SetTarget):
        return f"target {message.target_depth_m:g} m"
    if isinstance(message, m.Hover):
        return f"hover {message.depth_m:g} m"
    if isinstance(message, m.ParamSet):
        name = message.name if message.index < 0 else f"parameter #{message.index}"
        return f"set {one_line(name)} = {message.value:g}"
    if isinstance(message, m.StartLearning):
        return "start" + (f" ({message.max_episodes} episodes)" if message.max_episodes else "")
    if isinstance(message, m.DumpRequest):
        if message.dump_id or message.offset:
            return None  # a chunk of a dump already asked for
        kind = DumpKind(message.kind).name.lower() if message.kind in DumpKind._value2member_map_ else message.kind
        return f"dump {kind}"
    simple = {m.Stop: "stop", m.Pause: "pause", m.Surface: "surface", m.ResetModel: "reset-model"}
    return simple.get(type(message))


def answer_text(ack: m.Ack, mode: int | None) -> str:
    """`accepted (the agent was RECOVERING)` or `refused: NOT_ALLOWED_IN_MODE (...)`."""
    was = Mode(mode).name if mode is not None and mode in Mode._value2member_map_ else "in an unknown mode"
    result = AckResult(ack.result).name if ack.result in AckResult._value2member_map_ else f"result {ack.result}"
    reason = f", {one_line(ack.reason)}" if ack.reason else ""
    verdict = "accepted" if ack.result == AckResult.ACCEPTED else f"refused ({result}{reason})"
    return f"{verdict}; the agent was {was}"


def echo(tool: str, message: Message, ack: m.Ack, mode: int | None) -> tuple[str, dict[str, Any]] | None:
    """The run pane's line for a tool's command and its answer, and the `command` event's data; None: not echoed."""
    what = command_text(message)
    if what is None:
        return None
    data: dict[str, Any] = {"command": message.DEFINITION.name, "tool": tool,
                            "accepted": ack.result == AckResult.ACCEPTED, "result": ack.result}
    if isinstance(message, m.SetTarget):
        data["target_depth_m"] = round(message.target_depth_m, 6)  # the f32 as typed, not 0.6000000238418579
    return f"{tool}: {what}: {answer_text(ack, mode)}", data
