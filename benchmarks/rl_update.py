"""Time of one actor-critic update of the questioner (`finetune.update_step`'s forward and backward) on a
batch shaped like a Fixed-1 run's worst update: 64 episodes of short dialogues and one long episode that
asks at every step, so its last decisions read thousands of tokens. The records are synthetic (random
tokens and frame embeddings of the real sizes; the time does not depend on their values). Compares, in
the same run, one padded batch (every row padded to the longest dialogue) with `policy.score_records`
(rows grouped by length, chunks of at most TOKEN_BUDGET tokens), and checks they give the same
log-probabilities, entropies and values. Prints JSON.

    ./dialfred bench rl_update [--long 250] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import time

import torch

from dialfred_questioner.model import Questioner, QuestionerConfig, type_tokens
from dialfred_questioner.policy import TOKEN_BUDGET, Record, batch_records, score_records

VOCAB, NOUNS, INSTRUCTION, QA_TOKENS = 800, 80, 14, 12


def records(long_decisions: int, seed: int = 0) -> list[Record]:
    g = torch.Generator().manual_seed(seed)
    config = QuestionerConfig()
    out = []
    plan = [8] * 63 + [long_decisions]       # decisions per episode; each asks, so the dialogue grows
    for decisions in plan:
        for d in range(decisions):
            n = INSTRUCTION + QA_TOKENS * d
            ids = tuple(torch.randint(1, VOCAB, (n,), generator=g).tolist())
            types = tuple([0] * INSTRUCTION + [1 + (k // QA_TOKENS) % 3 for k in range(n - INSTRUCTION)])
            qtype = int(torch.randint(0, len(type_tokens()), (1,), generator=g))
            out.append(Record(ids, types, torch.randn(config.image, generator=g), d, qtype,
                              int(torch.randint(0, NOUNS, (1,), generator=g))))
    return out


def one_batch(model: Questioner, recs: list[Record]):
    b = batch_records(recs)
    enc = model.encode(b['lang_ids'], b['lang_types'], b['lang_valid'], b['image'], b['steps'])
    return model.log_prob(enc, b['types'], b['nouns']), model.entropy(enc, b['types']), model.value(enc)


def timed(fn, model, recs, repeats: int) -> tuple[float, tuple]:
    best, out = float('inf'), None
    for _ in range(repeats):
        model.zero_grad()
        t0 = time.perf_counter()
        out = fn(model, recs)
        (-(out[0].mean()) + out[2].pow(2).mean() - 0.01 * out[1].mean()).backward()
        best = min(best, time.perf_counter() - t0)
    return best, tuple(x.detach() for x in out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--long', type=int, default=250, help='decisions of the long episode')
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--threads', type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    model = Questioner(QuestionerConfig(), VOCAB, [f'noun{k}' for k in range(NOUNS)]).eval()
    recs = records(args.long)
    lengths = [len(r.lang_ids) for r in recs]
    t_new, new = timed(score_records, model, recs, args.repeats)
    t_old, old = timed(one_batch, model, recs, args.repeats)
    diff = max(float((a - b).abs().max()) for a, b in zip(old, new))
    print(json.dumps({
        'synthetic': True, 'decisions': len(recs), 'longest_tokens': max(lengths), 'tokens': sum(lengths),
        'padded_tokens_one_batch': len(recs) * max(lengths), 'token_budget': TOKEN_BUDGET,
        'threads': args.threads, 'repeats': args.repeats,
        'seconds_one_batch': round(t_old, 3), 'seconds_chunked': round(t_new, 3),
        'speedup': round(t_old / t_new, 1), 'max_abs_difference': diff}, indent=1))


if __name__ == '__main__':
    main()
