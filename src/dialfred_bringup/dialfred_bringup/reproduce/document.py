"""The results document of `./dialfred reproduce`: Tables II-IV with intervals, what holds, the SR-NQ plot."""

from __future__ import annotations

import json
import shutil
from collections import Counter
from pathlib import Path
from typing import Optional

import numpy as np

from dialfred_questioner.rl import Rewards
from dialfred_sim.metrics import has_goto, intervals, summarize, type_order
from dialfred_sim.protocol import PAPER_QUESTION_TYPES, question_text
from dialfred_sim.tasks import load_split

from ..evaluation import EvalRun, resumable_results
from ..failures import episode_failures
from ..paths import REPO
from ..report_page import environment
from .plan import (TRAINING, camera, weights_sha256, EXTRA, MAP_ROWS, SWAPPED, WORTH_ROWS, PAPER_T2, PAPER_T3, PAPER_T4, PERTURB_PROBABILITY, Plan, RESOLUTION, RETURN_ROWS, SHIPPED_QUESTIONERS, SHIPPED_RUN, SPLITS, STAGES, Setting, settings,
                   chained_settings)


# --------------------------------------------------------------------------------------------- the report

def setting_row(plan: Plan, s: Setting, resamples: int, chained: bool = False) -> dict:
    """The numbers of one setting from its results file (n = 0 when it has none); `chained`: of the chained
    stage's run of it (with the per-episode figures)."""
    folder = plan.chained_dir if chained else plan.eval_dir
    if not plan.available(s) or not (folder / f'{s.split}_{s.key}.jsonl').exists():
        return {'n': 0}
    config = plan.eval_config(s, chained=chained)
    tasks = load_split(s.split)[:config.limit]
    done = resumable_results(EvalRun(config, check=False), [t.task_id for t in tasks])
    results = [done[t.task_id] for t in tasks if t.task_id in done]
    if not results:
        return {'n': 0}
    overall = summarize(results)['overall']
    ci = intervals(results, resamples=resamples, seed=config.seed)
    counts = {t: sum(r.question_types.get(t, 0) for r in results) for t in PAPER_QUESTION_TYPES}
    recorded = sum(len(r.dialogue) for r in results)
    total = sum(r.questions for r in results)
    shares = ({t: counts[t] / recorded for t in PAPER_QUESTION_TYPES} if recorded else
              ({t: 0.0 for t in PAPER_QUESTION_TYPES} if total == 0 else None))
    asked = [[(qa['type'], qa['noun']) for qa in r.dialogue] for r in results]
    repeats = sum(len(a) - len(set(a)) for a in asked)
    returns = {name: sum(rewards.of_episode(r.success, r.steps, r.questions, r.invalid_questions) for r in results)
               / len(results) for name, rewards in (('return', Rewards()), ('return_fixed_1', Rewards.fixed_1()))}
    return {'n': len(results), 'tasks': len(tasks), 'repeats': round(repeats / recorded, 3) if recorded else 0.0,
            'steps': round(sum(r.steps for r in results) / len(results), 2),
            **{k: round(v, 4) for k, v in returns.items()},
            # unrounded: the document rounds once, where it prints (56.346 rounded to 56.35 first printed as 56.4)
            **{k: overall[k] for k in ('SR', 'PWSR', 'GC', 'NQ')},
            'CI95': {k: [lo, hi] for k, (lo, hi) in ci.items()},
            'shares': {t: round(v, 3) for t, v in shares.items()} if shares is not None else None,
            **({'episodes': summarize(results)['episodes']} if chained else {}),
            'results': results}


def build_report(plan: Plan, resamples: int) -> dict:
    rows = {(s.split, s.key): setting_row(plan, s, resamples) for s in settings()}
    chained = {(s.split, s.key): setting_row(plan, s, resamples, chained=True) for s in chained_settings()}
    return {'rows': rows, 'chained': chained, 'plan': plan}


# --------------------------------------------------------------------------------------------- chained

def chained_rows(rows: dict, chained: dict) -> list[list]:
    """The chained table: each setting of the chained stage beside the same setting under expert initialisation."""
    out = []
    for s in chained_settings():
        r, e = chained[(s.split, s.key)], rows.get((s.split, s.key), {})
        name = 'map-and-plan' if s.performer == 'map' else 'Episodic Transformer'
        label = MAP_ROWS[s.key][0] if s.key in MAP_ROWS else setting_name(s.key).removeprefix('Map performer: ')
        expert = f'{e["SR"]:.1f}' if e.get('n') else ('no results' if (s.split, s.key) in rows else 'not in the tables')
        if not r.get('n'):
            out.append([name, label, 0, 'no results', '', '', '', '', '', '', expert, ''])
            continue
        ep = r['episodes']
        out.append([name, label, _n(r), _v(r, 'SR'), _v(r, 'PWSR'), f'{r["GC"]:.1f}', _v(r, 'NQ'),
                    f'{ep["episodes"]}: {ep["all_succeeded"]:.1f}%', f'{ep["in_order"]:.2f}',
                    f'{ep["held_at_start"]}', expert,
                    f'{r["SR"] - e["SR"]:+.1f}' if e.get('n') else ''])
    return out


