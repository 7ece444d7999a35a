"""The value function and the policy as Foxglove RawImages after each dump, in the live view's colours."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from foxglove import Context
from foxglove.channels import RawImageChannel
from foxglove.messages import RawImage, Timestamp
from numpy.typing import NDArray

from groundstation.session.dumps import Dump
from groundstation.view.heatmap import DEFAULT_GRID, dump_grid, policy_image, untried_cells, value_image
from protocol import DumpKind

VALUE_TOPIC = "/value_function/image"
POLICY_TOPIC = "/policy/image"
IMAGE_PIXELS = 320  # the longer side: a 10 x 10 grid is 10 pixels, which an Image panel would smear when it scales up


def scaled(cells: NDArray[np.uint8], pixels: int = IMAGE_PIXELS) -> NDArray[np.uint8]:
    """One square block of pixels per cell, so every viewer shows sharp cells whatever its scaling."""
    factor = max(1, pixels // max(cells.shape[0], cells.shape[1]))
    return np.ascontiguousarray(np.repeat(np.repeat(cells, factor, axis=0), factor, axis=1))


class DumpImages:
    """Draws VALUES and POLICY dumps over the learner's grid (rows: depth, shallow on top; columns: velocity)."""

    def __init__(self, context: Context, sinks: Callable[[str], list[int]] | None = None) -> None:
        # to whom an image goes: each subscribed owner's client (sinks(topic)); None: every subscriber (tests)
        self._sinks = sinks
        self._value = RawImageChannel(VALUE_TOPIC, context=context)
        self._policy = RawImageChannel(POLICY_TOPIC, context=context)
        self._grid = dict(DEFAULT_GRID)  # the agent's values replace the defaults as its PARAM_VALUEs arrive
        self._untried: NDArray[np.bool_] | None = None  # from the latest POLICY dump: cells the agent never left
        self._values: Dump | None = None  # the latest VALUES dump, drawn again when its episode's POLICY comes
        self._last: dict[str, tuple[RawImage, int]] = {}  # topic -> its newest image and time, for late subscribers
        self.published = 0

    def saw_parameter(self, name: str, value: float) -> None:
        if name in self._grid:
            self._grid[name] = value

    def publish(self, dump: Dump, host_ns: int) -> None:
        if dump.kind not in (DumpKind.VALUES, DumpKind.POLICY):
            return
        g = self._grid
        grid = dump_grid(len(dump.values()), g["target_depth_m"], g["z_tol_m"], g["zdot_tol_mps"], int(g["z_cells"]),
                         int(g["zdot_cells"]))
        if grid is None:
            return  # not one row of cells: nothing to draw
        if dump.kind == DumpKind.VALUES:
            self._values = dump
            self._log(self._value, value_image(np.asarray(dump.values(), np.float32), grid.zdot_cells, self._untried),
                      dump.episode, host_ns)
            return
        actions = np.asarray(dump.values(), np.uint8)
        self._untried = untried_cells(actions)
        self._log(self._policy, policy_image(actions, grid.zdot_cells), dump.episode, host_ns)
        values = self._values
        if values is not None and values.episode == dump.episode and len(values.values()) == len(actions):
            # the agent sends VALUES, then POLICY: the value image again, its untried cells grey from this policy
            self._log(self._value, value_image(np.asarray(values.values(), np.float32), grid.zdot_cells,
                                               self._untried), values.episode, host_ns)

    def _log(self, channel: RawImageChannel, cells: NDArray[np.uint8], episode: int, host_ns: int) -> None:
        pixels = scaled(cells)
        height, width = pixels.shape[:2]
        stamp = Timestamp(sec=host_ns // 1_000_000_000, nsec=host_ns % 1_000_000_000)
        image = RawImage(timestamp=stamp, frame_id=f"episode {episode}", width=width, height=height,
                         encoding="rgb8", step=3 * width, data=pixels.tobytes())
        self._last[channel.topic()] = (image, host_ns)
        if self._sinks is None:
            channel.log(image, log_time=host_ns)
        else:  # never broadcast: a client that did not come through the door (gate.py) subscribes too
            for sink_id in self._sinks(channel.topic()):
                channel.log(image, log_time=host_ns, sink_id=sink_id)
        self.published += 1

    def replay(self, topic: str, sink_id: int) -> bool:
        """The newest image of `topic` to one client (channels.replay); whether `topic` is an image's."""
        channels = {VALUE_TOPIC: self._value, POLICY_TOPIC: self._policy}
        if topic not in channels:
            return False
        last = self._last.get(topic)
        if last is not None:
            channels[topic].log(last[0], log_time=last[1], sink_id=sink_id)
        return True
