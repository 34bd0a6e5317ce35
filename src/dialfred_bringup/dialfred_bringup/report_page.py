"""The HTML of an evaluation report (no ROS): one static page, its style, its SVG chart and its script.

`render_page(report)` turns a `report.Report` into the text of a page that works opened from disk:
no server, no network (no CDN, fonts or scripts from elsewhere). Everything shown is escaped here.
The page's filters are plain JavaScript over `data-*` attributes of each episode; their state is
kept in the address's fragment (`page.html#type=Clean&outcome=failure:stop`), so a filtered view
can be linked to.
"""

from __future__ import annotations

import html
from typing import Sequence

from dialfred_sim.metrics import END_REASONS

OUTCOME_LABELS = {'stop': 'the agent stopped', 'max_steps': 'step limit', 'max_failures': 'too many failed actions',
                  'error': 'error'}


def esc(value) -> str:
    return html.escape(str(value), quote=True)


def outcome_label(result) -> str:
    """'success' or 'failure (why)'."""
    return 'success' if result.success else f'failure ({OUTCOME_LABELS.get(result.end_reason, result.end_reason)})'


def interval_text(lo: float, hi: float, digits: int = 1) -> str:
    return f'[{lo:.{digits}f}, {hi:.{digits}f}]'


# ------------------------------------------------------------------------------------------------ chart

BAR_ROW, LABEL_W, PLOT_W, VALUE_W, TOP = 22, 190, 460, 170, 26


def sr_chart(rows: Sequence[tuple], title: str = 'SR per task type (%), with 95% intervals') -> str:
    """An inline SVG of horizontal bars: `rows` are (label, n, SR, (lo, hi), filter value or '').
    A row with a filter value is clickable (the script filters the episodes by that task type)."""
    width = LABEL_W + PLOT_W + VALUE_W
    height = TOP + BAR_ROW * len(rows) + 24
    x = lambda pct: LABEL_W + PLOT_W * max(0.0, min(100.0, pct)) / 100.0
    parts = [f'<svg class="chart" role="img" aria-label="{esc(title)}" viewBox="0 0 {width} {height}" '
             f'width="{width}" height="{height}" xmlns="http://www.w3.org/2000/svg">',
             f'<title>{esc(title)}</title>']
    bottom = TOP + BAR_ROW * len(rows)
    for pct in (0, 25, 50, 75, 100):
        parts.append(f'<line class="grid" x1="{x(pct):.1f}" y1="{TOP - 4}" x2="{x(pct):.1f}" y2="{bottom}"/>'
                     f'<text class="tick" x="{x(pct):.1f}" y="{bottom + 16}" text-anchor="middle">{pct}</text>')
    for k, (label, n, sr, (lo, hi), filter_type) in enumerate(rows):
        y = TOP + BAR_ROW * k
        attrs = f' data-filter-type="{esc(filter_type)}" tabindex="0"' if filter_type else ''
        parts.append(
            f'<g class="bar-row{" overall" if not filter_type else ""}"{attrs}>'
            f'<title>{esc(label)}: SR {sr:.1f}% {interval_text(lo, hi)} over {n} episodes</title>'
            f'<rect class="hit" x="0" y="{y}" width="{width}" height="{BAR_ROW}"/>'
            f'<text class="label" x="{LABEL_W - 8}" y="{y + 15}" text-anchor="end">{esc(label)}</text>'
            f'<rect class="bar" x="{LABEL_W}" y="{y + 4}" width="{x(sr) - LABEL_W:.1f}" height="{BAR_ROW - 8}"/>'
            f'<line class="ci" x1="{x(lo):.1f}" y1="{y + BAR_ROW / 2}" x2="{x(hi):.1f}" y2="{y + BAR_ROW / 2}"/>'
            f'<line class="ci" x1="{x(lo):.1f}" y1="{y + 7}" x2="{x(lo):.1f}" y2="{y + BAR_ROW - 7}"/>'
            f'<line class="ci" x1="{x(hi):.1f}" y1="{y + 7}" x2="{x(hi):.1f}" y2="{y + BAR_ROW - 7}"/>'
            f'<text class="value" x="{LABEL_W + PLOT_W + 8}" y="{y + 15}">{sr:.1f} {interval_text(lo, hi, 0)}'
            f' n={n}</text></g>')
    parts.append(f'<text class="tick" x="{LABEL_W}" y="{TOP - 10}">SR %</text></svg>')
    return ''.join(parts)


# ------------------------------------------------------------------------------------------------ parts