def lost_rows(rows: dict, chained: dict) -> list[list]:
    """Per task type, over the same tasks with the instruction only: SR under expert initialisation and under
    chaining, and the tasks lost (done from the expert's state, not from the agent's own) and gained, for each
    performer."""
    out = []
    pairs = {}
    for name, key in (('E.T.', 'instruction_only'), ('map', 'map_instruction_only')):
        e, c = rows.get(('valid_unseen', key), {}), chained.get(('valid_unseen', key), {})
        if e.get('n') and c.get('n'):
            mine = {r.task_id: r for r in e['results']}
            pairs[name] = [(mine[r.task_id], r) for r in c['results'] if r.task_id in mine]
    if not pairs:
        return out
    types = sorted({a.task_type for ps in pairs.values() for a, _ in ps}, key=type_order)
    for t in (*types, 'overall'):
        cells = [t]
        for name in ('E.T.', 'map'):
            ps = [(a, b) for a, b in pairs.get(name, []) if t == 'overall' or a.task_type == t]
            if not ps:
                cells += ['', '', '', '']
                continue
            n = len(ps)
            cells += [f'{n}', f'{100 * sum(a.success for a, _ in ps) / n:.1f} / {100 * sum(b.success for _, b in ps) / n:.1f}',
                      f'{sum(a.success and not b.success for a, b in ps)}', f'{sum(b.success and not a.success for a, b in ps)}']
        out.append(cells)
    return out


def chained_failure_rows(chained: dict, top: int = 10) -> list[list]:
    """The `top` most common ways a chained episode goes wrong with All QAs, for each performer: its first failed
    task (dialfred_bringup.failures.episode_failures)."""
    out = []
    for name, key in (('Episodic Transformer', 'all_qas'), ('map-and-plan', 'map_all_qas')):
        c = chained.get(('valid_unseen', key), {})
        if not c.get('n'):
            continue
        for k, row in enumerate(episode_failures(c['results'], top=top), start=1):
            out.append([name, k, row['task_type'], row['task_in_episode'], row['end_reason'], row['last_error'],
                        row['episodes'], f'{100 * row["share_of_episodes"]:.1f}%', ', '.join(f'`{x}`' for x in row['examples'][:2])])
    return out


def _v(row: dict, key: str) -> str:
    if not row.get('n'):
        return 'no results'
    d = 2 if key == 'NQ' else 1
    lo, hi = row['CI95'][key]
    return f'{row[key]:.{d}f} [{lo:.{d}f}, {hi:.{d}f}]'


def _n(row: dict) -> str:
    if not row.get('n'):
        return '0'
    return f'{row["n"]}' if row['n'] == row['tasks'] else f'{row["n"]} of {row["tasks"]}'


def _share(row: dict, t: str) -> str:
    if not row.get('n'):
        return 'no results'
    return 'not recorded' if row['shares'] is None else f'{row["shares"][t]:.2f}'


def most_asked(rows: dict, top: int = 10) -> list[tuple[str, int]]:
    c = Counter()
    for split in SPLITS:
        for r in rows[(split, 'rl_anytime')].get('results', []):
            for qa in r.dialogue:
                c[f'{qa["type"]} {qa["noun"]}'.strip()] += 1
    return sorted(c.items(), key=lambda kv: (-kv[1], kv[0]))[:top]


def turned_around(rows: dict, count: int = 5) -> list[tuple]:
    """Tasks failed by the performer alone (instruction only) and succeeded with RL anytime's questions."""
    out = []
    for split in SPLITS:
        base = {r.task_id: r for r in rows[(split, 'instruction_only')].get('results', [])}
        tasks = {t.task_id: t for t in load_split(split)}
        for r in rows[(split, 'rl_anytime')].get('results', []):
            b = base.get(r.task_id)
            if b is not None and not b.success and r.success and r.dialogue:
                out.append((tasks[r.task_id], b, r))
    return out[:count]


