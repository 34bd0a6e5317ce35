#!/usr/bin/env python3
"""Answer correctness of `/oracle/answer` against the simulator's ground truth, over valid_unseen.

For `--questions` questions on tasks drawn (seeded) from valid_unseen, the simulator is reset to
the task and, half of the time, the expert's first actions are played so the agent stands
elsewhere; then one question (location, appearance or direction, in turn) about one of the task's
objects goes through the oracle node, and the ground truth of the same moment comes straight from
`/sim/ground_truth`. Checks: a location answer names the object's parent receptacle (or says it is
held) and the 45-degree direction bin recomputed from the geometry (to the visible part's middle
for an object in view, else to its centre); an appearance answer names the object's assigned colour
variant and material; a direction answer matches the expert end pose.

The visible part, checked independently: for a location question about an object in view, the bin
holding most of its pixels is recomputed here from the frame's depth and segmentation and the
camera model (90 deg field of view, pitch = -horizon), and compared with the answer's bin and with
the bin of its centre (what the oracle used before), for all such objects and for large ones
(catalog footprint >= 1 m: bed, counter, sofa, armchair, tables, ...). The answer's bin is that of the
visible pixel with the median bearing, so it is the bin holding most pixels whenever one bin holds more
than half of them (checked apart); an object spread over three bins with none holding half (a counter
across the view) can get the middle bin where another holds a few more pixels.
Prints JSON with the agreement rates and the colour confusions.

    ./dialfred bench oracle_correctness [--questions 1000] [--seed 0]
"""

from __future__ import annotations

import argparse
import collections
import json
import math
import time

import numpy as np

from dialfred_bringup.graph import Graph, oracle_node, sim_node, use_private_ros_domain
from dialfred_msgs.msg import Action
from dialfred_msgs.srv import GroundTruth, OracleAnswer, SimReset, SimStep
from dialfred_oracle.answers import direction_bin
from dialfred_sim.catalog import load_catalog
from dialfred_sim.palette import COLOUR_NAMES as COLOURS
from dialfred_sim.tasks import load_split

TYPES = ('location', 'appearance', 'direction')
BINS = ('in front of you', 'to your front right', 'to your right', 'to your rear right', 'behind you',
        'to your rear left', 'to your left', 'to your front left')


def expected_direction(agent, end) -> str:
    """The direction answer the geometry calls for (the oracle's rule, recomputed independently)."""
    dx, dy = end[0] - agent[0], end[1] - agent[1]
    if math.hypot(dx, dy) < 0.125:            # the same grid point
        turn = (end[2] - agent[2] + 180) % 360 - 180
        if abs(turn) < 45:
            return "You don't need to move."
        return 'You should turn left.' if 45 <= turn < 135 else \
            'You should turn right.' if -135 < turn <= -45 else 'You should turn around.'
    b = direction_bin(agent[:2], agent[2], end[:2])
    return {'in front of you': 'You should go straight ahead.', 'to your front right': 'You should go straight ahead.',
            'to your front left': 'You should go straight ahead.', 'to your right': 'You should turn right.',
            'to your left': 'You should turn left.', 'to your rear right': 'You should turn around.',
            'to your rear left': 'You should turn around.', 'behind you': 'You should turn around.'}[b]


LARGE_M = 1.0


def large_types() -> set[str]:
    return {n for n, t in load_catalog().items() if t.dims and max(t.dims[:2]) >= LARGE_M}