def settings_html(settings: Sequence[tuple[str, str]]) -> str:
    return '<dl class="settings">' + ''.join(f'<dt>{esc(k)}</dt><dd>{esc(v)}</dd>' for k, v in settings) + '</dl>'


def summary_html(overall: dict, bounds: dict, end_reasons: dict) -> str:
    cards = []
    for key, unit, digits, what in (('SR', '%', 1, 'success rate'), ('PWSR', '%', 1, 'path-weighted success'),
                                    ('GC', '%', 1, 'goal conditions met'), ('NQ', '', 2, 'questions per episode')):
        lo, hi = bounds[key]
        cards.append(f'<div class="card" data-metric="{key}"><div class="metric">{key}</div>'
                     f'<div class="number">{overall[key]:.{digits}f}{unit}</div>'
                     f'<div class="interval">95% {interval_text(lo, hi, digits)}</div>'
                     f'<div class="what">{esc(what)}</div></div>')
    reasons = ', '.join(f'{esc(r)} {end_reasons[r]}' for r in END_REASONS if r in end_reasons)
    return (f'<div class="cards">{"".join(cards)}</div>'
            f'<p class="note">{overall["n"]} episodes; questions the oracle could not answer: '
            f'{overall["NQ_invalid"]:.2f} per episode; how episodes ended: {reasons or "-"}.</p>')


def per_type_table(per_type: dict) -> str:
    head = '<tr><th>task type</th><th>n</th><th>SR</th><th>PWSR</th><th>GC</th><th>NQ</th></tr>'
    body = ''.join(f'<tr><td>{esc(t)}</td><td>{r["n"]}</td><td>{r["SR"]:.1f}</td><td>{r["PWSR"]:.1f}</td>'
                   f'<td>{r["GC"]:.1f}</td><td>{r["NQ"]:.2f}</td></tr>' for t, r in per_type.items())
    return f'<table class="per-type">{head}{body}</table>'


def dialogue_html(dialogue: Sequence[dict]) -> str:
    if not dialogue:
        return '<p class="no-dialogue">no questions</p>'
    items = []
    for qa in dialogue:
        about = f' ({esc(qa.get("noun"))})' if qa.get('noun') else ''
        answer = (esc(qa.get('answer', '')) if qa.get('valid')
                  else '<span class="invalid">the oracle could not answer</span>')
        items.append(f'<li><span class="qtype">{esc(qa.get("type", "?"))}</span>{about} &rarr; {answer}</li>')
    return f'<ol class="dialogue">{"".join(items)}</ol>'


def episode_html(ep) -> str:
    """One episode's block (`ep`: a report.EpisodeView)."""
    r = ep.result
    outcome = 'success' if r.success else 'failure'
    media = (f'<img class="gif" loading="lazy" src="{esc(ep.gif)}" alt="{esc(r.task_id)}: the recorded episode">'
             if ep.gif else f'<div class="no-gif">{esc(ep.media_note or "no recording")}</div>')
    facts = [f'{r.steps} steps (expert {r.expert_length})',
             f'goal conditions {r.goal_conditions_met}/{r.goal_conditions_total}',
             f'{r.questions} question{"s" if r.questions != 1 else ""}'
             + (f' ({r.invalid_questions} unanswerable)' if r.invalid_questions else ''),
             f'{r.failed_actions} failed action{"s" if r.failed_actions != 1 else ""}']
    error = f'<p class="error">{esc(r.error)}</p>' if r.error and not r.success else ''
    instruction = f'<p class="instruction">&ldquo;{esc(ep.instruction)}&rdquo;</p>' if ep.instruction else ''
    scene = f' <span class="scene">{esc(ep.scene)}</span>' if ep.scene else ''
    return (f'<article class="episode {outcome}" id="{esc(r.task_id.replace("/", "_"))}" data-type="{esc(r.task_type)}" '
            f'data-outcome="{outcome}" data-reason="{esc(r.end_reason)}">'
            f'<div class="media">{media}</div><div class="body">'
            f'<h3><span class="task-id">{esc(r.task_id)}</span> <span class="type">{esc(r.task_type)}</span>{scene}</h3>'
            f'<p class="outcome {outcome}">{esc(outcome_label(r))}</p>{instruction}'
            f'<p class="facts">{esc(" · ".join(facts))}</p>{error}{dialogue_html(r.dialogue)}</div></article>')


