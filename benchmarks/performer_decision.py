"""Decision time of PerformerAgent (default PerformerConfig; the shipped checkpoint's weights when
it is there, else untrained: the time does not depend on the weights) on one CPU thread: ms per step
at steps 1, 20, 60 and 200 of an episode with a 3-QA dialogue, on random 128x128 frames resized to the
model's resolution. The incremental agent (the default: a step computes its own tokens against cached
keys and values; over a perception network without the reach input it makes a frame's pointer keys
only when it interacts), the same making the keys at every step, and the baseline that reads the whole
episode again at every step, in the same run. Prints JSON (with the share of interaction decisions:
those steps make the keys in every setting).

    ./dialfred bench performer_decision [--repeats 5] [--checkpoint PATH] [--last-step 200]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from dialfred_performer.agent import PerformerAgent
from dialfred_performer.data import INTERACTIONS
from dialfred_performer.model import SHIPPED_CHECKPOINT, Performer, PerformerConfig, load_checkpoint
from dialfred_performer.preprocess import Vocabulary
from dialfred_sim.protocol import QA, Question
from dialfred_sim.tasks import PublicTask

STEPS = (1, 20, 60, 200)

def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeats', type=int, default=5, help='episodes (of --last-step steps each)')
    ap.add_argument('--checkpoint', default=str(SHIPPED_CHECKPOINT), help='the performer (default: the shipped one)')
    ap.add_argument('--last-step', type=int, default=STEPS[-1], choices=STEPS, help='episodes end at this step')
    args = ap.parse_args()
    REPEATS, checkpoint = args.repeats, Path(args.checkpoint)
    steps = tuple(s for s in STEPS if s <= args.last_step)
    torch.set_num_threads(1)
    torch.manual_seed(0)
    config = PerformerConfig()
    instruction = 'Put the apple in the fridge.'
    answers = ['The apple is to your left in the fridge.', 'The apple is red and made of food.',
               'You should turn left.']
    vocab = Vocabulary.build([instruction, *answers])
    if checkpoint.is_file():
        model, vocab, _ = load_checkpoint(checkpoint)
        config = model.config
    else:
        model = Performer(config, len(vocab))
    task = PublicTask('bench/0', 'FloorPlan1', 'bench', instruction, ('apple', 'fridge'))
    report = {'checkpoint': str(checkpoint) if checkpoint.is_file() else None,
              'config': {'resolution': config.resolution, 'd_model': config.d_model, 'layers': config.layers,
                         'visual': config.visual},
              'threads': torch.get_num_threads(), 'repeats': REPEATS}
    for name, incremental, pointer_mode in (('incremental', True, None), ('incremental_keys_every_step', True, 'keys'),
                                            ('whole_episode', False, None)):
        agent = PerformerAgent(model, vocab, incremental, pointer_mode)
        times = {s: [] for s in steps}
        interactions = 0
        rng = np.random.default_rng(0)           # the same frames for every setting
        for r in range(REPEATS):
            agent.reset(task, seed=r)
            for qtype, noun, text in zip(('location', 'appearance', 'direction'), ('apple', 'apple', ''), answers):
                agent.hear(QA(Question(qtype, noun), True, text))
            for step in range(1, steps[-1] + 1):
                frame = rng.integers(0, 256, (128, 128, 3), dtype=np.uint8)
                t0 = time.perf_counter()
                action, _, _ = agent.act(frame)
                dt = (time.perf_counter() - t0) * 1000
                interactions += action in INTERACTIONS
                if step in times:
                    times[step].append(dt)
        report[name] = {'ms_per_step_median': {f'step_{k}': round(float(np.median(v)), 2) for k, v in times.items()},
                        'ms_per_step_max': {f'step_{k}': round(float(np.max(v)), 2) for k, v in times.items()},
                        'interaction_share': round(interactions / (REPEATS * steps[-1]), 3)}
    print(json.dumps(report))


if __name__ == '__main__':
    main()
