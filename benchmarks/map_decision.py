"""Decision time of the map performer (dialfred_performer.mapper.MapAgent) on one CPU thread, in real
episodes: every act() of the first --tasks tasks of a split (every --every-th), timed around the call
(perception, map update, planning), with the instruction only. With --signal, each step also asks
for the confusion signal first (action_probabilities, then act), as the performer node does before
every step's questions: the decision is made on a copy, then adopted. Prints JSON: median, 90th
percentile and maximum ms per step, and the steps timed.

    ./dialfred bench map_decision [--checkpoint PATH] [--tasks 10] [--every 100] [--signal]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from dialfred_oracle.in_process import EnvServer
from dialfred_performer.mapper.agent import MapAgent
from dialfred_performer.model import SHIPPED_CHECKPOINT
from dialfred_sim.env import DialfredEnv
from dialfred_sim.episode import play, run
from dialfred_sim.tasks.split_files import load_split


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--checkpoint', type=Path, default=SHIPPED_CHECKPOINT)
    p.add_argument('--split', default='valid_unseen')
    p.add_argument('--tasks', type=int, default=10)
    p.add_argument('--every', type=int, default=100)
    p.add_argument('--signal', action='store_true', help='time action_probabilities and act together')
    a = p.parse_args(argv)
    if a.tasks < 1 or a.every < 1:
        p.error('--tasks and --every must be at least 1')
    torch.set_num_threads(1)
    agent = MapAgent.from_checkpoint(a.checkpoint)
    env = DialfredEnv(resolution=agent.resolution)
    times: list[float] = []
    act = agent.act

    def timed(observation):
        t0 = time.perf_counter()
        if a.signal:
            agent.action_probabilities(observation)
        decision = act(observation)
        times.append((time.perf_counter() - t0) * 1000.0)
        return decision

    agent.act = timed
    for task in load_split(a.split)[::a.every][:a.tasks]:
        run(play(agent, seed=0, asks=False), EnvServer(env, task))
    ms = np.array(times)
    print(json.dumps({'checkpoint': str(a.checkpoint), 'tasks': a.tasks, 'steps': len(ms), 'threads': 1,
                      'signal': a.signal,
                      'ms_median': round(float(np.median(ms)), 2), 'ms_p90': round(float(np.percentile(ms, 90)), 2),
                      'ms_max': round(float(ms.max()), 2)}, indent=1))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
