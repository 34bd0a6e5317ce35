"""`PerformerAgent`: the performer as an agent of the evaluation (no ROS).

`reset(task, seed)` starts an episode of a `dialfred_sim.tasks.PublicTask` (the instruction and its
nouns; an agent never gets more); `hear(qa)` adds a QA of the dialogue, asked at the current step
(the number of actions taken so far), so it is seen from this step on, as in training;
`act(observation)` returns (action, x, y) with the pixel in the observation's frame (-1, -1 for
moves); `action_probabilities(observation)` gives the probabilities over `ACTIONS` of the action
`act` would choose now (for the model-confusion questioner), computed once per step and observation.

The observation is a `protocol.Observation` (or, called by hand, an HxWx3 uint8 frame: `as_observation`);
the agent reads its frame and `last_action_success`. Frames go through `preprocess.frame_tensor`, the path
training uses. Each frame is encoded once. The step itself is the model's (`Performer.step` over a
`StepState`, `Performer.advance` past it): the agent keeps the task, the dialogue and that state.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

import numpy as np
import torch

from dialfred_sim.protocol import ACTIONS, QA, Decision, Observation, as_observation

from .data import INTERACTION_IDS, MOVE_AHEAD
from .model import Performer, StepInputs, StepOutputs, load_checkpoint
from .nn import PerceivedFrames
from .nn.enc_action import failed_id
from .nn.heads import cell_centre_pixel
from .preprocess import AskedQA, Vocabulary, encode_language

TURNS = (ACTIONS.index('RotateLeft'), ACTIONS.index('RotateRight'))


class PerformerAgent:
    """A trained (or untrained) `Performer` playing one episode at a time; greedy decisions.

    With `incremental` (the default) a step computes only its own tokens against cached keys and
    values of the earlier steps (`Performer.step`), so a decision does not slow down as the
    episode grows; without it, or once the dialogue outgrows the model's `max_tokens` (the oldest QAs
    are then dropped, which moves every later token), the transformer reads the whole episode again
    at every step (`Performer.decode`, the training path). Both give the same decisions up to float
    rounding (tested)."""

    name = 'performer'

    def __init__(self, model: Performer, vocab: Vocabulary, incremental: bool = True,
                 pointer_mode: Optional[str] = None):
        if len(vocab) != model.vocab_size:
            raise ValueError(f'the vocabulary has {len(vocab)} words, the model {model.vocab_size}')
        self.model = model.eval()
        self.vocab = vocab
        self.config = model.config
        self.incremental = incremental
        self.pointer_mode = pointer_mode or model.pointer_mode      # Performer.pointer_mode; 'keys' makes them all
        if isinstance(self.model.visual, PerceivedFrames):
            self.model.visual.to_channels_last()
        self.reset_state()

    @classmethod
    def from_checkpoint(cls, path: Path, incremental: bool = True, pointer_mode: Optional[str] = None) -> 'PerformerAgent':
        model, vocab, _ = load_checkpoint(path)
        return cls(model, vocab, incremental, pointer_mode)

    def reset_state(self) -> None:
        self.task = None
        self.instruction = ''
        self.dialogue: list[AskedQA] = []
        self.state = self.model.new_state(self.incremental, self.pointer_mode)    # all it keeps of the model's
        self._pending: Optional[tuple] = None        # (observation, (step, dialogue length), outputs)

    @property
    def step(self) -> int:
        """The actions taken in this episode so far."""
        return self.state.step

    def reset(self, task: Any, seed: int = 0) -> None:
        """Start an episode of `task` (a PublicTask: only its instruction is read)."""
        self.reset_state()
        self.task = task
        self.instruction = task.instruction
        torch.manual_seed(seed)

    def hear(self, qa: QA) -> None:
        """A QA of the dialogue, asked now (before the action of the current step)."""
        self.dialogue.append(AskedQA(qa, self.step))

    def language_input(self):
        """The language the model reads now (preprocess.encode_language over the dialogue so far; an answer
        stream for a model trained on answers at any step, kept whole: its positions never outgrow the table)."""
        if self.config.stream_answers:
            return encode_language(self.vocab, self.instruction, self.dialogue, stream=True, table=self.config.max_tokens,
                                   fresh=self.config.fresh_types)
        return encode_language(self.vocab, self.instruction, self.dialogue, self.config.max_tokens)

    def _outputs(self, observation: Observation) -> StepOutputs:
        """The model's outputs for the current step and observation (`Performer.step`, computed once per step
        and dialogue)."""
        if self.task is None:
            raise RuntimeError('reset() the agent before it acts')
        key = (self.step, len(self.dialogue))
        if self._pending is not None and self._pending[0] is observation and self._pending[1] == key:
            return self._pending[2]
        obs = as_observation(observation)
        if self.config.failure_input:
            self._note_failure(obs)
        lang = self.language_input()
        dropped = not self.config.stream_answers and \
            len(lang) < len(encode_language(self.vocab, self.instruction, self.dialogue))
        result = self.model.step(self.state, StepInputs(self.model.frame_input(obs.rgb), obs.rgb.shape[:2], lang,
                                                        dropped))
        self._pending = (observation, key, result)
        return result

    def _note_failure(self, observation: Observation) -> None:
        """With the failure input: the previous action becomes its failed id if it was an interaction (or, with
        `failed_moves`, a MoveAhead) and the observation says it failed (`last_action_success`)."""
        previous = self.state.previous_actions[-1]
        kinds = INTERACTION_IDS + ((MOVE_AHEAD,) if self.config.failed_moves else ())
        if previous in kinds and not observation.last_action_success:
            self.state.previous_actions[-1] = failed_id(previous, len(ACTIONS))

    def action_probabilities(self, observation: Observation) -> np.ndarray:
        """Probabilities over ACTIONS of the next action given `observation` (the model's: `act` takes the likeliest,
        but for a `failed_moves` model's turn after a bump)."""
        return torch.softmax(self._outputs(observation).action_logits, -1).numpy()

    def act(self, observation: Observation) -> Decision:
        """The next (action, x, y); for an interaction, (x, y) is the centre of the pointer's cell
        in the observation's frame. With `failed_moves`, right after a MoveAhead the world blocked (from the same
        pose it would fail again), the likelier of the two turns."""
        out = self._outputs(observation)
        grid = out.grid
        logits = out.action_logits
        if self.config.failed_moves and self.state.previous_actions[-1] == failed_id(MOVE_AHEAD, len(ACTIONS)):
            # The world is deterministic: from the same pose the blocked MoveAhead would fail again; a turn
            # starts the way round (the guided walks' sidesteps, which the model learnt, start so).
            action = max(TURNS, key=lambda a: float(logits[a]))
        else:
            action = int(logits.argmax())
        x = y = -1
        if action in INTERACTION_IDS:
            grid, pointer_logits = self.model.step_pointer(out)
            height, width = out.frame_size
            x, y = cell_centre_pixel(int(pointer_logits.argmax()), self.config.grid_size, width, height)
        self.model.advance(self.state, out, action, grid)
        self._pending = None
        return ACTIONS[action], x, y
