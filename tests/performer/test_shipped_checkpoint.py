"""The performer checkpoint shipped in the package (dialfred_performer/checkpoints/et.pt).

Claims: it exists where every default points (the node's parameter, `launch eval --agent/--performer
et`), is at most 25 MB, loads with the model's own loader, records the command that reproduces it
(a `train-performer` run) and the commit it was trained at, and plays a valid_unseen task in the
real simulator with the instruction and a QA (greedy, so the same episode twice); it sees through the
perception network, and it is the performer docs/results.md was made with.
"""

from __future__ import annotations

from pathlib import Path

import torch

from dialfred_performer.agent import PerformerAgent
from dialfred_performer.model import SHIPPED_CHECKPOINT, load_checkpoint
from dialfred_sim.protocol import QA, Question, env_observation
from dialfred_sim.env import DialfredEnv


from dialfred_bringup.evaluation import EvalConfig, EvalRun

REPO = Path(__file__).resolve().parents[2]
MAX_BYTES = 25 * 1024 * 1024


def test_the_shipped_checkpoint_is_small_loads_and_says_how_it_was_made():
    assert SHIPPED_CHECKPOINT.is_file(), f'no shipped checkpoint at {SHIPPED_CHECKPOINT}'
    assert SHIPPED_CHECKPOINT.stat().st_size <= MAX_BYTES
    model, vocab, info = load_checkpoint(SHIPPED_CHECKPOINT)
    assert 'train-performer' in info['command'] or 'dialfred_performer.train' in info['command']
    assert info['git_commit'] != 'unknown'
    assert model.vocab_size == len(vocab)
    assert EvalRun(EvalConfig(agent='et')).checkpoint_path == SHIPPED_CHECKPOINT


def play(agent: PerformerAgent, task_id: str, steps: int = 12) -> list:
    env = DialfredEnv(resolution=agent.config.resolution)
    obs = env_observation(*env.reset(options={'task_id': task_id}))
    task = env.task.public()
    agent.reset(task, seed=0)
    agent.hear(QA(Question('location', task.object_nouns[0] if task.object_nouns else ''), True,
                  'It is to your left.'))
    actions = []
    for _ in range(steps):
        decision = agent.act(obs)
        actions.append(decision)
        raw, _, terminated, truncated, info = env.step({'action': decision[0], 'pixel': decision[1:]})
        obs = env_observation(raw, info)
        if terminated or truncated:
            break
    env.close()
    return actions


def test_the_shipped_checkpoint_plays_a_valid_unseen_task_the_same_way_twice():
    torch.set_num_threads(1)
    agent = PerformerAgent.from_checkpoint(SHIPPED_CHECKPOINT)
    first = play(agent, 'valid_unseen/000003')
    assert first and first == play(agent, 'valid_unseen/000003')


def test_the_shipped_performer_sees_through_the_perception_network():
    model, _, info = load_checkpoint(SHIPPED_CHECKPOINT)
    assert info['config'].visual == 'perception' and model.config.grid_size == model.config.resolution
    assert not any(p.requires_grad for p in model.visual.net.parameters())


def test_the_shipped_performer_is_the_one_the_results_document_was_made_with():
    """docs/results.md names its performer's weights digest; the shipped et.pt has those weights
    (`python -m dialfred_bringup.reproduce.ship` copied it out of that run)."""
    import re
    from dialfred_bringup.reproduce.plan import weights_sha256
    text = (REPO / 'docs' / 'results.md').read_text()
    named = re.search(r'- performer: .*?weights sha256 `([0-9a-f]{16})`', text)
    assert named, 'docs/results.md names no performer digest'
    assert weights_sha256(SHIPPED_CHECKPOINT).startswith(named.group(1))
