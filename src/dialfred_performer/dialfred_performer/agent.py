"""`PerformerAgent`: the performer as an agent of the evaluation (no ROS).

`reset(task, seed)` starts an episode of a `dialfred_sim.tasks.PublicTask` (the instruction and its
nouns; an agent never gets more); `hear(qa)` adds a QA of the dialogue, asked at the current step
(the number of actions taken so far), so it is seen from this step on, as in training;
`act(observation)` returns (action, x, y) with the pixel in the observation's frame (-1, -1 for
moves); `action_probabilities(observation)` gives the probabilities over `ACTIONS` of the action
`act` would choose now (for the model-confusion questioner), computed once per step and observation.

The observation is a `protocol.Observation` (or, called by hand, an HxWx3 uint8 frame: `as_observation`);
the agent reads its frame and `last_action_success`. Frames go through `preprocess.frame_tensor`, the path
training uses. Each frame is encoded once; at every step the transformer reads the whole episode.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple, Optional

import numpy as np
import torch

from dialfred_sim.protocol import ACTIONS, QA, Decision, Observation, as_observation

from .data import INTERACTION_IDS, START
from .model import Performer, camera_pitches, load_checkpoint
from .nn import PerceivedFrames
from .nn.enc_action import failed_id
from .nn.heads import cell_centre_pixel
from .preprocess import AskedQA, Vocabulary, encode_language, frame_tensor


class StepOutputs(NamedTuple):
    """What the model makes of the current step's observation (PerformerAgent._outputs)."""

    action_logits: torch.Tensor              # [13]
    pointer_logits: Optional[torch.Tensor]   # [C]; None under lazy_pointer until an interaction needs them
    frame_size: tuple[int, int]              # the observation frame's (height, width)
    embedding: torch.Tensor                  # the frame's embedding
    grid: Optional[torch.Tensor]             # the frame's pointer keys [1, C, k], or None (lazy_pointer)
    cache: Optional[Any]                     # the decoder's cache extended by this step, or None
    n_lang: int                              # language tokens read
    h: Optional[torch.Tensor]                # the step's decoder output (incremental steps), or None
    frame: torch.Tensor                      # the frame tensor
    encoded: Optional[tuple]                 # the perception network's encoder maps (lazy_pointer), or None
    perceived: Optional[Any] = None          # the network's output (keyless_pointer), or None


