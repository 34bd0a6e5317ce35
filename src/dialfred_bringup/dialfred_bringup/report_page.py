"""The HTML of an evaluation report (no ROS): one static page, its style, its SVG chart and its script.

`render_page(report)` turns a `report.Report` into the text of a page that works opened from disk:
no server, no network (no CDN, fonts or scripts from elsewhere). The page is the Jinja2 template
templates/report.html.j2 (its style report.css and script report.js are inlined); this module works
out what it shows (numbers formatted, the chart's geometry). Everything shown is escaped.
The page's filters are plain JavaScript over `data-*` attributes of each episode; their state is
kept in the address's fragment (`page.html#type=Clean&outcome=failure:stop`), so a filtered view
can be linked to.
"""

from __future__ import annotations

import functools
import html
from pathlib import Path
from typing import Optional, Sequence

import jinja2

from dialfred_sim.metrics import END_REASONS

OUTCOME_LABELS = {'stop': 'the agent stopped', 'max_steps': 'step limit', 'max_failures': 'too many failed actions',
                  'error': 'error'}


def esc(value) -> str:
    return html.escape(str(value), quote=True)


def outcome_label(result) -> str:
    """'success' or 'failure (why)'; a chained task whose goal held at its start says so."""
    if result.held_at_start:
        return 'failure (its goal held at its chained start: scored as not done)'
    return 'success' if result.success else f'failure ({OUTCOME_LABELS.get(result.end_reason, result.end_reason)})'


def interval_text(lo: float, hi: float, digits: int = 1) -> str:
    return f'[{lo:.{digits}f}, {hi:.{digits}f}]'


# ------------------------------------------------------------------------------------------------ chart

BAR_ROW, LABEL_W, PLOT_W, VALUE_W, TOP = 22, 190, 460, 170, 26
TEMPLATES = Path(__file__).resolve().parent / 'templates'


def sr_chart(rows: Sequence[tuple], title: str = 'SR per task type (%), with 95% intervals') -> dict:
    """The geometry of an SVG of horizontal bars: `rows` are (label, n, SR, (lo, hi), filter value or '').
    A row with a filter value is clickable (the page's script filters the episodes by that task type)."""
    width = LABEL_W + PLOT_W + VALUE_W

    def x(pct: float) -> float:
        return LABEL_W + PLOT_W * max(0.0, min(100.0, pct)) / 100.0

    bars = []
    for k, (label, n, sr, (lo, hi), filter_type) in enumerate(rows):
        y = TOP + BAR_ROW * k
        bars.append(dict(label=label, n=n, sr=f'{sr:.1f}', interval=interval_text(lo, hi), interval0=interval_text(lo, hi, 0),
                         y=y, mid=y + BAR_ROW / 2, width=f'{x(sr) - LABEL_W:.1f}', lo=f'{x(lo):.1f}', hi=f'{x(hi):.1f}',
                         filter_type=filter_type))
    return dict(title=title, width=width, height=TOP + BAR_ROW * len(rows) + 24, top=TOP, bottom=TOP + BAR_ROW * len(rows),
                row=BAR_ROW, label_w=LABEL_W, plot_w=PLOT_W, bars=bars,
                ticks=[dict(pct=pct, x=f'{x(pct):.1f}') for pct in (0, 25, 50, 75, 100)])


# ------------------------------------------------------------------------------------------------ page

@functools.lru_cache(maxsize=1)
def environment() -> jinja2.Environment:
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), autoescape=False, keep_trailing_newline=True,
                             undefined=jinja2.StrictUndefined)
    env.filters['esc'] = esc
    return env


def cards(overall: dict, bounds: dict) -> list[dict]:
    out = []
    for key, unit, digits, what in (('SR', '%', 1, 'success rate'), ('PWSR', '%', 1, 'path-weighted success'),
                                    ('GC', '%', 1, 'goal conditions met'), ('NQ', '', 2, 'questions per episode')):
        lo, hi = bounds[key]
        out.append(dict(key=key, number=f'{overall[key]:.{digits}f}{unit}', interval=interval_text(lo, hi, digits),
                        what=what))
    return out


def chained_places(results) -> dict:
    """{task id: 'episode E, task k of n'} of a chained run's results (its tasks in the order played)."""
    by_episode: dict = {}
    for r in results:
        if r.protocol == 'chained':
            by_episode.setdefault(r.episode_id, []).append(r.task_id)
    return {tid: f'episode {e}, task {k} of {len(ids)}' for e, ids in by_episode.items()
            for k, tid in enumerate(sorted(ids), start=1)}


def episode_view(ep, place: str = '') -> dict:
    """What the page shows of one episode (`ep`: a report.EpisodeView); `place`: where a chained task stands in
    its episode."""
    r = ep.result
    facts = ([place] if place else []) + [f'{r.steps} steps (expert {r.expert_length})',
             f'goal conditions {r.goal_conditions_met}/{r.goal_conditions_total}',
             f'{r.questions} question{"s" if r.questions != 1 else ""}'
             + (f' ({r.invalid_questions} unanswerable)' if r.invalid_questions else ''),
             f'{r.failed_actions} failed action{"s" if r.failed_actions != 1 else ""}']
    return dict(r=r, outcome='success' if r.success else 'failure', anchor=r.task_id.replace('/', '_'), gif=ep.gif,
                media_note=ep.media_note or 'no recording', scene=ep.scene, instruction=ep.instruction,
                outcome_label=outcome_label(r), facts=' · '.join(facts))


def chained_line(episodes: Optional[dict]) -> str:
    """The per-episode figures of a chained run (metrics.summarize's 'episodes'), as a sentence; '' otherwise."""
    if not episodes:
        return ''
    e = episodes
    return (f'Chained (DialFRED\'s challenge test): {e["episodes"]} episodes of {e["tasks_per_episode"]:.2f} tasks, each '
            f'task on the state the agent\'s own actions left; every task done in {e["all_succeeded"]:.1f}% of them, '
            f'{e["in_order"]:.2f} tasks done in order before the first failure, {e["questions_per_episode"]:.2f} '
            f'questions an episode; {e["held_at_start"]} tasks held at start (scored as not done).')


def render_page(report) -> str:
    """The whole page of a report.Report, as text."""
    summary = report.summary
    overall = summary['overall']
    places = chained_places(ep.result for ep in report.episodes)
    chart_rows = [('overall', overall['n'], overall['SR'], report.bounds['SR'], '')]
    chart_rows += [(t, row['n'], row['SR'], report.type_bounds[t], t) for t, row in summary['per_type'].items()]
    end_reasons = summary['end_reasons']
    per_type = [(t, dict(n=r['n'], SR=f'{r["SR"]:.1f}', PWSR=f'{r["PWSR"]:.1f}', GC=f'{r["GC"]:.1f}', NQ=f'{r["NQ"]:.2f}'))
                for t, r in summary['per_type'].items()]
    return environment().get_template('report.html.j2').render(
        report=report, overall=overall, cards=cards(overall, report.bounds), nq_invalid=f'{overall["NQ_invalid"]:.2f}',
        reasons=', '.join(f'{esc(r)} {end_reasons[r]}' for r in END_REASONS if r in end_reasons),
        sr_chart=sr_chart(chart_rows), per_type=per_type, total=len(report.episodes),
        episodes=[episode_view(ep, places.get(ep.result.task_id, '')) for ep in report.episodes],
        chained=chained_line(summary.get('episodes')),
        style=(TEMPLATES / 'report.css').read_text(), script=(TEMPLATES / 'report.js').read_text())