def what_holds(rows: dict) -> list[str]:
    u = lambda key: rows[('valid_unseen', key)]
    lines = []

    def have(*keys):
        return all(u(k).get('n') for k in keys)

    def verdict(ok: bool) -> str:
        return '**holds**' if ok else '**does not hold**'

    if have('rl_anytime', 'all_qas'):
        rl, allq = u('rl_anytime'), u('all_qas')
        ok = rl['SR'] >= allq['SR'] and rl['NQ'] <= allq['NQ'] / 4
        lines.append(f'RL anytime matches All QAs with a quarter of the questions (valid_unseen SR {rl["SR"]:.1f} >= '
                     f'{allq["SR"]:.1f}, NQ {rl["NQ"]:.2f} <= {allq["NQ"]:.2f} / 4 = {allq["NQ"] / 4:.2f}; paper 33.6 vs '
                     f'32.0 SR, NQ 0.71 vs 3.24): {verdict(ok)}.')
    for split in SPLITS:
        rl, rnd = rows[(split, 'rl_anytime')], rows[(split, 'random_qa')]
        if rl.get('n') and rnd.get('n'):
            p = PAPER_T2
            lines.append(f'RL anytime beats Random QA on {split} (SR {rl["SR"]:.1f} vs {rnd["SR"]:.1f}, 95% '
                         f'[{rl["CI95"]["SR"][0]:.1f}, {rl["CI95"]["SR"][1]:.1f}] vs [{rnd["CI95"]["SR"][0]:.1f}, '
                         f'{rnd["CI95"]["SR"][1]:.1f}]; paper {p["rl_anytime"]["SR"][split]} vs '
                         f'{p["random_qa"]["SR"][split]}): {verdict(rl["SR"] > rnd["SR"])}.')
    drops = {}
    for kind, base in (('rl_anytime', 'rl_anytime'), ('random_qa', 'random_qa')):
        if have(base, *(f'{kind}_withhold_{t}' for t in PAPER_QUESTION_TYPES)):
            drops[kind] = {t: u(base)['SR'] - u(f'{kind}_withhold_{t}')['SR'] for t in PAPER_QUESTION_TYPES}
    for kind, name in (('rl_anytime', 'RL anytime'), ('random_qa', 'Random')):
        if kind in drops:
            d = drops[kind]
            ok = d['location'] > d['appearance'] and d['location'] > d['direction']
            lines.append(f'Withholding location answers hurts {name} more than appearance or direction (SR drop '
                         f'{d["location"]:+.1f} vs {d["appearance"]:+.1f} and {d["direction"]:+.1f} points; paper '
                         f'{"1.4 vs 1.2 and 0.6" if kind == "rl_anytime" else "2.4 vs 2.3 and 2.2"}): {verdict(ok)}.')
    base = u('rl_anytime')
    if base.get('n') and base['shares'] is not None:
        for t in PAPER_QUESTION_TYPES:
            w = u(f'rl_anytime_withhold_{t}')
            if w.get('n') and w['shares'] is not None:
                ok = w['shares'][t] < base['shares'][t]
                paper = PAPER_T3[f'rl_anytime_withhold_{t}'][4][PAPER_QUESTION_TYPES.index(t)]
                lines.append(f'RL trained with {t} answers withheld asks fewer {t} questions (share {w["shares"][t]:.2f} '
                             f'vs {base["shares"][t]:.2f} unperturbed; paper {paper:.2f} vs '
                             f'{PAPER_T3["rl_anytime"][4][PAPER_QUESTION_TYPES.index(t)]:.2f}): {verdict(ok)}.')
    if 'rl_anytime' in drops and 'random_qa' in drops:
        rl = sum(drops['rl_anytime'].values()) / 3
        rnd = sum(drops['random_qa'].values()) / 3
        lines.append(f'Under a perturbed oracle RL loses less SR than Random (mean drop over the three types '
                     f'{rl:+.1f} vs {rnd:+.1f} points; paper +0.9 vs +2.3): {verdict(rl < rnd)}.')
    for split in SPLITS:      # beyond the paper: the objective RL maximises, against its start (both ask at the start)
        rl, start = rows[(split, 'rl_begin')], rows[(split, 'pretrained')]
        if rl.get('n') and start.get('n') and rl['n'] == start['n']:
            lo, hi = paired_interval(rl['results'], start['results'])
            lines.append(f'(Beyond the paper) RL begin raises the return it maximises over its pre-trained start, both '
                         f'asking at the start, on {split} (return {rl["return"]:+.4f} vs {start["return"]:+.4f}, '
                         f'difference 95% [{lo:+.4f}, {hi:+.4f}] over the same tasks; SR {rl["SR"]:.1f} vs '
                         f'{start["SR"]:.1f}, NQ {rl["NQ"]:.2f} vs {start["NQ"]:.2f}): '
                         + ('**holds**' if lo > 0 else '**not shown** (the interval includes 0)' if hi > 0
                            else '**does not hold**') + '.')
    return lines + swap_lines(rows)


def _worth(alone: dict, asked: list) -> Optional[tuple[float, int]]:
    """(SR points per question of `asked` over the results in `alone` (task id -> result) of the same tasks,
    the tasks), None without questions."""
    nq = sum(r.questions for r in asked)
    if not asked or not nq:
        return None
    return 100.0 * sum(r.success - alone[r.task_id].success for r in asked) / nq, len(asked)


