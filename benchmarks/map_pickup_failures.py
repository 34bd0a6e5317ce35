"""Why the map performer fails to pick things up: replays the failed episodes of a results file whose
tasks pick something up, and for every frame of a pickup step compares what the simulator shows (the
target's true mask, privileged, read here only to measure) with what the perception network labels.
Each episode falls in one class:

- never_near: the target never showed (>= 4 pixels at the camera's resolution) within 1.5 m;
- near_never_labelled: it showed within 1.5 m, and no cell was ever labelled with its type;
- labelled: some frame labelled it (then the failure lies in reaching or acting on it).

It also reports the network's probability of the target's type under the target's mask in the frames
where the target showed with at least 16 pixels within 1.5 m (its median, and how often it was the
most probable type there). Prints JSON.

    ./dialfred bench map_pickup_failures RESULTS.jsonl [--checkpoint PATH] [--questioner all|none] \
        [--limit 40] [--resolution 128]
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter
from pathlib import Path

import numpy as np
import torch

from dialfred_oracle.in_process import EnvServer
from dialfred_performer.mapper.agent import MapAgent
from dialfred_performer.model import SHIPPED_CHECKPOINT
from dialfred_performer.preprocess import frame_tensor
from dialfred_questioner.baselines import with_questioner
from dialfred_questioner.questioners import make_questioner
from dialfred_sim.env import DialfredEnv
from dialfred_sim.episode import play, run
from dialfred_sim.metrics import load_results
from dialfred_sim.protocol import episode_seed
from dialfred_sim.tasks.split_files import load_split

NEAR_M = 1.5


def measure(results: Path, checkpoint: Path, questioner: str, limit: int, resolution: int) -> dict:
    rows = load_results(results)
    if not rows:
        raise SystemExit(f'{results}: no results')
    split, seed = rows[0].split, rows[0].seed
    failed = {r.task_id for r in rows if not r.success and 'Pick' in r.task_type}
    agent = MapAgent.from_checkpoint(checkpoint)
    env = DialfredEnv(resolution=resolution)
    perceive = agent._update
    frame: dict = {}

    def watch(observation):
        perceive(observation)
        step = agent._current()
        if step.kind != 'pickup' or step.target not in agent.class_id:
            return
        k = agent.class_id[step.target]
        seg, depth = observation.segmentation, observation.depth
        ids, names = env.world.instance_table()
        true = np.isin(seg, [b for b, name in zip(ids, names) if name.rsplit('_', 1)[0] == step.target])
        pixels = int(true.sum())
        near = pixels >= 4 and float(np.median(depth[true])) < NEAR_M
        labelled = bool(((agent.labels == k) & (agent.conf > 0.3)).any())
        frame['near'] = frame.get('near', False) or near
        frame['labelled'] = frame.get('labelled', False) or labelled
        if near and pixels >= 16:
            s = agent.labels.shape[0]
            cells = true.reshape(s, resolution // s, s, resolution // s).mean(axis=(1, 3)) >= 0.5
            if cells.any():
                with torch.inference_mode():
                    out = agent.net(frame_tensor(observation.rgb, agent.resolution)[None])
                    prob = torch.softmax(agent.net.heads(out.fine)[0][0], 0).numpy()
                frame.setdefault('probability', []).append(float(prob[k][cells].max()))
                frame.setdefault('top', []).append(bool((prob[:, cells].argmax(0) == k).any()))

    agent._update = watch
    classes, probability, top, episodes = Counter(), [], [], []
    t0 = time.monotonic()
    for index, task in enumerate(load_split(split)):
        if task.task_id not in failed:
            continue
        frame.clear()
        policy = with_questioner(agent, make_questioner(questioner)) if questioner != 'none' else agent
        state = run(play(policy, seed=episode_seed(seed, index), asks=questioner != 'none'), EnvServer(env, task))
        kind = 'labelled' if frame.get('labelled') else 'near_never_labelled' if frame.get('near') else 'never_near'
        classes[kind] += 1
        probability += frame.get('probability', [])
        top += frame.get('top', [])
        episodes.append({'task_id': task.task_id, 'class': kind, 'success': state.success})
        if len(episodes) >= limit:
            break
    return {'results': str(results), 'checkpoint': str(checkpoint), 'questioner': questioner,
            'resolution': resolution, 'episodes': len(episodes),
            'replayed_successes': sum(e['success'] for e in episodes),
            'classes': dict(classes),
            'frames_target_near_16px': len(probability),
            'target_probability_median': round(float(np.median(probability)), 4) if probability else None,
            'target_most_probable_share': round(float(np.mean(top)), 3) if top else None,
            'seconds': round(time.monotonic() - t0, 1), 'by_episode': episodes}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('results', type=Path, help='a results file of the map performer (launch eval --agent map)')
    ap.add_argument('--checkpoint', type=Path, default=Path(SHIPPED_CHECKPOINT))
    ap.add_argument('--questioner', default='all', help="the results' questioner: all or none")
    ap.add_argument('--limit', type=int, default=40, help='failed episodes replayed')
    ap.add_argument('--resolution', type=int, default=128, help="the results' camera pixels")
    args = ap.parse_args()
    print(json.dumps(measure(args.results, args.checkpoint, args.questioner, args.limit, args.resolution), indent=1))


if __name__ == '__main__':
    main()