def pixel_bins(observation, body: int) -> list[str]:
    """The direction bin of every pixel of `body` in `observation`, from its depth (metres along
    the view axis) and the camera's pose: an implementation of its own of the camera model."""
    img = observation.segmentation
    seg = np.frombuffer(bytes(img.data), np.int32).reshape(img.height, img.width)
    depth = np.frombuffer(bytes(observation.depth.data), np.float32).reshape(img.height, img.width)
    pose = observation.pose
    ys, xs = np.nonzero(seg == body)
    yaw, pitch = math.radians(pose.rotation_deg), math.radians(-pose.horizon_deg)
    fwd = np.array([math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), math.sin(pitch)])
    right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
    up = np.cross(right, fwd)
    h, w = seg.shape
    u = ((xs + 0.5) / w * 2 - 1) * math.tan(math.radians(45.0))
    v = (1 - (ys + 0.5) / h * 2) * math.tan(math.radians(45.0))
    rays = fwd[None] + u[:, None] * right[None] + v[:, None] * up[None]
    points = np.array([pose.x, pose.y, pose.camera_height])[None] + depth[ys, xs][:, None] * rays
    return [direction_bin((pose.x, pose.y), pose.rotation_deg, p[:2]) for p in points]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--questions', type=int, default=1000)
    ap.add_argument('--seed', type=int, default=0)
    args = ap.parse_args()
    use_private_ros_domain()
    rng = np.random.default_rng(args.seed)
    tasks = load_split('valid_unseen')
    large = large_types()
    checks = collections.defaultdict(list)
    confusions = collections.Counter()
    disagreements = []     # location answers whose bin is not where most of the object's pixels are
    examples = []
    t0 = time.perf_counter()
    with Graph([sim_node(128), oracle_node()]) as graph:
        reset = graph.client(SimReset, '/sim/reset')
        step = graph.client(SimStep, '/sim/step')
        truth_cli = graph.client(GroundTruth, '/sim/ground_truth')
        ask = graph.client(OracleAnswer, '/oracle/answer')
        for q in range(args.questions):
            task = tasks[int(rng.integers(len(tasks)))]
            r = graph.call(reset, SimReset.Request(task_id=task.task_id))
            assert r.ok
            observation = r.observation
            if rng.random() < 0.5:
                for a in task.expert_actions[:int(rng.integers(len(task.expert_actions)))]:
                    r = graph.call(step, SimStep.Request(action=Action(action=a.action, x=a.x, y=a.y)))
                    observation = r.observation
                    if r.terminated:
                        break
            qtype = TYPES[q % 3]
            truth = graph.call(truth_cli, GroundTruth.Request())
            task_objects = dict(zip(truth.task_nouns, truth.task_object_ids))
            facts = {f.object_id: f for f in truth.objects}
            nouns = [n for n, oid in task_objects.items() if oid in facts]
            if not nouns:
                continue
            noun = nouns[int(rng.integers(len(nouns)))]
            reply = graph.call(ask, OracleAnswer.Request(question_type=qtype, object_noun=noun))
            checks[f'{qtype}_valid'].append(reply.valid)
            if not reply.valid:
                examples.append({'q': (qtype, noun), 'invalid': reply.reason})
                continue
            fact = facts[task_objects[noun]]
            agent = (truth.agent.x, truth.agent.y, truth.agent.rotation_deg)
            text = reply.answer
            if qtype == 'location':
                if fact.held:
                    checks['location_receptacle'].append('holding' in text)
                else:
                    if fact.parent_noun:
                        checks['location_receptacle'].append(f'{fact.preposition} the {fact.parent_noun}' in text)
                    where = (fact.seen_x, fact.seen_y) if fact.in_view else (fact.x, fact.y)
                    said = direction_bin(agent[:2], agent[2], where)
                    checks['location_direction_bin'].append(said in text)
                    if fact.in_view:
                        body = dict(zip(observation.instance_object_ids, observation.instance_ids))[fact.object_id]
                        bins = pixel_bins(observation, body)
                        most = max(sorted(set(bins)), key=bins.count)
                        centre = direction_bin(agent[:2], agent[2], (fact.x, fact.y))
                        for group in ('in_view', 'large_in_view') if fact.type_name in large else ('in_view',):
                            checks[f'location_{group}_answer_is_where_most_pixels_are'].append(f' {most}' in text)
                            checks[f'location_{group}_centre_is_where_most_pixels_are'].append(centre == most)
                        majority = bins.count(most) * 2 > len(bins)
                        if majority:       # the answer's median pixel lies in a bin holding over half of them
                            checks['location_in_view_answer_is_the_majority_bin_when_one_holds_over_half'].append(
                                f' {most}' in text)
                        if f' {most}' not in text:
                            disagreements.append({'task': task.task_id, 'answer': text, 'majority_bin': majority,
                                                  'pixels_per_bin': dict(collections.Counter(bins).most_common())})
            elif qtype == 'appearance':
                named = next((c for c in text.replace('.', ' ').split() if c in COLOURS), '')
                ok = named == fact.colour
                checks['appearance_colour'].append(ok)
                checks['appearance_material'].append(fact.material in text)
                if not ok:
                    confusions[f'{fact.colour}->{named or "?"}'] += 1
            else:
                e = truth.answer_key.expert_end_pose
                checks['direction'].append(text == expected_direction(agent, (e.x, e.y, e.rotation_deg)))
            if len(examples) < 12:
                examples.append({'task': task.task_id, 'q': (qtype, noun), 'a': text})
    report = {'benchmark': 'oracle_correctness', 'questions': args.questions, 'seed': args.seed,
              'wall_s': round(time.perf_counter() - t0, 1)}
    for name, vals in sorted(checks.items()):
        report[name] = {'n': len(vals), 'agree': int(sum(vals)),
                        'rate': round(float(np.mean(vals)), 4) if vals else None}
    report['colour_confusions'] = dict(confusions.most_common(15))
    report['visible_part_disagreements'] = disagreements[:10]
    report['examples'] = examples[:12]
    print(json.dumps(report, indent=2))


if __name__ == '__main__':
    main()