def worth_rows(rows: dict) -> list[list[str]]:
    """The worth of a question for each performer on valid_unseen: All QAs over instruction only, overall and by
    task family; by type, Random QA's episodes that drew that type over instruction only on the same tasks; and
    the swap control (All QAs with another task's answers), its SR against All QAs' with a paired interval."""
    out = []
    fmt = lambda w: 'no questions' if w is None else f'{w[0]:+.2f} ({w[1]})'
    for name, alone_key, all_key, random_key, swapped_key in WORTH_ROWS.values():
        alone, allq = rows[('valid_unseen', alone_key)], rows[('valid_unseen', all_key)]
        if not (alone.get('n') and allq.get('n')):
            continue
        base = {r.task_id: r for r in alone['results']}
        asked = [r for r in allq['results'] if r.task_id in base]
        cells = [name, fmt(_worth(base, asked))]
        for goto in (True, False):
            cells.append(fmt(_worth(base, [r for r in asked if has_goto(r.task_type) == goto])))
        drawn = rows[('valid_unseen', random_key)].get('results', [])
        for t in PAPER_QUESTION_TYPES:
            cells.append(fmt(_worth(base, [r for r in drawn if r.task_id in base and r.dialogue
                                           and all(qa['type'] == t for qa in r.dialogue)])))
        sw = rows[('valid_unseen', swapped_key)]
        own = {r.task_id: r for r in asked}
        swapped = [r for r in sw.get('results', []) if r.task_id in own]
        if swapped:
            mine = [own[r.task_id] for r in swapped]
            lo, hi = paired_interval(mine, swapped, value=lambda r: 100.0 * r.success)
            sr = lambda rs: 100.0 * sum(r.success for r in rs) / len(rs)
            cells += [f'{sr(swapped):.1f}', f'{sr(mine) - sr(swapped):+.1f} [{lo:+.1f}, {hi:+.1f}]']
        else:
            cells += ['no results', '']
        out.append(cells)
    return out


def swap_lines(rows: dict) -> list[str]:
    """What the swap control says of each performer: does it read its answers?"""
    lines = []
    for name, _, all_key, _, swapped_key in WORTH_ROWS.values():
        allq, sw = rows[('valid_unseen', all_key)], rows[('valid_unseen', swapped_key)]
        if not (allq.get('n') and sw.get('n')) or allq['n'] != sw['n']:
            continue
        lo, hi = paired_interval(allq['results'], sw['results'], value=lambda r: 100.0 * r.success)
        same = sum(a.steps == b.steps and a.success == b.success for a, b in zip(allq['results'], sw['results']))
        lines.append(f'(Beyond the paper) The {name} performer reads its answers: with each answer replaced by the answer '
                     f'to the same question in another task it succeeds less (SR {sw["SR"]:.1f} vs {allq["SR"]:.1f} with its '
                     f'own answers, difference 95% [{lo:+.1f}, {hi:+.1f}] over the same tasks; {same} of {allq["n"]} '
                     'episodes end with the same steps and outcome): '
                     + ('**holds**' if lo > 0 else '**not shown** (the interval includes 0)' if hi > 0
                        else '**does not hold**') + '.')
    return lines


def sampled_mix(run_dir: Path, last: int = 8) -> Optional[dict]:
    """The question-type mix an RL run sampled over its last `last` updates (its metrics.jsonl), weighting
    each update by its questions; None when the run's training log is not there (shipped checkpoints)."""
    path = run_dir / 'metrics.jsonl'
    try:
        records = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    except (OSError, ValueError):
        return None
    records = [r for r in records if r.get('mix')][-last:]
    weights = [r.get('nq', 0.0) * r.get('episodes', 0) for r in records]
    if not records or not sum(weights):
        return None
    return {t: sum(w * r['mix'].get(t, 0.0) for w, r in zip(weights, records)) / sum(weights) for t in PAPER_QUESTION_TYPES}


