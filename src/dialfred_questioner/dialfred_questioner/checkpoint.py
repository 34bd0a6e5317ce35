"""The learned questioner's checkpoints: writing one (`save`, read by `policy.LearnedQuestioner`), and
going on from a training run's last.pt (`resume_training`), for pre-training and RL fine-tuning alike."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Optional

import torch

from dialfred_sim.dataclass_cli import command_line, config_changes
from dialfred_performer.model import read_state
from dialfred_performer.preprocess import Vocabulary

from .model import Questioner

FORMAT = 'dialfred-questioner/1'


def resume_training(out: Path, cfg, resumable: tuple, model: torch.nn.Module, opt: torch.optim.Optimizer,
                    counter: str) -> tuple[dict, list[str]]:
    """Go on from `out`/last.pt: ValueError if its config differs from `cfg` in more than the `resumable`
    fields; load the model's and optimiser's state; cut metrics.jsonl back to its lines whose `counter`
    (epoch or update) is at most the saved one. (The saved `extra`, the log lines kept.)"""
    state = read_state(out / 'last.pt')
    extra = state['extra']
    differ = sorted(config_changes(json.loads(extra['config']), cfg, resumable))
    if differ:
        raise ValueError(f'--resume: the config differs from the run in {out} in {differ}')
    model.load_state_dict(state['state_dict'])
    opt.load_state_dict(extra['optimizer'])
    log_path = out / 'metrics.jsonl'
    lines = [line for line in log_path.read_text().splitlines() if json.loads(line)[counter] <= extra[counter]] \
        if log_path.exists() else []
    log_path.write_text(''.join(line + '\n' for line in lines))
    return extra, lines


def save(path: Path, model: Questioner, vocab: Vocabulary, visual_state: dict, performer_info: dict, cfg,
         commit: str, extra: Optional[dict] = None, timing: Optional[dict] = None, module: str = 'dialfred_questioner.pretrain',
         reads_dialogue: bool = True) -> None:
    """Everything the questioner needs to run: its config, nouns, the vocabulary, its weights and the
    frozen visual encoder's, which performer they came from, when it asks (`timing`, a rollout.Timing
    as a dict; none: at the start only), whether it reads the dialogue so far (False: the original's
    instruction-only input, an ablation), the command (of `module`) and commit."""
    state = {'format': FORMAT, 'config': dataclasses.asdict(model.config), 'nouns': list(model.nouns),
             'vocab': vocab.to_json(), 'state_dict': model.state_dict(), 'visual': visual_state,
             'visual_resolution': performer_info['config'].resolution,
             'visual_config': dataclasses.asdict(performer_info['config']), 'performer': performer_info['path'],
             'performer_model': performer_info.get('model', 'et'),
             'timing': timing, 'reads_dialogue': reads_dialogue, 'git_commit': commit, 'command': command_line(module, cfg), 'extra': extra or {}}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + '.tmp')
    torch.save(state, tmp)
    tmp.replace(path)
