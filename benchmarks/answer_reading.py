#!/usr/bin/env python3
"""How well the map performer's reader (dialfred_performer/mapper/words.py) reads answers in other words:
the oracle's answers at the start of each task (every question All QAs asks), said by each wording source,
read back into the oracle's fields and compared with the fields of the oracle's own answer. Prints JSON,
per source and per question type: recall (fields read right, of the fields the oracle's answer has) and
precision (fields read right, of the fields the reader claimed).

Fields: location: the direction bin, the receptacle, in or on it, held; appearance: the colour; direction:
the turn (left, right, around, straight or stay). Sources: `templates` (the oracle's words), `annotator`
(the synthetic annotator's paraphrases, dialfred_oracle.annotator.paraphrase: the wording the questioner's
data uses) and `held-out` (dialfred_oracle.wording.HeldOutWording, written apart from both; it leaves a
detail out of about a quarter of its location answers: `recall` counts those fields, `recall_said` only the
fields the words say, `HeldOutWording.spoken`'s).

    ./dialfred bench answer_reading [--split valid_unseen] [--limit N]
"""

from __future__ import annotations

import argparse
import json
import zlib

import numpy as np

from dialfred_oracle.annotator import answer_content, paraphrase
from dialfred_oracle.answerers import Asked
from dialfred_oracle.in_process import answer_now
from dialfred_oracle.wording import HeldOutWording
from dialfred_performer.mapper.language import parse_answer
from dialfred_performer.mapper.words import read_answer
from dialfred_sim.agents import task_nouns
from dialfred_sim.env import DialfredEnv
from dialfred_sim.progress import progress_bar
from dialfred_sim.tasks import load_split


def fields(fact) -> dict:
    if fact is None:
        return {}
    if fact.kind == 'direction':
        return {'turn': 'stay' if fact.stay else fact.turn_deg}
    if fact.kind == 'appearance':
        return {'colour': fact.colour} if fact.colour else {}
    if fact.kind == 'held':
        return {'held': True, **({'receptacle': fact.receptacle} if fact.receptacle else {})}
    out = {'held': False}
    if fact.bearing_deg is not None:
        out['bin'] = int(round(fact.bearing_deg / 45.0)) % 8
    if fact.receptacle:
        out['receptacle'], out['inside'] = fact.receptacle, bool(fact.inside)
    return out


COUNTS = ('answers', 'truth', 'read', 'right', 'truth_said', 'right_said')
# A field the words leave unsaid, by the name HeldOutWording.spoken gives it ('receptacle': with in or on).
UNSAID_FIELDS = {'inside': 'receptacle'}


def rates(c: dict) -> dict:
    return {**c, 'recall': round(c['right'] / c['truth'], 4),
            'recall_said': round(c['right_said'] / c['truth_said'], 4) if c['truth_said'] else None,
            'precision': round(c['right'] / c['read'], 4) if c['read'] else None}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--split', default='valid_unseen')
    ap.add_argument('--limit', type=int, default=None)
    args = ap.parse_args()
    tasks = load_split(args.split)[:args.limit]
    held_out = HeldOutWording()
    sources = ('templates', 'annotator', 'held-out')
    counts = {s: {} for s in sources}
    examples = {s: [] for s in sources}
    env = DialfredEnv(resolution=64)
    try:
        with progress_bar(total=len(tasks), unit='task') as bar:
            for task in tasks:
                env.reset(options={'task': task})
                for qtype, noun in [(q, n) for n in task_nouns(task) for q in ('location', 'appearance')] + \
                        [('direction', '')]:
                    oracle = answer_now(env, qtype, noun)
                    if not oracle.valid:
                        continue
                    truth = fields(parse_answer(qtype, oracle.text))
                    if not truth:
                        continue
                    content = answer_content(oracle, qtype, noun)
                    rng = np.random.default_rng(zlib.crc32(f'{task.task_id}|{qtype}|{noun}'.encode()))
                    spoken = held_out.spoken(Asked(task.task_id, qtype, noun, ''), content)
                    said = {'templates': (oracle.text, frozenset()), 'annotator': (paraphrase(content, rng), frozenset()),
                            'held-out': tuple(spoken) if spoken else (oracle.text, frozenset())}
                    for source, (words, unsaid) in said.items():
                        got = fields(read_answer(qtype, words, noun))
                        c = counts[source].setdefault(qtype, dict.fromkeys(COUNTS, 0))
                        c['answers'] += 1
                        c['truth'] += len(truth)
                        c['read'] += len(got)
                        right = sum(got.get(k) == v for k, v in truth.items())
                        c['right'] += right
                        told = [k for k in truth if UNSAID_FIELDS.get(k, k) not in unsaid]
                        c['truth_said'] += len(told)
                        c['right_said'] += sum(got.get(k) == truth[k] for k in told)
                        if right < len(truth) and len(examples[source]) < 12:
                            examples[source].append({'task': task.task_id, 'oracle': oracle.text, 'said': words,
                                                     'read': got, 'truth': truth})
                bar.update(1)
    finally:
        env.close()
    report = {'split': args.split, 'tasks': len(tasks), 'sources': {}}
    for source in sources:
        row, total = {}, dict.fromkeys(COUNTS, 0)
        for qtype, c in counts[source].items():
            row[qtype] = rates(c)
            for k in total:
                total[k] += c[k]
        row['all'] = rates(total)
        report['sources'][source] = {'types': row, 'misread_examples': examples[source]}
    print(json.dumps(report, indent=1))


if __name__ == '__main__':
    main()