class PerformerAgent:
    """A trained (or untrained) `Performer` playing one episode at a time; greedy decisions.

    With `incremental` (the default) a step computes only its own tokens against cached keys and
    values of the earlier steps (`Performer.decode_step`), so a decision does not slow down as the
    episode grows; without it, or once the dialogue outgrows the model's `max_tokens` (the oldest QAs
    are then dropped, which moves every later token), the transformer reads the whole episode again
    at every step (`Performer.decode`, the training path). Both give the same decisions up to float
    rounding (tested)."""

    name = 'performer'

    def __init__(self, model: Performer, vocab: Vocabulary, incremental: bool = True):
        if len(vocab) != model.vocab_size:
            raise ValueError(f'the vocabulary has {len(vocab)} words, the model {model.vocab_size}')
        self.model = model.eval()
        self.vocab = vocab
        self.config = model.config
        self.incremental = incremental
        if self.channels_last:
            self.model.visual.to_channels_last()
        self.reset_state()

    @classmethod
    def from_checkpoint(cls, path: Path, incremental: bool = True) -> 'PerformerAgent':
        model, vocab, _ = load_checkpoint(path)
        return cls(model, vocab, incremental)

    def reset_state(self) -> None:
        self.task = None
        self.instruction = ''
        self.dialogue: list[AskedQA] = []
        self.step = 0
        self._embeddings: list[torch.Tensor] = []     # [d] per past step
        self._grids: list[Optional[torch.Tensor]] = []   # [C, d] per past step (None: not made yet, see _grid)
        self._frames: list[Optional[torch.Tensor]] = []   # [1, 3, R, R] per past step whose keys are not made
        self._previous_actions: list[int] = [START]
        self._pending: Optional[tuple] = None        # (observation, (step, dialogue length), outputs)
        self._cache = self.model.encoder.empty_cache() if self.incremental else None
        self._lang_cached = 0                         # language tokens in the cache

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
        """The language the model reads now (preprocess.encode_language over the dialogue so far)."""
        return encode_language(self.vocab, self.instruction, self.dialogue, self.config.max_tokens)

    @property
    def lazy_pointer(self) -> bool:
        """Whether a step makes its frame's pointer keys only when it acts on the frame: the action of a
        performer over a perception network without the reach input does not depend on them, and the
        network's decoder and the key layer are about half of a step's perception."""
        return isinstance(self.model.visual, PerceivedFrames) and not self.config.reach_input

    @property
    def channels_last(self) -> bool:
        """Whether the perception network runs on channels-last tensors (oneDNN's faster layout on a CPU; the
        same numbers up to rounding)."""
        return isinstance(self.model.visual, PerceivedFrames)

    @property
    def keyless_pointer(self) -> bool:
        """Whether a step scores the pixels without making their keys: with the reach input the action reads
        where the pointer points at every step, and the key layer and the upsampling are linear, so the
        query is folded into them (PerceivedFrames.pointer_logits, as training does; the same numbers up to
        rounding, a sixth less time per step). Keys are made only if the whole episode is read again."""
        return isinstance(self.model.visual, PerceivedFrames) and self.config.reach_input

    def _grid(self, t: int) -> torch.Tensor:
        """Step t's pointer keys [C, k], made from its frame on first use (the same numbers as at the step)."""
        if self._grids[t] is None:
            if self.keyless_pointer:
                self._grids[t] = self.model.encode_frames(self._frames[t])[1][0]
            else:
                self._grids[t] = self.model.visual.keys_of(self.model.visual.encode(self._frames[t]))[0]
        return self._grids[t]

    @torch.inference_mode()
    def _outputs(self, observation: Observation) -> StepOutputs:
        """The model's outputs for the current step and observation (computed once per step and dialogue)."""
        if self.task is None:
            raise RuntimeError('reset() the agent before it acts')
        key = (self.step, len(self.dialogue))
        if self._pending is not None and self._pending[0] is observation and self._pending[1] == key:
            return self._pending[2]
        obs = as_observation(observation)
        if self.config.failure_input:
            self._note_failure(obs)
        rgb = obs.rgb
        frame = frame_tensor(rgb, self.config.resolution)[None]
        if self.channels_last:
            frame = frame.contiguous(memory_format=torch.channels_last)
        encoded = perceived = None
        if self.lazy_pointer:
            emb, encoded = self.model.visual.embedding_and_encoded(frame)     # keys_of(encoded) if it interacts
            grid = None
        elif self.keyless_pointer:
            emb, perceived = self.model.visual.embedding_and_output(frame)
            grid = None
        else:
            emb, grid = self.model.encode_frames(frame)
        lang = self.language_input()
        if self._cache is not None and len(lang) < len(encode_language(self.vocab, self.instruction, self.dialogue)):
            self._cache = None           # QAs were dropped to fit max_tokens: positions moved
        if self._cache is not None:
            h, cache = self.model.step_output(
                self._cache, torch.tensor(lang.ids), torch.tensor(lang.types), self._lang_cached, emb[0],
                self._previous_actions[-1], self.step)
            if perceived is not None:
                visual = self.model.visual
                pointer_logits = visual.pointer_logits(perceived, self.model.pointer_head.query(h)[None])[0] * \
                    self.model.pointer_head.scale
                action_logits = self.model._actions(h, pointer_logits, visual.distances(perceived)[0], self._pitch())
            elif grid is None:
                action_logits, pointer_logits = self.model.action_head(h), None
            else:
                action_logits, pointer_logits = self.model.heads(h, grid[0], self._pitch())
            result = StepOutputs(action_logits, pointer_logits, rgb.shape[:2], emb[0], grid, cache, len(lang), h,
                                 frame, encoded, perceived)
        else:
            ids = torch.tensor([lang.ids], dtype=torch.long)
            embeddings = torch.stack([*self._embeddings, emb[0]])[None]
            if perceived is not None:
                grid = self.model.visual.grid_of(perceived)
            elif grid is None:
                grid = self.model.visual.keys_of(encoded)
            grids = torch.stack([*(self._grid(t) for t in range(self.step)), grid[0]])[None]
            T = embeddings.shape[1]
            action_logits, pointer_logits = self.model.decode(
                ids, torch.tensor([lang.types]), torch.tensor([lang.steps]), torch.ones_like(ids, dtype=torch.bool),
                embeddings, grids, torch.tensor([self._previous_actions]), torch.ones(1, T, dtype=torch.bool))
            result = StepOutputs(action_logits[0, -1], pointer_logits[0, -1], rgb.shape[:2], emb[0], grid, None,
                                 len(lang), None, frame, encoded)
        self._pending = (observation, key, result)
        return result

    def _pitch(self) -> torch.Tensor:
        """The camera's pitch now, dead reckoned from the actions taken (model.camera_pitches)."""
        return camera_pitches(torch.tensor(self._previous_actions))[-1]

    def _note_failure(self, observation: Observation) -> None:
        """With the failure input: the previous action becomes its failed id if it was an interaction and
        the observation says it failed (`last_action_success`)."""
        previous = self._previous_actions[-1]
        if previous in INTERACTION_IDS and not observation.last_action_success:
            self._previous_actions[-1] = failed_id(previous, len(ACTIONS))

    def action_probabilities(self, observation: Observation) -> np.ndarray:
        """Probabilities over ACTIONS of the next action given `observation`."""
        return torch.softmax(self._outputs(observation).action_logits, -1).numpy()

    @torch.inference_mode()
    def _pointer(self, h: torch.Tensor, encoded: tuple) -> tuple[torch.Tensor, torch.Tensor]:
        """(the frame's grid [1, C, k], the pointer logits [C]) of a step whose output is h and whose frame's
        encoder maps are `encoded` (lazy_pointer)."""
        grid = self.model.visual.keys_of(encoded)
        return grid, self.model.pointer_head(h, grid[0])

    def act(self, observation: Observation) -> Decision:
        """The next (action, x, y); for an interaction, (x, y) is the centre of the pointer's cell
        in the observation's frame."""
        out = self._outputs(observation)
        grid, pointer_logits = out.grid, out.pointer_logits
        action = int(out.action_logits.argmax())
        x = y = -1
        if action in INTERACTION_IDS:
            if pointer_logits is None:
                grid, pointer_logits = self._pointer(out.h, out.encoded)
            height, width = out.frame_size
            x, y = cell_centre_pixel(int(pointer_logits.argmax()), self.config.grid_size, width, height)
        self._embeddings.append(out.embedding)
        self._grids.append(None if grid is None else grid[0])
        self._frames.append(out.frame if grid is None else None)     # kept only to make the keys later
        self._previous_actions.append(action)
        if self._cache is not None:
            self._cache, self._lang_cached = out.cache, out.n_lang
        self.step += 1
        self._pending = None
        return ACTIONS[action], x, y
