"""The Episodic-Transformer performer (DialFRED paper, "Performer"; Pashevich et al. 2021), trained
from scratch: `PerformerConfig`, `Performer`, its loss, and checkpoints.

`Performer.forward(batch)` runs whole episodes with teacher forcing (a padded batch made by
`dialfred_performer.data.collate`); at step t it predicts the expert's action from the instruction,
the QAs asked at steps <= t, the frames of steps <= t and the actions before t, and, for an
interaction, the cell of the frame's feature grid that holds the target pixel.
An episode is played one step at a time by `Performer.step(state, inputs)` over a `StepState` (the
frames' embeddings and keys so far, the actions taken, the decoder's cache), advanced by
`Performer.advance`: the same `encode_frames` and encoder, incrementally or over the whole episode again;
an agent (`agent.py`) keeps only that state.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple, Optional

import torch
import torch.nn.functional as F
from torch import nn

from dialfred_sim.dataclass_cli import arg
from dialfred_sim.metrics import git_commit
from dialfred_sim.protocol import ACTIONS, BODY, MAX_STEPS

from .nn import ActionEmbedding, ActionHead, LanguageEncoder, MultimodalEncoder, PerceivedFrames, PointerHead, VisualEncoder
from .perception import Perception, PerceptionNetConfig, native_bf16
from .preprocess import Vocabulary, frame_tensor, n_token_types
from .shipped import SHIPPED_CHECKPOINT  # noqa: F401 - where the modules that load checkpoints find it

CHECKPOINT_FORMAT = 'dialfred-performer/1'


@dataclass(frozen=True)
class PerformerConfig:
    """Sizes of the performer. The vocabulary size comes from the vocabulary it is built with."""

    resolution: int = arg(64, 'frames are resized to resolution x resolution pixels (a multiple of 8)')
    d_model: int = arg(128, 'the width of the transformer (every token and frame embedding)')
    heads: int = arg(4, "the transformer's attention heads")
    layers: int = arg(2, "the transformer's layers")
    ff: int = arg(256, 'the width of each layer\'s feed-forward block')
    dropout: float = arg(0.1, 'dropout in the transformer while training')
    max_tokens: int = arg(256, 'language tokens the model reads: the instruction and every QA')
    max_steps: int = arg(MAX_STEPS, 'frames of one episode (the simulator truncates at MAX_STEPS)')
    visual: str = arg('cnn', "'cnn': three convolutions learnt through the action loss and a pointer over 8 x 8-pixel "
                      "cells; 'perception': the pretrained Perception network (dialfred_performer.perception), "
                      'frozen, and a pointer over every pixel (set by --perception)')
    perception_net: str = arg('', "visual='perception': the network's sizes (JSON of PerceptionNetConfig; set by "
                              '--perception)')
    pointer_key: int = arg(32, "visual='perception': the size of each pixel's pointer key")
    reach_input: bool = arg(False, "visual='perception': the action head also reads how far away what the pointer "
                            "points at is (the network's predicted distance under the pointer's distribution: "
                            '`reach_features`), gradient-free')
    failure_input: bool = arg(False, 'an interaction that failed in the world (the observation\'s last_action_success) '
                              'is a previous action of its own (`failed_id`), learnt from recovery examples '
                              '(--recovery, data.insert_failed_interaction)')
    failed_moves: bool = arg(False, 'with --failure-input: a MoveAhead that something blocked is a previous action of '
                             'its own too (`failed_id`), learnt from guided walks that bump into it (--blocked, '
                             'data.blocked_steps)')
    frozen_arithmetic: str = arg('fp32', "visual='perception': the frozen network's arithmetic while the performer "
                                 "trained ('fp32' or 'bf16', set by --perception-precision); the agent and the "
                                 "questioner's copy run it so where the CPU does bfloat16 natively, else in fp32")
    stream_answers: bool = arg(False, 'the language is an answer stream (preprocess.encode_language(stream=True)): '
                               'a repeat adds nothing, a newer answer of a (type, noun) supersedes the older from its '
                               "step on, each QA's positions restart after the instruction; trained on answers at any "
                               'step (--streams)')
    fresh_directions: bool = arg(False, "with --stream-answers: a direction answer holds for the step it is heard at "
                                 "only (it says where to go from where the agent stood), so one heard at every step "
                                 "is heard afresh at each and one heard once does not steer the steps after it")

    def __post_init__(self):
        if self.visual not in ('cnn', 'perception'):
            raise ValueError(f"visual must be 'cnn' or 'perception', got {self.visual!r}")
        if self.frozen_arithmetic not in ('fp32', 'bf16'):
            raise ValueError(f"frozen_arithmetic must be 'fp32' or 'bf16', got {self.frozen_arithmetic!r}")
        if self.fresh_directions and not self.stream_answers:
            raise ValueError('fresh_directions is a way of reading an answer stream: it needs stream_answers')
        if self.failed_moves and not self.failure_input:
            raise ValueError('failed_moves is a kind of failure input: it needs failure_input')
        if self.visual == 'perception' and not self.perception_net:
            raise ValueError("visual='perception' needs perception_net (train with --perception PATH)")

    @property
    def fresh_types(self) -> tuple[str, ...]:
        """The answer types that hold for the step they are heard at only (preprocess.encode_language's fresh)."""
        return ('direction',) if self.fresh_directions else ()

    @property
    def grid_size(self) -> int:
        """The pointer's cells per side: 8 x 8-pixel cells (cnn) or every pixel (perception)."""
        return self.resolution if self.visual == 'perception' else self.resolution // 8


def build_visual(config: PerformerConfig) -> nn.Module:
    """The frame encoder of a performer with `config` (untrained): a VisualEncoder, or PerceivedFrames
    around a perception network. The questioner builds its frozen copy of a performer's encoder here too.
    The network runs in the arithmetic the performer trained with (`frozen_arithmetic`) where this CPU does
    it natively; a bf16-trained performer runs it in fp32 elsewhere (emulated bfloat16 is about ten times
    slower; the features differ by bfloat16's rounding)."""
    if config.visual == 'perception':
        precision = config.frozen_arithmetic if native_bf16() else 'fp32'
        return PerceivedFrames(config.d_model, config.pointer_key,
                               Perception(PerceptionNetConfig(**json.loads(config.perception_net))),
                               distance=config.reach_input, precision=precision)
    return VisualEncoder(config.d_model, config.resolution)


# The reach input (PerformerConfig.reach_input): the simulator's reach, and what the action head reads.
REACH_METRES = BODY.reach
REACH_FEATURES = ('expected distance / 2 m', 'pointer mass within reach', 'distance at the best pixel / 2 m')


LOOK_UP, LOOK_DOWN = ACTIONS.index('LookUp'), ACTIONS.index('LookDown')


def camera_pitches(previous_actions: torch.Tensor) -> torch.Tensor:
    """Previous action ids [..., T] -> the camera's pitch at each step [..., T] (degrees, down positive),
    dead reckoned as the simulator moves it: BODY.start_horizon at the start, BODY.look_step per LookDown or LookUp,
    held at the limits, where the simulator refuses a look (so no success flag is needed)."""
    delta = BODY.look_step * ((previous_actions == LOOK_DOWN).float() - (previous_actions == LOOK_UP).float())
    out = torch.empty_like(delta)
    pitch = torch.full(delta.shape[:-1], BODY.start_horizon)
    for t in range(delta.shape[-1]):
        pitch = (pitch + delta[..., t]).clamp(BODY.horizon_min, BODY.horizon_max)
        out[..., t] = pitch
    return out


def axis_factors(pitch: torch.Tensor, cells: int) -> torch.Tensor:
    """Camera pitches [...] (degrees) -> [..., cells]: per pixel of a square grid of `cells`, the
    distance of the point seen there from the agent's vertical axis over its distance from the eye
    (the simulator measures reach from the axis, as AI2-THOR does; the network predicts along the ray).
    The camera's own geometry (`reach_lengths`, `ray_lengths`), once per distinct pitch: the looks take
    the pitch through a few values only."""
    size = round(cells ** 0.5)
    pitches, index = torch.unique(pitch.float(), return_inverse=True)
    rays = BODY.ray_lengths(size, size)
    table = torch.stack([torch.from_numpy(BODY.reach_lengths(size, size, p) / rays).float().flatten()
                         for p in pitches.tolist()])
    return table.to(pitch.device)[index]     # the camera's tables are numpy; the pitch may live on a GPU


def reach_features(pointer_logits: torch.Tensor, distances: torch.Tensor) -> torch.Tensor:
    """Pointer logits [..., C] and each pixel's predicted distance from the agent's axis [..., C] (metres)
    -> [..., 3] (REACH_FEATURES): how far away what the pointer points at is, and how much of it lies
    within reach."""
    p = torch.softmax(pointer_logits, -1)
    best = distances.gather(-1, pointer_logits.argmax(-1, keepdim=True))[..., 0]
    return torch.stack([(p * distances).sum(-1) / 2, (p * (distances < REACH_METRES)).sum(-1), best / 2], -1)


class StepInputs(NamedTuple):
    """What one step of an episode reads besides the state (`Performer.step`)."""

    frame: torch.Tensor                      # [1, 3, R, R] (`Performer.frame_input`)
    frame_size: tuple[int, int]              # the observation frame's (height, width)
    lang: Any                                # the language read now (preprocess.encode_language, max_tokens)
    lang_dropped: bool                       # QAs were dropped to fit max_tokens: every position moved


class StepOutputs(NamedTuple):
    """What the model makes of the current step's inputs (`Performer.step`)."""

    action_logits: torch.Tensor              # [13]
    pointer_logits: Optional[torch.Tensor]   # [C]; None in the lazy mode until an interaction needs them
    frame_size: tuple[int, int]              # the observation frame's (height, width)
    embedding: torch.Tensor                  # the frame's embedding
    grid: Optional[torch.Tensor]             # the frame's pointer keys [1, C, k], or None (lazy, keyless)
    cache: Optional[Any]                     # the decoder's cache extended by this step, or None
    n_lang: int                              # language tokens read
    h: Optional[torch.Tensor]                # the step's decoder output (incremental steps), or None
    frame: torch.Tensor                      # the frame tensor
    encoded: Optional[tuple]                 # the perception network's encoder maps (lazy), or None
    perceived: Optional[Any] = None          # the network's output (keyless), or None


@dataclass
class StepState:
    """What the performer carries from one step of an episode to the next: all an agent keeps of the model's
    (`Performer.new_state`, `step`, `advance`). `pointer_mode` says how a step gets the pointer
    (`Performer.pointer_mode`); `cache` holds the decoder's keys and values of the steps so far, or None once
    the whole episode is read again at every step."""

    pointer_mode: str
    previous_actions: list                   # the action token of each step: <start>, then the actions taken
    cache: Optional[Any] = None
    lang_cached: int = 0                     # language tokens in the cache
    step: int = 0
    embeddings: list = dataclasses.field(default_factory=list)    # [d] per past step
    grids: list = dataclasses.field(default_factory=list)         # [C, k] per past step (None: not made yet)
    frames: list = dataclasses.field(default_factory=list)        # [1, 3, R, R] per past step whose keys are not made


class Performer(nn.Module):
    def __init__(self, config: PerformerConfig, vocab_size: int):
        super().__init__()
        if config.reach_input and config.visual != 'perception':
            raise ValueError('reach_input needs a perception network (train with --perception PATH): the '
                             'distances are its predictions')
        self.config = config
        self.vocab_size = vocab_size
        d = config.d_model
        self.language = LanguageEncoder(vocab_size, d, config.max_tokens, n_token_types(), config.dropout)
        self.visual = build_visual(config)
        if config.visual == 'perception':
            self.pointer_head = PointerHead(d, config.pointer_key, project_keys=False)
        else:
            self.pointer_head = PointerHead(d)
        self.actions = ActionEmbedding(len(ACTIONS), d, failures=config.failure_input)
        self.encoder = MultimodalEncoder(d, config.heads, config.layers, config.ff, config.max_steps, config.dropout)
        self.action_head = ActionHead(d, len(ACTIONS))
        if config.reach_input:
            self.reach_head = nn.Sequential(nn.Linear(len(REACH_FEATURES), 32), nn.ReLU(), nn.Linear(32, len(ACTIONS)))
            nn.init.zeros_(self.reach_head[2].weight)      # starts as the action head alone
            nn.init.zeros_(self.reach_head[2].bias)

    def heads(self, h: torch.Tensor, grid: torch.Tensor, pitch: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The step outputs h [..., d] over their frames' grids [..., C, k] (with reach_input, [..., C, k + 1]:
        the last channel is each pixel's predicted distance along its ray), taken at camera pitches [...]
        (`camera_pitches`) -> (action logits [..., 13], pointer logits [..., C])."""
        if not self.config.reach_input:
            return self.action_head(h), self.pointer_head(h, grid)
        pointer = self.pointer_head(h, grid[..., :-1])
        return self._actions(h, pointer, grid[..., -1], pitch), pointer

    def _actions(self, h: torch.Tensor, pointer: torch.Tensor, distances: torch.Tensor,
                 pitch: torch.Tensor) -> torch.Tensor:
        """The action logits from h, where the pointer points and each pixel's distance along its ray at
        camera `pitch` (the reach features read the distance from the agent's axis)."""
        axis = distances * axis_factors(torch.as_tensor(pitch), distances.shape[-1])
        return self.action_head(h) + self.reach_head(reach_features(pointer.detach(), axis))

    def encode_frames(self, frames: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """frames [N, 3, R, R] -> (embedding [N, d], grid [N, C, k]: a key per pointer cell)."""
        return self.visual(frames)

    def hidden(self, lang_ids, lang_types, lang_steps, lang_valid, frame_embedding, previous_actions,
               step_valid, lang_positions=None, lang_until=None) -> torch.Tensor:
        """The multimodal encoder's output [B, T, d] (see decode)."""
        lang = self.language(lang_ids, lang_types, lang_positions)
        return self.encoder(lang, lang_steps, lang_valid, frame_embedding, self.actions(previous_actions), step_valid,
                            lang_until)

    def decode(self, lang_ids, lang_types, lang_steps, lang_valid, frame_embedding, grid, previous_actions,
               step_valid, lang_positions=None, lang_until=None) -> tuple[torch.Tensor, torch.Tensor]:
        """Language [B, L], frame embeddings [B, T, d] with grids [B, T, C, k], previous actions
        [B, T] and valid steps [B, T] -> (action logits [B, T, 13], pointer logits [B, T, C]). An answer
        stream's language also has positions and `until` [B, L] (preprocess.LanguageInput)."""
        h = self.hidden(lang_ids, lang_types, lang_steps, lang_valid, frame_embedding, previous_actions, step_valid,
                        lang_positions, lang_until)
        return self.heads(h, grid, camera_pitches(previous_actions))

    @torch.no_grad()
    def decode_step(self, cache, lang_ids: torch.Tensor, lang_types: torch.Tensor, first_new: int,
                    frame_embedding: torch.Tensor, grid: torch.Tensor, previous_action: int, t: int,
                    pitch: float):
        """Step t of one episode, incrementally (the agent's path; see MultimodalEncoder.step): the
        language so far (lang_ids, lang_types [L]; the tokens from `first_new` on became known at
        step t), the frame's embedding [d] and grid [C, d], the previous action, the camera's pitch
        (`camera_pitches`). Returns (action logits [13], pointer logits [C], the extended cache)."""
        h, cache = self.step_output(cache, lang_ids, lang_types, first_new, frame_embedding, previous_action, t)
        return (*self.heads(h, grid, torch.tensor(pitch)), cache)

    @torch.no_grad()
    def step_output(self, cache, lang_ids: torch.Tensor, lang_types: torch.Tensor, first_new: int,
                    frame_embedding: torch.Tensor, previous_action: int, t: int, lang_positions=None,
                    lang_until=None) -> tuple[torch.Tensor, object]:
        """decode_step before the heads: (the step's output h [d], the extended cache). An answer stream's
        language also has positions and `until` [L]."""
        positions = None if lang_positions is None else lang_positions[None]
        lang = self.language(lang_ids[None], lang_types[None], positions)[0, first_new:]
        action = self.actions(torch.tensor([[previous_action]]))[0, 0]
        return self.encoder.step(cache, lang, frame_embedding, action, t, first_new, lang_until)

    # ------------------------------------------------------------------ one step of an episode (the agent's)
    @property
    def pointer_mode(self) -> str:
        """How an agent's step gets the pointer. 'keys': every frame's pointer keys are made. 'lazy' (over a
        perception network without the reach input, whose action does not depend on them): a frame's keys
        only when the agent acts on it; the network's decoder and the key layer are about half a step's
        perception. 'keyless' (with the reach input, where the action reads where the pointer points at
        every step): the query is folded into the linear key layer and upsampling
        (PerceivedFrames.pointer_logits, as training does; a sixth less time a step); keys are made only if
        the whole episode is read again. The three give the same decisions up to rounding (tested)."""
        if not isinstance(self.visual, PerceivedFrames):
            return 'keys'
        return 'keyless' if self.config.reach_input else 'lazy'

    def new_state(self, incremental: bool = True, pointer_mode: Optional[str] = None) -> StepState:
        """The state before an episode's first step: with `incremental`, steps extend a cache of the decoder's
        keys and values; without, each reads the whole episode again. `pointer_mode`: the model's own if None."""
        mode = pointer_mode or self.pointer_mode
        if mode not in (self.pointer_mode, 'keys'):
            raise ValueError(f'pointer mode {mode!r}: this model takes {self.pointer_mode!r} or keys')
        return StepState(mode, [self.actions.start_id], self.encoder.empty_cache() if incremental else None)

    def frame_input(self, rgb) -> torch.Tensor:
        """An HxWx3 uint8 frame as a step reads it: [1, 3, R, R] at the model's resolution (channels-last over
        a perception network: oneDNN's faster layout on a CPU, the same numbers up to rounding)."""
        frame = frame_tensor(rgb, self.config.resolution)[None]
        return frame.contiguous(memory_format=torch.channels_last) if isinstance(self.visual, PerceivedFrames) else frame

    @torch.inference_mode()
    def step(self, state: StepState, inputs: StepInputs) -> StepOutputs:
        """The action and pointer logits of step state.step. Incremental while the state has a cache and the
        language kept its positions; else the whole episode is read again (`decode`, the training path), the
        keys of earlier frames made where they were not (`step_grid`). The state is not advanced (`advance`)."""
        frame, lang = inputs.frame, inputs.lang
        encoded = perceived = grid = None
        if state.pointer_mode == 'lazy':
            emb, encoded = self.visual.embedding_and_encoded(frame)     # keys_of(encoded) if it interacts
        elif state.pointer_mode == 'keyless':
            emb, perceived = self.visual.embedding_and_output(frame)
        else:
            emb, grid = self.encode_frames(frame)
        positions = None if lang.positions is None else torch.tensor(lang.positions)
        until = None if lang.until is None else torch.tensor(lang.until)
        if state.cache is not None and not inputs.lang_dropped:
            h, cache = self.step_output(state.cache, torch.tensor(lang.ids), torch.tensor(lang.types),
                                        state.lang_cached, emb[0], state.previous_actions[-1], state.step,
                                        positions, until)
            if perceived is not None:
                pointer_logits = self.visual.pointer_logits(perceived, self.pointer_head.query(h)[None])[0] * \
                    self.pointer_head.scale
                action_logits = self._actions(h, pointer_logits, self.visual.distances(perceived)[0],
                                              self.pitch_now(state))
            elif grid is None:
                action_logits, pointer_logits = self.action_head(h), None
            else:
                action_logits, pointer_logits = self.heads(h, grid[0], self.pitch_now(state))
            return StepOutputs(action_logits, pointer_logits, inputs.frame_size, emb[0], grid, cache, len(lang), h,
                               frame, encoded, perceived)
        ids = torch.tensor([lang.ids], dtype=torch.long)
        embeddings = torch.stack([*state.embeddings, emb[0]])[None]
        if perceived is not None:
            grid = self.visual.grid_of(perceived)
        elif grid is None:
            grid = self.visual.keys_of(encoded)
        grids = torch.stack([*(self.step_grid(state, t) for t in range(state.step)), grid[0]])[None]
        T = embeddings.shape[1]
        action_logits, pointer_logits = self.decode(
            ids, torch.tensor([lang.types]), torch.tensor([lang.steps]), torch.ones_like(ids, dtype=torch.bool),
            embeddings, grids, torch.tensor([state.previous_actions]), torch.ones(1, T, dtype=torch.bool),
            None if positions is None else positions[None], None if until is None else until[None])
        return StepOutputs(action_logits[0, -1], pointer_logits[0, -1], inputs.frame_size, emb[0], grid, None,
                           len(lang), None, frame, encoded)

    @staticmethod
    def pitch_now(state: StepState) -> torch.Tensor:
        """The camera's pitch at the state's step, dead reckoned from the actions taken (camera_pitches)."""
        return camera_pitches(torch.tensor(state.previous_actions))[-1]

    def step_grid(self, state: StepState, t: int) -> torch.Tensor:
        """Step t's pointer keys [C, k], made from its kept frame on first use (the same numbers as at the step)."""
        if state.grids[t] is None:
            if state.pointer_mode == 'keyless':
                state.grids[t] = self.encode_frames(state.frames[t])[1][0]
            else:
                state.grids[t] = self.visual.keys_of(self.visual.encode(state.frames[t]))[0]
        return state.grids[t]

    @torch.inference_mode()
    def step_pointer(self, outputs: StepOutputs) -> tuple[Optional[torch.Tensor], torch.Tensor]:
        """(the frame's grid [1, C, k] or None, the pointer logits [C]) of a step: made now from its decoder
        output and encoder maps if the step left them out (the lazy mode)."""
        if outputs.pointer_logits is not None:
            return outputs.grid, outputs.pointer_logits
        grid = self.visual.keys_of(outputs.encoded)
        return grid, self.pointer_head(outputs.h, grid[0])

    @staticmethod
    def advance(state: StepState, outputs: StepOutputs, action: int, grid: Optional[torch.Tensor]) -> None:
        """Past the step whose `outputs` chose `action` (`grid`: the frame's keys, if made): what later steps
        read of it is kept in `state` (its frame only while its keys are not made)."""
        state.embeddings.append(outputs.embedding)
        state.grids.append(None if grid is None else grid[0])
        state.frames.append(outputs.frame if grid is None else None)
        state.previous_actions.append(action)
        state.cache = outputs.cache          # None after a step that read the whole episode: so do the later ones
        if outputs.cache is not None:
            state.lang_cached = outputs.n_lang
        state.step += 1

    def forward(self, batch: dict) -> dict:
        """A padded batch of episodes (keys of `data.collate`) -> {'action_logits' [B, T, 13],
        'pointer_logits' [K, C]: at the K steps with a target (batch['target_cells'] >= 0), in order}.
        Over a perception network, batch['perceived'] (its output for the B x T frames, flat: from
        blocks.BlockFeatures) stands for batch['frames']."""
        B, T = batch['actions'].shape
        has_target = batch['target_cells'] >= 0
        if isinstance(self.visual, PerceivedFrames):       # keys (no distances) only for the frames that need them
            if 'perceived' in batch:
                emb, keys, out = self.visual.read(batch['perceived'], keys_for=has_target.reshape(-1))
            else:
                emb, keys, out = self.visual.perceive(batch['frames'].flatten(0, 1), keys_for=has_target.reshape(-1))
        else:
            flat = batch['frames'].flatten(0, 1)
            emb, grid = self.visual(flat)
            keys = grid.view(B, T, grid.shape[1], -1)[has_target]
        stream = self.config.stream_answers
        h = self.hidden(batch['lang_ids'], batch['lang_types'], batch['lang_steps'], batch['lang_valid'],
                        emb.view(B, T, -1), batch['previous_actions'], batch['step_valid'],
                        batch['lang_positions'] if stream else None, batch['lang_until'] if stream else None)
        if not self.config.reach_input:
            return {'action_logits': self.action_head(h), 'pointer_logits': self.pointer_head(h[has_target], keys)}
        with torch.no_grad():                              # where the pointer would point at every step
            queries = self.pointer_head.query(h).reshape(B * T, -1)
            pointer_all = self.visual.pointer_logits(out, queries).view(B, T, -1) * self.pointer_head.scale
            distances = self.visual.distances(out).view(B, T, -1)
        return {'action_logits': self._actions(h, pointer_all, distances, camera_pitches(batch['previous_actions'])),
                'pointer_logits': self.pointer_head(h[has_target], keys)}


def pointer_ce(logits: torch.Tensor, targets: torch.Tensor, reduction: str = 'mean') -> torch.Tensor:
    """Cross-entropy of pointer logits [K, C] against target masks [K, C] (bool): -log of the
    probability the pointer gives to all of the target's cells together (every cell of the target is
    a right answer; a mask of one cell is the usual cross-entropy)."""
    ce = torch.logsumexp(logits, -1) - torch.logsumexp(logits.masked_fill(~targets, float('-inf')), -1)
    return ce.mean() if reduction == 'mean' else ce.sum()


def performer_loss(outputs: dict, batch: dict, pointer_weight: float = 1.0) -> tuple[torch.Tensor, dict]:
    """Cross-entropy of the expert's actions over the steps whose action is a target (batch['action_valid'])
    + `pointer_weight` x the pointer's cross-entropy against the target's cells (batch['target_masks']
    [K, C]) over the interaction steps. Returns (loss, {'action', 'pointer'})."""
    valid = batch['action_valid']
    action = F.cross_entropy(outputs['action_logits'][valid], batch['actions'][valid])
    if len(batch['target_masks']):
        pointer = pointer_ce(outputs['pointer_logits'], batch['target_masks'])
    else:
        pointer = outputs['pointer_logits'].sum() * 0.0
    loss = action + pointer_weight * pointer
    return loss, {'action': float(action.detach()), 'pointer': float(pointer.detach())}


# ---------------------------------------------------------------------- checkpoints

class CheckpointError(ValueError):
    """A checkpoint that cannot be loaded, with what does not match."""


def save_checkpoint(path: Path, model: Performer, vocab: Vocabulary, command: Optional[str] = None,
                    extra: Optional[dict] = None, commit: Optional[str] = None) -> None:
    """Write everything needed to rebuild `model`: config, vocabulary, weights, the git commit (default:
    the repository's now; training passes the one it started at) and the command that made it
    (default: this process's command line)."""
    if len(vocab) != model.vocab_size:
        raise ValueError(f'the vocabulary has {len(vocab)} words, the model {model.vocab_size}')
    state = {'format': CHECKPOINT_FORMAT, 'config': dataclasses.asdict(model.config), 'vocab': vocab.to_json(),
             'state_dict': model.state_dict(), 'git_commit': commit or git_commit(),
             'command': command if command is not None else ' '.join(sys.argv), 'extra': extra or {}}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + '.tmp')
    torch.save(state, tmp)
    tmp.replace(path)


REQUIRED_KEYS = ('format', 'config', 'vocab', 'state_dict', 'git_commit', 'command')


def state_digest(state: dict) -> str:
    """sha256 over a state dict's tensors (name, dtype, shape and bytes, in name order): the same
    weights give the same digest whatever file, command or commit they were saved with."""
    h = hashlib.sha256()
    for name in sorted(state):
        t = state[name].detach().contiguous().reshape(-1)
        h.update(f'{name}\0{t.dtype}\0{tuple(state[name].shape)}\0'.encode())
        h.update(t.view(torch.uint8).numpy().tobytes())
    return h.hexdigest()


def visual_state(path: Path) -> dict:
    """The frame encoder's weights (state dict without the 'visual.' prefix) of the performer checkpoint
    at `path`."""
    state = read_state(path).get('state_dict')
    if not isinstance(state, dict):
        raise CheckpointError(f'{path}: no state_dict')
    return {k[len('visual.'):]: v for k, v in state.items() if k.startswith('visual.')}


def read_state(path: Path) -> dict:
    """The dict a training run saved with torch.save, loaded with weights_only=True: tensors and plain
    values only, so a crafted file's pickled code never runs. FileNotFoundError if there is none;
    CheckpointError saying why for a damaged, foreign or crafted file."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f'no checkpoint at {path}')
    try:
        state = torch.load(path, map_location='cpu', weights_only=True)
    except Exception as exc:  # noqa: BLE001 - torch raises many kinds for a damaged or crafted file
        raise CheckpointError(f'{path} is not a readable checkpoint ({type(exc).__name__}: {str(exc)[:300]})') from None
    if not isinstance(state, dict):
        raise CheckpointError(f'{path}: expected a dict, found {type(state).__name__}')
    return state


def load_checkpoint(path: Path, state: Optional[dict] = None) -> tuple[Performer, Vocabulary, dict]:
    """(model in eval mode, vocabulary, {'git_commit', 'command', 'extra', 'config'}) from a checkpoint
    of `save_checkpoint` (`state`: its `read_state(path)`, when the caller has read it already).
    FileNotFoundError if there is none; CheckpointError saying what is wrong if it is not readable,
    lacks a part, or its weights do not fit its config and vocabulary."""
    path = Path(path)
    if state is None:
        if not path.is_file():
            raise FileNotFoundError(f'no performer checkpoint at {path}')
        state = read_state(path)
    missing = [k for k in REQUIRED_KEYS if k not in state]
    if missing:
        raise CheckpointError(f'{path}: missing {missing} (a performer checkpoint has {list(REQUIRED_KEYS)})')
    if state['format'] != CHECKPOINT_FORMAT:
        raise CheckpointError(f'{path}: format {state["format"]!r}, this code reads {CHECKPOINT_FORMAT!r}')
    fields = {f.name for f in dataclasses.fields(PerformerConfig)}
    unknown = sorted(set(state['config']) - fields)
    if unknown:
        raise CheckpointError(f'{path}: config fields {unknown} are not in PerformerConfig')
    config = PerformerConfig(**state['config'])
    try:
        vocab = Vocabulary.from_json(state['vocab'])
    except (ValueError, TypeError) as exc:
        raise CheckpointError(f'{path}: bad vocabulary ({exc})') from exc
    model = Performer(config, len(vocab))
    expected, found = model.state_dict(), state['state_dict']
    problems = []
    if sorted(set(expected) - set(found)):
        problems.append(f'missing weights {sorted(set(expected) - set(found))[:8]}')
    if sorted(set(found) - set(expected)):
        problems.append(f'unexpected weights {sorted(set(found) - set(expected))[:8]}')
    shapes = [f'{k}: {tuple(found[k].shape)} != {tuple(v.shape)}' for k, v in expected.items()
              if k in found and tuple(found[k].shape) != tuple(v.shape)]
    if shapes:
        problems.append(f'shape mismatch (checkpoint != config) {shapes[:8]}')
    types = found.get('language.token_type.weight')
    if types is not None and types.shape[0] != n_token_types():
        problems.append(f'it was trained for {types.shape[0] - 2} question types and {n_token_types() - 2} are '
                        'registered now (protocol.question_types()): retrain it for a type added since')
    if problems:
        raise CheckpointError(f'{path}: weights do not fit config {config} with {len(vocab)} words: '
                              + '; '.join(problems))
    model.load_state_dict(found)
    model.eval()
    return model, vocab, {'git_commit': state['git_commit'], 'command': state['command'],
                          'extra': state.get('extra', {}), 'config': config}
