"""An example of your own agent: it walks where the oracle's direction answers send it.

Before every action it asks the oracle "Which direction should I turn to?". Then it does what the
answer says:
- "go straight ahead": MoveAhead;
- "turn left" / "turn right": RotateLeft / RotateRight;
- "turn around": RotateLeft (the next answer says the rest);
- "You don't need to move.": Stop.

A MoveAhead that the furniture blocks is followed by a turn to the side that was not tried last.

It never interacts with an object, so it can only succeed at going somewhere: the Move tasks. It
shows what the dialogue is worth to a performer that listens. It is written against the public
agent protocol only, as your agent would be:

    ./dialfred launch eval --agent examples.direction_follower:DirectionFollower \\
        --questioner examples.direction_follower:AskForDirections

Or as one agent that asks by itself (`DirectionAsker`: a protocol.DialogueAgent, with its own
`ask(observation)`; the evaluation then starts the oracle without a questioner):

    ./dialfred launch eval --agent examples.direction_follower:DirectionAsker

Run from the repository's root, `examples` is importable as it is (with `--local` too). On valid_unseen
it reaches the goal in 125 of the 169 Move tasks (74.0%, 15.1 questions a task; the Move row of the
first command's table, with `--local`).
"""

from __future__ import annotations

from dialfred_sim.protocol import QA, Observation, Question

ADVICE = (('straight ahead', 'MoveAhead'), ('turn left', 'RotateLeft'), ('turn right', 'RotateRight'),
          ('turn around', 'RotateLeft'), ("don't need to move", 'Stop'))


class AskForDirections:
    """The questioner: one direction question before every action."""

    name = 'directions'

    def reset(self, task, seed: int) -> None:
        self._asked_at = -1

    def ask(self, observation, step: int):
        if self._asked_at == step:
            return None
        self._asked_at = step
        return Question('direction')

    def hear(self, qa: QA) -> None:
        pass


class DirectionFollower:
    """The performer: follows the last direction answer it heard."""

    name = 'direction_follower'

    def __init__(self, resolution: int = 128):
        self.resolution = resolution
        self.reset(None, 0)

    def reset(self, task, seed: int) -> None:
        self.advice = ''
        self.last_action = ''
        self.turn_next = 'RotateLeft'

    def hear(self, qa: QA) -> None:
        if qa.question.question_type == 'direction' and qa.valid:
            self.advice = qa.answer

    def act(self, observation: Observation):
        blocked = self.last_action == 'MoveAhead' and not observation.last_action_success
        action = next((a for words, a in ADVICE if words in self.advice), 'Stop')
        if blocked and action == 'MoveAhead':
            # Walk around the obstacle: alternate the side we turn to.
            action, self.turn_next = self.turn_next, ('RotateRight' if self.turn_next == 'RotateLeft'
                                                      else 'RotateLeft')
        self.last_action = action
        return (action, -1, -1)


class DirectionAsker(DirectionFollower):
    """The follower asking for itself: a direction question before every action (as AskForDirections)."""

    name = 'direction_asker'

    def reset(self, task, seed: int) -> None:
        super().reset(task, seed)
        self._asked = False

    def ask(self, observation):
        if self._asked:
            return None
        self._asked = True
        return Question('direction')

    def act(self, observation):
        self._asked = False          # the next action gets its own question
        return super().act(observation)
