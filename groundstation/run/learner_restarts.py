"""A run's learner chapters, live: one line when the agent's learner restarts, and the run's episode count across.

A learner restart (SPEC.md 1.3 s. 6) numbers the agent's episodes from 1 again. The run counts its episodes across
restarts (the agent's CMD_START budget does too), so it keeps an offset: the episodes of the chapters before. A 1.3
agent says its generation in every HEARTBEAT and episode frame; for a 1.0-1.2 agent (generation 0) a restart shows
as its episode counter going back. Who caused it: a learner-resetting command this ground sent (the run's own, or a
tool's through the run's hub), else the agent's TEXT about it, else someone this ground does not see (another
ground, the robot's button).
"""

from __future__ import annotations

from dataclasses import dataclass

from groundstation.recording.chapters import restart_words
from protocol import AckResult, NodeKind
from protocol import messages as m
from protocol.parameters import PARAMS

# SPEC.md s. 13's learner parameters, by name and index: a PARAM_SET that changes one restarts the learner.
_LEARNER_PARAMS = frozenset({p.name for p in PARAMS if p.learner} | {p.index for p in PARAMS if p.learner})


@dataclass
class Chapter:
    """Where the run is: the chapter (1, 2, ... in this run) and the learner generation the agent named."""

    number: int = 1
    generation: int = 0  # 0 until the agent names one (never, for a 1.0-1.2 agent)
    boot_id: int | None = None
    last_episode: int = 0  # the highest episode number seen in this chapter
    episode_base: int = 0  # the run's episodes done = the agent's episode counter - episode_base


class LearnerRestarts:
    """Follows the live frames (none backfilled) and the commands sent; `restart_line` once per new chapter."""

    def __init__(self) -> None:
        self.chapter = Chapter()
        self._asked = ""  # the learner-resetting command this ground sent last, until its ACK
        self._caused = ""  # ... and once it was accepted, until the restart shows
        self._said = ""  # the agent's TEXT about a restart, until the restart shows

    def started_at(self, episode: int) -> None:
        """The run began with the agent's episode counter here (an agent already learning counts on)."""
        self.chapter.episode_base = self.chapter.last_episode = episode

    def sent(self, message: m.Message) -> None:
        if isinstance(message, m.ResetModel):
            self._asked = "CMD_RESET_MODEL"
        elif isinstance(message, m.ParamSet) and (message.name or message.index) in _LEARNER_PARAMS:
            self._asked = f"PARAM_SET {message.name or f'#{message.index}'}"

    def received(self, message: m.Message) -> str | None:
        """A live frame; the line to print if it shows a new chapter."""
        c = self.chapter
        if isinstance(message, m.Ack):
            if self._asked and message.cmd_msg_id in (m.ResetModel.MSG_ID, m.ParamSet.MSG_ID):
                self._caused = self._asked if message.result == AckResult.ACCEPTED else self._caused
                self._asked = ""
            return None
        if isinstance(message, m.Text):
            if restart_words(message.text):
                self._said = message.text
            return None
        if isinstance(message, m.Hello) and message.node_kind == NodeKind.AGENT:
            if c.boot_id is not None and message.boot_id != c.boot_id:
                return self._restart(message.generation, "the agent rebooted", message.boot_id)
            c.boot_id = message.boot_id
            return self._generation(message.generation)
        if isinstance(message, m.Heartbeat | m.EpisodeStart | m.EpisodeEnd):
            line = self._generation(message.generation)
            if line is None and not message.generation and message.episode < c.last_episode and (
                    isinstance(message, m.Heartbeat) or message.episode <= 1):
                line = self._restart(0, "", c.boot_id, inferred=True)  # a 1.0-1.2 agent: its counter went back
            c.last_episode = max(c.last_episode, message.episode)
            return line
        return None

    def _generation(self, generation: int) -> str | None:
        c = self.chapter
        if not generation or generation == c.generation:
            return None
        if not c.generation:  # the first the agent named: this is where the run began, no restart
            c.generation = generation
            return None
        return self._restart(generation, "", c.boot_id)

    def _restart(self, generation: int, why: str, boot_id: int | None, inferred: bool = False) -> str:
        c = self.chapter
        # A learner-resetting command still awaiting its ACK counts: the agent's frames of the new generation may
        # overtake the ACK on the wire (a HEARTBEAT sent in the same step).
        caused = self._caused or self._asked
        cause = why or caused and f"{caused} sent by this run or a tool attached to it" or \
            self._said and f"the agent said \"{self._said}\"" or \
            "not through this ground (another ground, or the robot itself)"
        done = c.last_episode - c.episode_base
        self.chapter = Chapter(c.number + 1, generation, boot_id, 0, -done)
        self._caused = self._said = self._asked = ""
        named = f", generation {generation}" if generation else ", inferred: the agent sends no generation (SPEC 1.2)"
        return (f"the learner restarted ({cause}): chapter {c.number + 1}{named}; its episodes number from 1 again, "
                f"the run's count goes on from {done}")

    def run_episodes(self, agent_episode: int) -> int:
        """The run's episodes done, from the agent's episode counter in the current chapter."""
        return agent_episode - self.chapter.episode_base