def filters_html(type_counts: dict, outcome_counts: dict, total: int) -> str:
    types = ''.join(f'<option value="{esc(t)}">{esc(t)} ({n})</option>' for t, n in type_counts.items())
    outcomes = ''.join(f'<option value="{esc(value)}">{esc(label)} ({n})</option>'
                       for value, (label, n) in outcome_counts.items())
    return (f'<div class="filters" role="search"><label>task type <select id="filter-type">'
            f'<option value="all">all types ({total})</option>{types}</select></label> '
            f'<label>outcome <select id="filter-outcome"><option value="all">all outcomes ({total})</option>'
            f'{outcomes}</select></label> <button type="button" id="filter-reset">show all</button> '
            f'<span class="count">showing <b id="shown-count">{total}</b> of {total} episodes</span></div>'
            f'<p id="none-shown" hidden>No episode matches these filters.</p>')


# ------------------------------------------------------------------------------------------------ page

STYLE = """
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;color:#1d232a;background:#f5f6f8}
main{max-width:1160px;margin:0 auto;padding:16px 20px 40px}
h1{font-size:22px;margin:8px 0 4px}h2{font-size:17px;margin:26px 0 8px}
.sub{color:#59636e;margin:0 0 10px}
.warnings{background:#fff4d6;border:1px solid #e6c760;padding:8px 12px;border-radius:6px}
.settings{display:grid;grid-template-columns:max-content 1fr;gap:2px 16px;background:#fff;padding:10px 14px;
border-radius:6px;border:1px solid #dde1e6;margin:0}
.settings dt{color:#59636e}.settings dd{margin:0;font-family:ui-monospace,monospace;word-break:break-all}
.cards{display:flex;gap:12px;flex-wrap:wrap}
.card{background:#fff;border:1px solid #dde1e6;border-radius:6px;padding:10px 16px;min-width:150px}
.card .metric{font-weight:600;color:#3a4550}.card .number{font-size:26px;font-weight:600}
.card .interval,.card .what,.note{color:#59636e;font-size:13px}
.chart{max-width:100%;height:auto;background:#fff;border:1px solid #dde1e6;border-radius:6px}
.chart .grid{stroke:#e3e6ea}.chart .tick{fill:#59636e;font-size:11px}
.chart .label,.chart .value{fill:#1d232a;font-size:12px}
.chart .bar{fill:#4c78a8}.chart .overall .bar{fill:#2f4b6e}.chart .ci{stroke:#1d232a;stroke-width:1.3}
.chart .hit{fill:transparent}.chart [data-filter-type]{cursor:pointer}
.chart [data-filter-type]:hover .hit,.chart [data-filter-type]:focus .hit{fill:#eef3fa}
details{margin-top:8px}.per-type{border-collapse:collapse;background:#fff}
.per-type td,.per-type th{border:1px solid #dde1e6;padding:2px 10px;text-align:right}
.per-type td:first-child,.per-type th:first-child{text-align:left}
.filters{position:sticky;top:0;z-index:1;background:#f5f6f8;padding:8px 0;border-bottom:1px solid #dde1e6}
.filters label{margin-right:10px}.filters select{font:inherit}.count{margin-left:10px}
.episode{display:flex;gap:14px;background:#fff;border:1px solid #dde1e6;border-left:5px solid #b8c0c8;
border-radius:6px;padding:10px;margin:10px 0}
.episode.success{border-left-color:#2e8540}.episode.failure{border-left-color:#c0392b}
.episode[hidden]{display:none}
.media{flex:0 0 auto;width:256px}.gif{width:256px;height:auto;image-rendering:auto;display:block}
.no-gif{width:256px;height:120px;display:flex;align-items:center;justify-content:center;text-align:center;
background:#eceff2;color:#59636e;border-radius:4px;font-size:13px;padding:6px;box-sizing:border-box}
.body{flex:1;min-width:0}.body h3{margin:0 0 4px;font-size:15px}
.task-id{font-family:ui-monospace,monospace}.type{background:#e8eef6;border-radius:4px;padding:1px 6px;font-weight:500}
.scene{color:#59636e;font-weight:400;font-size:13px}
.outcome{margin:2px 0;font-weight:600}.outcome.success{color:#2e8540}.outcome.failure{color:#c0392b}
.instruction{margin:2px 0;font-style:italic}.facts{margin:2px 0;color:#3a4550}
.error{margin:2px 0;color:#8a2b20;font-family:ui-monospace,monospace;font-size:12px}
.dialogue{margin:4px 0;padding-left:22px}.qtype{font-weight:600}.invalid{color:#8a2b20}
.no-dialogue{margin:4px 0;color:#59636e}
@media (max-width:700px){.episode{flex-direction:column}.filters{position:static}}
"""

