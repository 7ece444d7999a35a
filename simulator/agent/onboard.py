"""The on-board program as the server sees it: the Python reference or the C firmware, behind one interface.

The server (server.py) owns the transport, the faults and the pacing; an OnboardAgent owns everything the
agent itself does: its link layer, its program and the simulated hardware it runs on.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import numpy as np

from learning import LearnerConfig
from simulator.agent.batch import StepBatcher
from simulator.agent.hardware import SimulatedHardware
from simulator.agent.link import AgentLink, LinkWire
from simulator.agent.mission import MissionConfig
from simulator.agent.program import OnboardProgram
from simulator.parameters import PlantParams

Write = Callable[[bytes], None]  # takes the wire bytes of one frame


class OnboardAgent(Protocol):
    """What AgentServer drives: bytes in, frames out through `write`, agent time advancing one step per call."""

    @property
    def t_us(self) -> int:
        """Agent time."""

    @property
    def next_seq(self) -> int:
        """The seq the agent's next frame gets."""

    @property
    def true_depth_m(self) -> float:
        """The plant's depth (for the radio blackout model only)."""

    def step(self) -> None:
        """One control step of the program, then its period of agent time passes."""

    def receive(self, data: bytes) -> None:
        """Whatever the link delivered."""

    def service(self) -> None:
        """Called every loop of the server, steps or not: the HELLO repeat until the ground is heard."""

    @property
    def work_after_ack(self) -> bool:
        """A command was ACKed whose effect takes long (a learner restart): the server lets its ACK leave first."""

    def finish_command(self) -> None:
        """Run that effect now."""

    def link_up(self) -> None:
        """A new connection: sequence tracking restarts, HELLO goes out."""

    def link_down(self) -> None:
        """The connection closed."""

    def counters(self) -> dict[str, int]:
        """next_sample, signing_rejects, rx_lost and rx_rejects, for serve --report."""


class PythonAgent:
    """The Python reference: AgentLink + OnboardProgram over SimulatedHardware."""

    def __init__(self, plant: PlantParams, learner: LearnerConfig, mission: MissionConfig, rng: np.random.Generator,
                 write: Write, node_id: int, key: bytes | None, link_clock_s: Callable[[], float] | None = None,
                 mark_file: Path | None = None, wire: LinkWire | None = None) -> None:
        self.link = AgentLink(write, node_id=node_id, key=key, link_clock_s=link_clock_s, mark_file=mark_file,
                              wire=wire)
        self.hw = SimulatedHardware(plant, rng)
        self.program = OnboardProgram(plant, learner, mission, self.hw, rng, self.link)
        self.link.attach(self.program)
        self._batcher = StepBatcher(self.program, self.link)

    @property
    def t_us(self) -> int:
        return self.hw.t_us

    @property
    def next_seq(self) -> int:
        return self.link.next_seq

    @property
    def true_depth_m(self) -> float:
        return self.hw.true_depth_m

    def take_over(self) -> None:
        """Called once, when the program starts serving a link a starting agent kept (serve/starting.py)."""
        self.link.take_over()

    def step(self) -> None:
        self.program.step()
        self.link.tick()

    def run(self, max_steps: int, until_us: int) -> int:
        """Up to max_steps steps until agent time reaches until_us, in compiled batches; their frames in few writes.

        Frame for frame what as many step() calls would send and log; `write` gets several frames per call.
        """
        return self._batcher.run(max_steps, until_us)

    def receive(self, data: bytes) -> None:
        self.link.receive(data)

    def service(self) -> None:
        self.link.service()

    @property
    def work_after_ack(self) -> bool:
        return self.program.restart_pending

    def finish_command(self) -> None:
        self.program.finish_command()

    def link_up(self) -> None:
        self.link.on_connect()

    def link_down(self) -> None:
        self.link.on_disconnect()

    def counters(self) -> dict[str, int]:
        stats = self.link.decoder.stats
        return {"next_sample": self.program.next_sample, "signing_rejects": self.link.signing_rejects,
                "rx_lost": stats.lost, "rx_rejects": stats.rejects}
