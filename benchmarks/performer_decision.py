"""Decision time of PerformerAgent (untrained, default PerformerConfig) on one CPU thread: ms per
step at steps 1, 20 and 60 of an episode with a 3-QA dialogue, on random 128x128 frames resized to
the model's resolution. Prints JSON.

    ./dialfred bench performer_decision
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from dialfred_performer.agent import PerformerAgent
from dialfred_performer.model import Performer, PerformerConfig
from dialfred_performer.preprocess import Vocabulary
from dialfred_sim.agents import QA, Question
from dialfred_sim.tasks import PublicTask

def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeats', type=int, default=5, help='episodes of 60 steps')
    REPEATS = ap.parse_args().repeats
    torch.set_num_threads(1)
    torch.manual_seed(0)
    config = PerformerConfig()
    instruction = 'Put the apple in the fridge.'
    answers = ['The apple is to your left in the fridge.', 'The apple is red and made of food.',
               'You should turn left.']
    vocab = Vocabulary.build([instruction, *answers])
    agent = PerformerAgent(Performer(config, len(vocab)), vocab)
    task = PublicTask('bench/0', 'FloorPlan1', 'bench', instruction, ('apple', 'fridge'))
    frames = np.random.default_rng(0).integers(0, 256, (REPEATS, 61, 128, 128, 3), dtype=np.uint8)
    times = {1: [], 20: [], 60: []}
    for r in range(REPEATS):
        agent.reset(task, seed=r)
        for qtype, noun, text in zip(('location', 'appearance', 'direction'), ('apple', 'apple', ''), answers):
            agent.hear(QA(Question(qtype, noun), True, text))
        for step in range(1, 61):
            t0 = time.perf_counter()
            agent.act(frames[r, step])
            dt = (time.perf_counter() - t0) * 1000
            if step in times:
                times[step].append(dt)
    print(json.dumps({'config': {'resolution': config.resolution, 'd_model': config.d_model,
                                 'layers': config.layers}, 'threads': torch.get_num_threads(),
                      'ms_per_step_median': {f'step_{k}': round(float(np.median(v)), 2) for k, v in times.items()},
                      'ms_per_step_max': {f'step_{k}': round(float(np.max(v)), 2) for k, v in times.items()},
                      'repeats': REPEATS}))


if __name__ == '__main__':
    main()