SCRIPT = """
(function () {
  'use strict';
  var typeSelect = document.getElementById('filter-type');
  var outcomeSelect = document.getElementById('filter-outcome');
  var shownCount = document.getElementById('shown-count');
  var noneShown = document.getElementById('none-shown');
  var episodes = Array.prototype.slice.call(document.querySelectorAll('article.episode'));

  function matches(episode, type, outcome) {
    if (type !== 'all' && episode.dataset.type !== type) { return false; }
    if (outcome === 'all') { return true; }
    if (outcome === 'success' || outcome === 'failure') { return episode.dataset.outcome === outcome; }
    return episode.dataset.outcome === 'failure' && 'failure:' + episode.dataset.reason === outcome;
  }

  function hasOption(select, value) {
    return Array.prototype.some.call(select.options, function (o) { return o.value === value; });
  }

  function apply() {
    var type = typeSelect.value, outcome = outcomeSelect.value, shown = 0;
    episodes.forEach(function (episode) {
      var show = matches(episode, type, outcome);
      episode.hidden = !show;
      if (show) { shown += 1; }
    });
    shownCount.textContent = String(shown);
    noneShown.hidden = shown !== 0;
    var params = new URLSearchParams();
    if (type !== 'all') { params.set('type', type); }
    if (outcome !== 'all') { params.set('outcome', outcome); }
    var fragment = params.toString();
    if (fragment !== location.hash.replace(/^#/, '')) {
      try { history.replaceState(null, '', fragment ? '#' + fragment : location.pathname + location.search); }
      catch (e) { /* some browsers refuse history on file: pages; the filter still works */ }
    }
  }

  function fromFragment() {
    var params = new URLSearchParams(location.hash.replace(/^#/, ''));
    var type = params.get('type') || 'all', outcome = params.get('outcome') || 'all';
    typeSelect.value = hasOption(typeSelect, type) ? type : 'all';
    outcomeSelect.value = hasOption(outcomeSelect, outcome) ? outcome : 'all';
  }

  function filterType(type) {
    typeSelect.value = hasOption(typeSelect, type) ? type : 'all';
    apply();
    document.getElementById('episodes').scrollIntoView();
  }

  typeSelect.addEventListener('change', apply);
  outcomeSelect.addEventListener('change', apply);
  document.getElementById('filter-reset').addEventListener('click', function () {
    typeSelect.value = 'all';
    outcomeSelect.value = 'all';
    apply();
  });
  Array.prototype.forEach.call(document.querySelectorAll('[data-filter-type]'), function (row) {
    row.addEventListener('click', function () { filterType(row.dataset.filterType); });
    row.addEventListener('keydown', function (event) {
      if (event.key === 'Enter' || event.key === ' ') { event.preventDefault(); filterType(row.dataset.filterType); }
    });
  });
  window.addEventListener('hashchange', function () { fromFragment(); apply(); });
  fromFragment();
  apply();
  document.body.dataset.ready = 'true';
})();
"""


def render_page(report) -> str:
    """The whole page of a report.Report, as text."""
    summary = report.summary
    chart_rows = [('overall', summary['overall']['n'], summary['overall']['SR'], report.bounds['SR'], '')]
    chart_rows += [(t, row['n'], row['SR'], report.type_bounds[t], t) for t, row in summary['per_type'].items()]
    warnings = ''.join(f'<li>{esc(w)}</li>' for w in report.warnings)
    warnings = f'<ul class="warnings">{warnings}</ul>' if warnings else ''
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{esc(report.title)}</title>
<link rel="icon" href="data:,">
<style>{STYLE}</style>
</head>
<body>
<main>
<h1>{esc(report.title)}</h1>
<p class="sub">{esc(report.subtitle)}</p>
{warnings}
<h2>Run</h2>
{settings_html(report.settings)}
<h2>Summary</h2>
{summary_html(summary['overall'], report.bounds, summary['end_reasons'])}
<h2>Success rate per task type</h2>
{sr_chart(chart_rows)}
<p class="note">Bars: SR; whiskers: 95% percentile-bootstrap intervals ({report.resamples} resamples, seed {report.seed}).
Click a task type to show its episodes.</p>
<details><summary>the table (SR, PWSR, GC in %, NQ per episode)</summary>{per_type_table(summary['per_type'])}</details>
<h2 id="episodes">Episodes</h2>
{filters_html(report.type_counts, report.outcome_counts, len(report.episodes))}
<div id="episode-list">
{chr(10).join(episode_html(ep) for ep in report.episodes)}
</div>
</main>
<script>{SCRIPT}</script>
</body>
</html>
"""