def why_lines(plan: Plan, rows: dict) -> list[str]:
    """What the numbers say about why the paper's findings hold or not here: the worth of a question
    against the rewards' price, greedy against sampled question mixes, what RL does when answers are
    withheld. Every figure is computed from the rows or the RL runs' training logs."""
    rewards, lines = Rewards(), []
    price = -rewards.question / rewards.success * 100           # SR points a question must buy to pay for itself

    def row(split, key):
        return rows.get((split, key), {})

    for split in SPLITS:
        alone, allq, pre = row(split, 'instruction_only'), row(split, 'all_qas'), row(split, 'pretrained')
        if not (alone.get('n') and allq.get('n') and allq['NQ']):
            continue
        worth = (allq['SR'] - alone['SR']) / allq['NQ']
        p_alone, p_all = PAPER_T2['instruction_only'], PAPER_T2['all_qas']
        paper_worth = (p_all['SR'][split] - p_alone['SR'][split]) / p_all['NQ']
        text = (f'The worth of a question on {split}: All QAs\' answers raise SR by {worth:.1f} points per question over '
                f'instruction only ({allq["SR"]:.1f} vs {alone["SR"]:.1f} with {allq["NQ"]:.2f} questions; the paper\'s '
                f'performer: {paper_worth:.1f}). Under the paper\'s rewards a question pays for itself only if it buys '
                f'more than {price:.1f} SR points (its {rewards.question:+.2f} against success {rewards.success:+.0f}; '
                f'steps aside), so asking everything {"loses" if worth < price else "earns"} return here '
                f'(All QAs {allq["return"]:+.4f} vs instruction only {alone["return"]:+.4f})')
        if pre.get('n') and pre['NQ']:
            text += (f'; the pre-trained questioner\'s questions at the start buy {(pre["SR"] - alone["SR"]) / pre["NQ"]:.1f} '
                     f'points each ({pre["NQ"]:.2f} per episode)')
        lines.append(text + ('. RL maximises that return, so with answers worth less than their price it learns to ask '
                             'few questions, and its SR stays near those few questions\' SR rather than All QAs\'.'
                             if worth < price else '. Here answers are worth their price, so RL has reason to ask.'))
    mixes = {}
    for key in ('rl_anytime', *(f'rl_anytime_withhold_{t}' for t in PAPER_QUESTION_TYPES)):
        if not plan.cfg.shipped:
            mix = sampled_mix(plan.run / 'questioner' / key)
            if mix is not None:
                mixes[key] = mix
    greedy = row('valid_unseen', 'rl_anytime').get('shares')
    if greedy:
        fmt = lambda m: ' / '.join(f'{m[t]:.2f}' for t in PAPER_QUESTION_TYPES)
        text = (f'Question mix: the evaluation plays each questioner greedily, asking the type its policy ranks first; '
                f'RL anytime\'s greedy shares on valid_unseen are {fmt(greedy)} (location / appearance / direction)')
        if 'rl_anytime' in mixes:
            text += f', while sampling in training (its last 8 updates) it asked {fmt(mixes["rl_anytime"])}'
            moved = [f'{t} withheld: {fmt(mixes[f"rl_anytime_withhold_{t}"])} (its {t} share '
                     f'{mixes[f"rl_anytime_withhold_{t}"][t] - mixes["rl_anytime"][t]:+.2f})'
                     for t in PAPER_QUESTION_TYPES if f'rl_anytime_withhold_{t}' in mixes]
            if moved:
                text += '; sampled mixes of the runs trained with one type withheld: ' + '; '.join(moved)
        else:
            text += ' (the RL runs\' training logs are not in this run folder: no sampled mixes)'
        lines.append(text + '. A shift of the sampled mix that leaves the first-ranked type in place does not show '
                     'in the greedy shares of Table III.')
    base, loc = row('valid_unseen', 'rl_anytime'), row('valid_unseen', 'rl_anytime_withhold_location')
    if base.get('n') and loc.get('n'):
        lines.append(f'With location answers withheld half the time, RL trained that way asks {loc["NQ"]:.2f} questions '
                     f'per episode against {base["NQ"]:.2f} unperturbed, and {loc["repeats"]:.3f} of its questions '
                     f'repeat one already asked (unperturbed {base["repeats"]:.3f}): '
                     + ('it asks the withheld type again until it is answered rather than switching type.'
                        if loc['NQ'] > base['NQ'] and loc['repeats'] > base['repeats'] else
                        'it does not ask the withheld type again more often.'))
    return lines


def paired_interval(a: list, b: list, resamples: int = 2000, seed: int = 0, value=None) -> tuple[float, float]:
    """95% bootstrap interval of the mean paired difference of `value` (an episode's number; default the
    paper's return), a - b (results of the same tasks, in the same order)."""
    ret = value or (lambda r: Rewards().of_episode(r.success, r.steps, r.questions, r.invalid_questions))
    d = np.array([ret(x) - ret(y) for x, y in zip(a, b)])
    rng = np.random.default_rng(seed)
    means = d[rng.integers(0, len(d), size=(resamples, len(d)))].mean(axis=1)
    return float(np.quantile(means, 0.025)), float(np.quantile(means, 0.975))


