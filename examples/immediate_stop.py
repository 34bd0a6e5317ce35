"""A baseline agent that does nothing: its first action is Stop.

It measures what a metric gives for no work at all. Success and PWSR are 0 by construction; GC
counts only the goal conditions that did not already hold at the task's start, so it is 0 too
(docs/dataset.md, "Metrics"). Before that rule, this agent scored GC 66.7% on every Clean, Cool
and Heat task (the object already in hand, the appliance already closed).

    ./dialfred launch eval --agent examples.immediate_stop:ImmediateStop
"""

from __future__ import annotations


class ImmediateStop:
    """Stop at once, in every task."""

    name = 'immediate_stop'

    def __init__(self, resolution: int = 128):
        self.resolution = resolution

    def reset(self, task, seed: int) -> None:
        pass

    def act(self, observation):
        return ('Stop', -1, -1)