def draw_frontier(points: list[tuple[str, float, float]], out_path: Path) -> Path:
    """SR against NQ, one labelled dot per setting (Pillow; the style of dialfred_performer.curves)."""
    from PIL import Image, ImageDraw, ImageFont  # lazy: PIL, which the rest of this module does without

    from dialfred_performer.curves import _ticks  # lazy: PIL, which the rest of this module does without
    font = ImageFont.load_default()
    legend = [f'{label} ({sr:.1f}, {nq:.2f})' for label, sr, nq in points]
    probe = ImageDraw.Draw(Image.new('RGB', (1, 1)))
    R = 48 + int(max([probe.textlength(t, font=font) for t in legend] + [100]))     # the legend fits, always
    W, H, (L, T, B) = 520 + R, max(480, 40 + 14 * len(points)), (56, 30, 40)
    image = Image.new('RGB', (W, H), 'white')
    draw = ImageDraw.Draw(image)
    title = 'SR (valid_unseen) against questions per episode (NQ)'
    draw.text((W // 2 - len(title) * 3, 8), title, fill='black', font=font)
    left, top, right, bottom = L, T, W - R, H - B
    draw.rectangle((left, top, right, bottom), outline=(160, 160, 160))
    x_hi = max([p[2] for p in points] + [1.0]) * 1.08
    y_hi = max([p[1] for p in points] + [10.0]) * 1.1

    def at(x, y):
        return left + x / x_hi * (right - left), bottom - y / y_hi * (bottom - top)

    for y in _ticks(0.0, y_hi):
        _, py = at(0, y)
        draw.line((left, py, right, py), fill=(230, 230, 230))
        draw.text((4, py - 6), f'{y:.3g}', fill='black', font=font)
    for x in _ticks(0.0, x_hi):
        px, _ = at(x, 0)
        draw.text((px - 8, bottom + 4), f'{x:g}', fill='black', font=font)
    draw.text((right - 60, bottom + 18), 'NQ', fill='black', font=font)
    draw.text((4, top - 18), 'SR %', fill='black', font=font)
    palette = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
               (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207)]
    frontier, best = [], -1.0
    for _label, sr, nq in sorted(points, key=lambda p: (p[2], -p[1])):
        if sr > best:
            frontier.append(at(nq, sr))
            best = sr
    if len(frontier) > 1:
        draw.line(frontier, fill=(200, 200, 200), width=2)
    def mark(shape: int, x: float, y: float, colour) -> None:
        """Colours repeat after 10 settings; each round of them gets another shape, so no two settings look alike."""
        box = (x - 4, y - 4, x + 4, y + 4)
        if shape == 0:
            draw.ellipse(box, fill=colour)
        elif shape == 1:
            draw.rectangle(box, fill=colour)
        elif shape == 2:
            draw.polygon([(x, y - 5), (x - 5, y + 4), (x + 5, y + 4)], fill=colour)
        else:
            draw.polygon([(x, y - 5), (x + 5, y), (x, y + 5), (x - 5, y)], fill=colour)

    for k, (_label, sr, nq) in enumerate(points):
        colour, shape = palette[k % len(palette)], (k // len(palette)) % 4
        mark(shape, *at(nq, sr), colour)
        y = top + 14 * k
        mark(shape, right + 16, y + 6, colour)
        draw.text((right + 26, y), legend[k], fill='black', font=font)
    out_path = Path(out_path)
    image.save(out_path)
    return out_path


def _relative(path: Path) -> str:
    try:
        return str(Path(path).resolve().relative_to(REPO))
    except ValueError:
        return str(path)


def check_line(plan: Plan) -> str:
    """What the check stage found: the settings' first tasks through the graph against the tables' episodes."""
    path = plan.check_dir / 'report.json'
    if not plan.check_tasks or not path.exists():
        return '- check through the ROS graph: not run (`--check-tasks 0`)'
    report = json.loads(path.read_text())
    rows = report['settings']
    episodes = sum(r['episodes'] for r in rows.values())
    bad = {k: r['differing'] for k, r in rows.items() if r['differing']}
    head = (f'- check through the ROS graph (performer, questioner, oracle and simulator nodes): the first '
            f'{report["tasks"]} tasks of {len(rows)} settings, {episodes} episodes: ')
    if not bad:
        return head + 'every one the same as the tables\' episodes (steps, success, questions, dialogue, end)'
    return head + f'**{sum(map(len, bad.values()))} differ** ' + '; '.join(
        f'{k}: {", ".join(v[:5])}' for k, v in sorted(bad.items()))


def render(plan: Plan, report: dict, plot_name: str) -> str:
    """The results document (Markdown) of `plan`'s run from its `report` (build_report): every cell is
    computed here, the words and layout are the template templates/results.md.j2."""
    rows, cfg = report['rows'], plan.cfg
    mode = '--quick' if cfg.quick else '--shipped' if cfg.shipped else ''
    through = {'local': 'in local worker processes without ROS (`dialfred_bringup.local`, the graph\'s episodes)',
               'graph': 'through the ROS graph (performer nodes)',
               'in-process': 'by the agent in the launcher\'s process with simulator and oracle nodes'}[plan.eval_path]
    perf = plan.performer_checkpoint
    settings = [
        f'- performer: `{_relative(perf)}` (weights sha256 `{weights_sha256(perf)[:16]}`...: a digest of its '
        'tensors, the same wherever the same model is trained; the file itself also records its command and commit)'
        if perf.exists() else f'- performer: `{_relative(perf)}` (absent)',
        '- questioners: ' + ('the shipped checkpoints in `' + _relative(SHIPPED_QUESTIONERS) + '/`' if cfg.shipped
                             else f'fine-tuned by the rl stage in `{_relative(plan.run / "questioner")}/`') + ', played greedily',
        f'- evaluation: the `et` performer at {camera("et")} px (the map performer\'s table: `map`, over the same '
        f'perception network, its camera at {camera("map")} px area-averaged to the network\'s {RESOLUTION} px), played {through}, seed {cfg.seed}, '
        + (f'the first {plan.eval_limit} tasks of each split' if plan.eval_limit else 'every task of each split')
        + f'; perturbed oracle: one type\'s answers withheld with probability {PERTURB_PROBABILITY}',
        check_line(plan),
        f'- intervals: 95% percentile bootstrap over episodes, {cfg.resamples} resamples '
        '(`dialfred_sim.metrics.intervals`); SR and PWSR in percent, NQ questions per episode']
    table2 = [[p['number'], p['name'], split, _n(r), _v(r, 'SR'), p['SR'][split], _v(r, 'PWSR'), p['PWSR'][split],
               _v(r, 'NQ'), p['NQ']]
              for key, p in PAPER_T2.items() for split in SPLITS for r in [rows[(split, key)]]]
    table3 = [[name, _n(r), _v(r, 'SR'), sr, _v(r, 'PWSR'), pwsr, _v(r, 'NQ'), nq, *(_share(r, t) for t in PAPER_QUESTION_TYPES),
               ' / '.join(f'{v:.2f}' for v in shares)]
              for key, (name, sr, pwsr, nq, shares) in PAPER_T3.items() for r in [rows[('valid_unseen', key)]]]
    table4 = [[name, _n(r), _v(r, 'SR'), sr, _v(r, 'PWSR'), pwsr, _v(r, 'NQ'), nq]
              for key, (name, sr, pwsr, nq) in PAPER_T4.items() for r in [rows[('valid_unseen', key)]]]
    extra = []
    for key, name in EXTRA.items():
        r = rows[('valid_unseen', key)]
        extra.append(f'| {name} | {_n(r)} | {_v(r, "SR")} | {_v(r, "PWSR")} | {_v(r, "NQ")} | {r["repeats"]:.3f} | '
                     + ' | '.join(_share(r, t) for t in PAPER_QUESTION_TYPES) + ' |' if r.get('n')
                     else f'| {name} | 0 | no results | | | |  | | |')
    map_rows = []
    for key, (name, et_key, *_) in MAP_ROWS.items():
        r, e = rows[('valid_unseen', key)], rows[('valid_unseen', et_key)]
        gain = f'{r["SR"] - e["SR"]:+.1f}' if r.get('n') and e.get('n') else ''
        map_rows.append([name, _n(r), _v(r, 'SR'), _v(r, 'PWSR'), _v(r, 'NQ'),
                         f'{e["SR"]:.1f}' if e.get('n') else 'no results', f'{e["NQ"]:.2f}' if e.get('n') else '', gain])
    returns = [[setting_name(key), split, r['n'], f'{r["SR"]:.1f}', f'{r["NQ"]:.2f}', f'{r["steps"]:.1f}',
                f'{r["return"]:+.4f}', f'{r["return_fixed_1"]:+.4f}']
               for split in SPLITS for key in RETURN_ROWS for r in [rows.get((split, key), {})] if r.get('n')]
    asked = []
    for q, k in most_asked(rows):
        kind, _, noun = q.partition(' ')
        asked.append((question_text(kind, noun), k))
    examples = [dict(task_id=task.task_id, task_type=task.task_type, instruction=task.instruction,
                     alone_end=base.end_reason, alone_steps=base.steps, steps=r.steps,
                     dialogue=[(question_text(qa['type'], qa['noun']), qa['answer'] if qa['valid'] else '(no answer)')
                               for qa in r.dialogue])
                for task, base, r in turned_around(rows)]
    times = run_times(plan)
    return environment().get_template('results.md.j2').render(
        command='./dialfred reproduce' + (f' {mode}' if mode else ''), eval_dir=_relative(plan.eval_dir),
        quick=cfg.quick, settings=settings, table2=table2, table3=table3, table4=table4, extra=extra, returns=returns,
        map_rows=map_rows, worth=worth_rows(rows),
        chained=chained_rows(rows, report['chained']), chained_worth=worth_rows(report['chained']),
        chained_lost=lost_rows(rows, report['chained']), chained_failures=chained_failure_rows(report['chained']),
        chained_dir=_relative(plan.chained_dir),
        plot_name=plot_name, holds=what_holds(rows), why=why_lines(plan, rows), asked=asked, examples=examples,
        times=times)


def stage_times(run: Path) -> dict:
    """{stage: {'seconds', 'runs', 'reused', 'items', 'machine', 'speed_probe_s', 'done'}} from a run's stamps
    (the stages with one; `done`: whether the stamp says the stage finished; `speed_probe_s`: the machine's
    speed probe at each run's start and end, [] in stamps from before it was kept)."""
    out = {}
    for stage in STAGES[:-1]:
        try:
            s = json.loads((run / 'stamps' / f'{stage}.json').read_text())
        except (OSError, ValueError):
            continue
        items = (s.get('report') or {}).get('items') or {}
        # An itemized stage costs the sum of its items' times, each counting its own cut-off runs: an item
        # reused from an earlier run cost its time then (in an earlier stage run whose time the stage's
        # own seconds may or may not hold, so they are not added).
        seconds = sum(i.get('seconds', 0) for i in items.values()) if items else s.get('seconds', 0)
        out[stage] = {'seconds': round(seconds, 1), 'runs': s.get('runs', 1),
                      'reused': sum(1 for i in items.values() if i.get('reused')), 'items': len(items),
                      'machine': s.get('machine'), 'speed_probe_s': s.get('speed_probe_s', []),
                      'done': s.get('status') == 'done'}
    return out


def run_times(plan: Plan) -> list[str]:
    """One line per stage with its seconds from its stamp, and the total; with --shipped, the training
    stages' times in the run that made the shipped models (SHIPPED_RUN, written by `ship`)."""
    cfg = plan.cfg
    here = stage_times(plan.run)
    try:
        shipped = json.loads(SHIPPED_RUN.read_text()).get('stages', {}) if cfg.shipped else {}
    except (OSError, ValueError):
        shipped = {}
    times, total, total_shipped = [], 0.0, 0.0
    for stage in STAGES[:-1]:
        t = here.get(stage)
        if t is None:
            made = shipped.get(stage) if stage in TRAINING else None
            if made:
                total_shipped += made['seconds']
                cpu = (made.get('machine') or {}).get('cpu')
                times.append(f'{stage}: not run here (shipped; {made["seconds"]:.0f} s in the run that made them'
                             + (f', on {cpu}' if cpu else '') + ')')
            else:
                times.append(f'{stage}: not run here' + (' (shipped)' if cfg.shipped and stage in TRAINING else ''))
            continue
        total += t['seconds']
        notes = ([f'over {t["runs"]} runs: it was resumed'] if t['runs'] > 1 else []) + \
            ([f'{t["reused"]} of its {t["items"]} items done by an earlier run of the same inputs, their '
              'time included'] if t['reused'] else []) + \
            ([f'speed probe {min(t["speed_probe_s"]) * 1000:.1f}-{max(t["speed_probe_s"]) * 1000:.1f} ms'] if t['speed_probe_s'] else [])
        times.append(f'{stage}: {t["seconds"]:.0f} s' + (f' ({"; ".join(notes)})' if notes else ''))
    times.append(f'total of the stages: {total / 60:.1f} min')
    if any(t['speed_probe_s'] for t in here.values()):
        times.append('speed probe: a fixed convolution timed at each stage run\'s start and end (machine.speed_probe); '
                     'the same machine gives it up to 2x apart in different hours, and a stage\'s time moves with it')
    if total_shipped:
        times.append(f'with the shipped models\' training stages: {(total + total_shipped) / 60:.1f} min')
    return times


def setting_name(key: str) -> str:
    """A setting's name in the plot and the returns table (the paper's where it has one)."""
    names = {**{k: p['name'] for k, p in PAPER_T2.items()}, **{k: v[0] for k, v in PAPER_T3.items()},
             **{k: v[0] for k, v in PAPER_T4.items()}, 'pretrained': 'Pre-trained only',
             'rl_anytime_no_dialogue': 'RL anytime, instruction only',
             SWAPPED: 'All QAs, answers swapped', 'rl_anytime_chained': 'RL anytime, fine-tuned chained',
             'map_rl_anytime_chained': 'Map performer: RL anytime, fine-tuned chained',
             **{k: f'Map performer: {name}' for k, (name, *_) in MAP_ROWS.items()}}
    return names[key]


def write_outputs(plan: Plan, report: dict) -> tuple[Path, Path]:
    rows = report['rows']
    points = []
    seen = set()
    for s in settings():
        r = rows[(s.split, s.key)]
        if s.split == 'valid_unseen' and r.get('n') and s.key not in seen and s.answers == 'oracle':
            seen.add(s.key)
            points.append((setting_name(s.key), r['SR'], r['NQ']))
    plot = draw_frontier(points, plan.run / 'sr_nq.png')
    doc = plan.run / 'results.md'
    doc.write_text(render(plan, report, plot.name))
    return doc, plot


def copy_doc(run: Path, target: Path) -> None:
    """Copy the run's results.md to `target` with its plot beside it: sr_nq.png next to a results.md,
    <stem>_sr_nq.png (the link rewritten) next to a doc of another name, so that two documents (a full
    run's and the shipped checkpoints') can share a folder."""
    text = (run / 'results.md').read_text()
    plot = 'sr_nq.png' if target.name == 'results.md' else f'{target.stem}_sr_nq.png'
    text = text.replace('](sr_nq.png)', f']({plot})')
    shutil.copyfile(run / 'sr_nq.png', target.with_name(plot))
    target.write_text(text)
