"""`./dialfred report RESULTS.jsonl`: one static HTML page of an evaluation (dialfred_bringup.report).

Most tests use SYNTHETIC results (made-up episodes of made-up tasks, `synthetic/00000k`) and SYNTHETIC
bags (random frames written with the EpisodeRecorder); one plays a real 3-task evaluation with
recording and reports it.

Claims: the page shows the run's settings, SR/PWSR/GC/NQ with the 95% bootstrap intervals of
metrics.intervals, a bar per task type whose length is its SR, and every episode with its type,
outcome, steps, dialogue and the GIF rendered from its bag (an episode without a bag says "no
recording", one whose bag cannot be read says why; both are reported on stderr); it names nothing
outside itself and its media folder; a missing, empty or corrupt results file is an error (exit 2)
that writes no page, a cut-off last line is skipped with a warning.
In a real headless chromium, the page renders (the screenshot is not blank), reports no error, and its
filters by task type and outcome show the right episodes and count; the same checks catch a broken
script, a console error and a GIF that does not load.
"""

from __future__ import annotations

import dataclasses

import html
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from dialfred_sim.metrics import EpisodeResult, append_result, dialogue_entry, intervals, summarize
from dialfred_sim.bag import EpisodeRecorder, bag_name
from dialfred_bringup.report import build_report, main as report_main
from headless_browser import Browser, blank_fraction, chromium_path, pixel_std, screenshot_cli

REPO = Path(__file__).resolve().parents[2]

needs_chromium = pytest.mark.skipif(
    chromium_path() is None, reason='no chromium on PATH: `./dialfred setup` installs it as root with apt-get '
                                    '(DIALFRED_NO_APT unset), or run `apt-get install chromium`')


# ------------------------------------------------------------------------------------------ synthetic data

def synthetic_results() -> list[EpisodeResult]:
    """SYNTHETIC: eight episodes of three task types, with every way an episode can end."""
    def ep(k, task_type, success, end_reason, steps, questions=(), error=''):
        dialogue = [dialogue_entry(t, noun, valid, answer) for t, noun, valid, answer in questions]
        return EpisodeResult(task_id=f'synthetic/{k:06d}', task_type=task_type, split='synthetic', success=success,
                             goal_conditions_met=1 if success else 0, goal_conditions_total=1, steps=steps,
                             expert_length=5, questions=len(dialogue), invalid_questions=sum(not q[2] for q in questions),
                             failed_actions=0 if success else 2, end_reason=end_reason, error=error,
                             agent='et-0123abcd+all', seed=3, dialogue=dialogue)
    loc = ('location', 'apple', True, 'The apple is on the counter.')
    return [
        ep(0, 'Clean', True, 'success', 5, [loc, ('direction', '', True, 'Turn left.')]),
        ep(1, 'Clean', False, 'stop', 9, [('appearance', 'unicorn', False, '')], 'Pickup: nothing there'),
        ep(2, 'Clean', False, 'max_failures', 14, error='MoveAhead blocked by Sofa_0'),
        ep(3, 'Put', True, 'success', 10),
        ep(4, 'Put', False, 'max_steps', 1000, [loc]),
        ep(5, 'Move & Pick', True, 'success', 5, [('location', 'mug', True, 'It is <b>"here"</b> & there')]),
        ep(6, 'Move & Pick', False, 'error', 3, error='the sim node did not answer'),
        ep(7, 'Move & Pick', True, 'success', 7),
    ]


SUMMARY = {'split': 'synthetic', 'tasks_file': None, 'agent': 'et-0123abcd+all', 'privileged': False, 'oracle': '',
           'seed': 3, 'resolution': 64, 'workers': 2, 'through': 'performer node',
           'checkpoint': {'path': '/x/et.pt', 'sha256': '0123abcd' + 'f' * 56}, 'limit': None, 'shard': None,
           'tasks': 8}


def write_results(folder: Path, results=None, summary=True) -> Path:
    path = folder / 'run.jsonl'
    for r in results if results is not None else synthetic_results():
        append_result(path, r)
    if summary:
        path.with_suffix('.summary.json').write_text(json.dumps(SUMMARY))
    return path


def write_bag(folder: Path, result: EpisodeResult, seed: int = 0) -> Path:
    """SYNTHETIC: a bag of `result`'s episode with 48x64 frames of random colour blocks (few colours, as a
    rendered room has: noise would make the GIF's palette the cost of the test), its actions and dialogue."""
    rng = np.random.default_rng(seed)
    frame = lambda: rng.integers(0, 256, (4, 4, 3), dtype=np.uint8).repeat(12, axis=0).repeat(16, axis=1)
    rec = EpisodeRecorder(result.task_id, 'FloorPlan1', result.split, f'Do task {result.task_id}.', ['apple'])
    rec.observation(0, frame(), (0.0, 0.0, 0.0, 30.0), 1.5)
    for qa in result.dialogue:
        rec.question(0, qa['type'], qa['noun'], 'What?', qa['answer'], qa['valid'])
    steps = min(result.steps, 6)
    for k in range(1, steps + 1):
        rec.action(k, 'MoveAhead', -1, -1, True, result.questions)
        rec.observation(k, frame(), (0.25 * k, 0.0, 0.0, 30.0), 1.5)
    rec.result(success=result.success, steps=result.steps, end_reason=result.end_reason, questions=result.questions,
               failed_actions=result.failed_actions)
    return rec.save(folder)


def episode_block(page: str, task_id: str) -> str:
    start = page.index(f'id="{task_id.replace("/", "_")}"')
    return page[start:page.index('</article>', start)]


@pytest.fixture
def run(tmp_path):
    """A synthetic results file (with its summary) and a bags folder holding bags for all but two of
    its episodes (synthetic/000003 has none; synthetic/000004's is cut off)."""
    results = synthetic_results()
    path = write_results(tmp_path)
    bags = tmp_path / 'bags'
    for k, r in enumerate(results):
        if r.task_id != 'synthetic/000003':
            write_bag(bags, r, seed=k)
    (mcap,) = (bags / 'synthetic_000004').glob('*.mcap')
    mcap.write_bytes(mcap.read_bytes()[:200])
    return path, bags, results


# ------------------------------------------------------------------------------------------ the page

def test_the_page_shows_the_settings_and_the_summary_with_its_bootstrap_intervals(run):
    path, bags, results = run
    page_path, report, _ = build_report(path, bags)
    assert page_path == path.with_suffix('.html')
    page = page_path.read_text()
    for label, value in (('split', 'synthetic'), ('agent', 'et-0123abcd'), ('questioner', 'all'),
                         ('oracle', 'exact answers'), ('seed', '3'), ('tasks', '8'),
                         ('checkpoint', 'sha256 0123abcd' + 'f' * 56)):
        assert f'<dt>{label}</dt><dd>{value}' in page, label
    assert '<h1>DialFRED evaluation: et-0123abcd+all on synthetic</h1>' in page
    summary, bounds = summarize(results), intervals(results)
    assert report.summary == summary and report.bounds == bounds
    for key, digits, unit in (('SR', 1, '%'), ('PWSR', 1, '%'), ('GC', 1, '%'), ('NQ', 2, '')):
        lo, hi = bounds[key]
        card = re.search(rf'<div class="card" data-metric="{key}">(.*?)</div></div>', page).group(1)
        assert f'{summary["overall"][key]:.{digits}f}{unit}' in card
        assert f'95% [{lo:.{digits}f}, {hi:.{digits}f}]' in card
    assert 'success 4, stop 1, max_steps 1, max_failures 1, error 1' in page


def test_sr_per_task_type_is_a_bar_as_long_as_its_sr_in_the_papers_order(run):
    path, bags, results = run
    page = build_report(path)[0].read_text()
    svg = page[page.index('<svg class="chart"'):page.index('</svg>')]
    rows = re.findall(r'<g class="bar-row[^"]*"(?: data-filter-type="([^"]*)")?.*?<text class="label"[^>]*>([^<]*)'
                      r'</text><rect class="bar" x="(\d+)" y="[\d.]+" width="([\d.]+)"', svg)
    assert [label for _, label, _, _ in rows] == ['overall', 'Clean', 'Put', 'Move &amp; Pick']
    widths = {label: float(w) for _, label, _, w in rows}
    full = 460.0  # report_page.PLOT_W: 100%
    per_type = summarize(results)['per_type']
    assert widths['Clean'] == pytest.approx(full * per_type['Clean']['SR'] / 100, abs=0.1)
    assert widths['Put'] == pytest.approx(full / 2, abs=0.1) and widths['overall'] == pytest.approx(full / 2, abs=0.1)
    assert [t for t, _, _, _ in rows] == ['', 'Clean', 'Put', 'Move &amp; Pick']   # bars of a type filter on click


def test_every_episode_shows_its_type_outcome_steps_dialogue_and_escaped_text(run):
    path, bags, results = run
    page = build_report(path, bags)[0].read_text()
    assert page.count('<article class="episode') == len(results)
    first = episode_block(page, 'synthetic/000000')
    assert 'data-type="Clean" data-outcome="success" data-reason="success"' in first
    assert '>success</p>' in first and '5 steps (expert 5)' in first and '2 questions' in first
    assert ('<li><span class="qtype">location</span> (apple) &rarr; The apple is on the counter.</li>'
            '<li><span class="qtype">direction</span> &rarr; Turn left.</li>') in first
    stopped = episode_block(page, 'synthetic/000001')
    assert 'failure (the agent stopped)' in stopped and 'Pickup: nothing there' in stopped
    assert 'the oracle could not answer' in stopped and '1 unanswerable' in stopped
    assert 'failure (too many failed actions)' in episode_block(page, 'synthetic/000002')
    assert 'failure (step limit)' in episode_block(page, 'synthetic/000004')
    assert 'no questions' in episode_block(page, 'synthetic/000003')
    # what the results say is text, never markup
    assert 'It is &lt;b&gt;&quot;here&quot;&lt;/b&gt; &amp; there' in episode_block(page, 'synthetic/000005')
    assert '<b>"here"</b>' not in page
    # the filters offer each type and each outcome present, with counts
    assert '<option value="Move &amp; Pick">Move &amp; Pick (3)</option>' in page
    assert '<option value="failure:max_failures">failure: too many failed actions (1)</option>' in page
    assert 'showing <b id="shown-count">8</b> of 8 episodes' in page


def test_each_recorded_episode_gets_its_gif_and_a_missing_or_unreadable_bag_is_said(run, capsys):
    path, bags, results = run
    assert report_main([str(path), '--bags', str(bags)]) == 0
    out, err = capsys.readouterr()
    page = path.with_suffix('.html').read_text()
    media = path.parent / 'run_media'
    from PIL import Image
    for r in results:
        block = episode_block(page, r.task_id)
        if r.task_id == 'synthetic/000003':
            assert '<div class="no-gif">no recording</div>' in block and '<img' not in block
        elif r.task_id == 'synthetic/000004':
            assert 'recording unreadable' in block and '<img' not in block
        else:
            gif = media / f'{bag_name(r.task_id)}.gif'
            assert f'src="run_media/{gif.name}"' in block
            with Image.open(gif) as img:       # the start, each question, each action (film)
                assert img.n_frames == 1 + len(r.dialogue) + min(r.steps, 6) and img.size[0] == 256
            assert f'Do task {r.task_id}.' in block     # the instruction, from the bag
    assert '1 of 8 episodes have no bag' in err
    assert 'synthetic_000004: recording unreadable' in err and 'shown without a GIF' in err
    assert re.search(r'GIFs: 7/7', err)
    assert '6 GIFs, 1 without a bag, 1 unreadable bags, 0 bags of another run' in out


def test_a_bag_of_another_runs_episode_of_the_same_task_gets_no_gif_and_is_said(run, capsys):
    """Bags are named by task: a run recorded into a folder that holds another run's bags would show that
    run's GIFs beside this run's episodes. A bag whose recorded outcome or dialogue is not the results line's
    is flagged instead."""
    path, bags, results = run
    other = dataclasses.replace(results[0], steps=results[0].steps + 3, success=not results[0].success)
    write_bag(bags, other, seed=99)                       # replaces synthetic/000000's bag with another episode's
    assert report_main([str(path), '--bags', str(bags)]) == 0
    out, err = capsys.readouterr()
    block = episode_block(path.with_suffix('.html').read_text(), results[0].task_id)
    assert 'the recording is of another episode of this task (success, steps differ' in block and '<img' not in block
    assert 'another run recorded into that folder' in err
    assert '5 GIFs, 1 without a bag, 1 unreadable bags, 1 bags of another run' in out


def test_without_bags_every_episode_says_no_recording_and_no_media_folder_is_made(run):
    path, _, results = run
    page = build_report(path)[0].read_text()
    assert page.count('<div class="no-gif">no recording</div>') == len(results)
    assert '<img' not in page and not (path.parent / 'run_media').exists()


def test_embedded_gifs_make_one_self_contained_file(run, tmp_path):
    path, bags, _ = run
    out = tmp_path / 'elsewhere' / 'one.html'
    page = build_report(path, bags, out=out, embed=True)[0].read_text()
    assert page.count('src="data:image/gif;base64,R0lGOD') == 6     # 'GIF8' in base64
    assert not (out.parent / 'one_media').exists() and not (path.parent / 'run_media').exists()


def test_the_page_names_nothing_outside_itself_and_its_media(run):
    path, bags, _ = run
    page = build_report(path, bags, workers=2)[0].read_text()
    addresses = re.findall(r'(?:src|href)="([^"]*)"', page)
    assert addresses and all(a.startswith(('data:', 'run_media/')) for a in addresses), addresses
    assert all((path.parent / a).is_file() for a in addresses if not a.startswith('data:'))
    assert not re.search(r'https?://(?!www\.w3\.org/2000/svg)', page)     # no CDN, font or script from elsewhere
    assert '@import' not in page and 'url(' not in page


def test_a_second_report_gives_the_same_page(run):
    path, bags, _ = run
    first = build_report(path, bags)[0].read_text()
    assert build_report(path, bags, workers=2)[0].read_text() == first


# ------------------------------------------------------------------------------------------ bad input

def test_a_missing_results_file_is_exit_2_with_a_message_and_no_page(tmp_path, capsys):
    assert report_main([str(tmp_path / 'none.jsonl'), '--out', str(tmp_path / 'p.html')]) == 2
    assert 'no results file' in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize('content, message', [(b'', 'holds no episode results'),
                                              (b'{"task_id": "x"', 'holds no episode results')])
def test_an_empty_results_file_is_exit_2_and_no_page(tmp_path, capsys, content, message):
    path = tmp_path / 'r.jsonl'
    path.write_bytes(content)
    assert report_main([str(path)]) == 2
    assert message in capsys.readouterr().err
    assert not path.with_suffix('.html').exists()


def test_malformed_lines_are_said_and_skipped_and_the_others_reported(tmp_path, capsys):
    path = tmp_path / 'r.jsonl'
    lines = [r.to_json() for r in synthetic_results()]
    odd_dialogue = json.loads(lines[3])
    odd_dialogue['dialogue'] = ['where is it?', 7]                  # entries that are not objects
    path.write_text('\n'.join(lines[:2] + ['{"task_id": 7}'] + lines[2:3] + [json.dumps(odd_dialogue)]
                              + lines[4:]) + '\n')
    before = path.read_bytes()
    assert report_main([str(path)]) == 0
    err = capsys.readouterr().err
    assert err.count('skipped 1 malformed line') == 2 and ':3:' in err and ':5:' in err and 'a dialogue entry is' in err
    assert path.with_suffix('.html').read_text().count('<article class="episode') == len(lines) - 1
    assert path.read_bytes() == before                               # the report only reads its input


@pytest.mark.parametrize('name, out', [('run.html', None), ('r.jsonl', 'r.jsonl'), ('r.jsonl', 'r.summary.json')])
def test_the_page_is_never_written_over_an_input(tmp_path, capsys, name, out):
    path = write_results(tmp_path)
    if name != path.name:
        path = path.rename(tmp_path / name)
    summary = path.with_suffix('.summary.json')
    inputs = {p: p.read_bytes() for p in (path, summary) if p.exists()}
    assert report_main([str(path)] + (['--out', str(tmp_path / out)] if out else [])) == 2
    assert 'would be written over an input' in capsys.readouterr().err
    assert {p: p.read_bytes() for p in inputs} == inputs


def test_a_cut_off_last_line_is_skipped_with_a_warning_on_stderr_and_on_the_page(tmp_path, capsys):
    path = write_results(tmp_path)
    path.write_bytes(path.read_bytes() + synthetic_results()[0].to_json().encode()[:40])
    assert report_main([str(path)]) == 0
    err = capsys.readouterr().err
    assert 'warning' in err and 'truncated final line' in err
    page = path.with_suffix('.html').read_text()
    assert '<ul class="warnings">' in page and 'truncated final line' in page
    assert page.count('<article class="episode') == 8


def test_a_bags_argument_that_is_no_folder_is_exit_2(run, capsys):
    path, _, _ = run
    assert report_main([str(path), '--bags', str(path.parent / 'nowhere')]) == 2
    assert 'is not a folder' in capsys.readouterr().err and not path.with_suffix('.html').exists()


def test_without_a_summary_file_the_settings_come_from_the_results(tmp_path):
    path = write_results(tmp_path, summary=False)
    page, report, _ = build_report(path)
    assert ('agent', 'et-0123abcd') in report.settings and ('seed', '3') in report.settings
    assert ('checkpoint', 'sha256 0123abcd... (from the agent name)') in report.settings
    assert 'no run.summary.json beside the results' in page.read_text()


def test_a_perturbed_oracle_is_named_with_what_it_withholds(tmp_path):
    path = write_results(tmp_path)
    path.with_suffix('.summary.json').write_text(json.dumps({**SUMMARY, 'oracle': 'location:0.5'}))
    assert ('oracle', 'withholds location answers with probability 0.5') in build_report(path)[1].settings


def test_a_summary_of_another_run_is_flagged(tmp_path):
    path = write_results(tmp_path)
    path.with_suffix('.summary.json').write_text(json.dumps({**SUMMARY, 'tasks': 99, 'agent': 'random'}))
    text = build_report(path)[0].read_text()
    assert 'the summary file counts 99 tasks, the results file holds 8' in text
    assert 'the summary file names agent random' in text


@pytest.mark.slow   # ./dialfred report as a subprocess; fast: build_report and the page tests
def test_the_dialfred_entry_point_runs_the_report_in_the_callers_directory(run):
    path, bags, _ = run
    proc = subprocess.run([str(REPO / 'dialfred'), 'report', path.name, '--bags', bags.name, '--out', 'page.html'],
                          cwd=path.parent, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (path.parent / 'page.html').is_file() and (path.parent / 'page_media').is_dir()
    assert 'page.html: 8 episodes' in proc.stdout


# ------------------------------------------------------------------------------------------ a real run

def test_a_recorded_evaluation_is_reported_with_its_gifs_and_instructions(tmp_path):
    from dialfred_bringup.evaluation import EvalConfig, run_eval
    from dialfred_sim.tasks.split_files import get_task
    report = run_eval(EvalConfig(split='valid_unseen', agent='expert', questioner='all', limit=3, workers=1,
                                 resolution=64, out=tmp_path / 'eval.jsonl', record=tmp_path / 'bags'), progress=False)
    page_path, shown, counts = build_report(tmp_path / 'eval.jsonl', tmp_path / 'bags')
    assert counts == {'gifs': 3, 'missing': 0, 'unreadable': 0, 'mismatched': 0}   # the real bags are this run's
    page = page_path.read_text()
    assert '<dt>agent</dt><dd>expert (privileged reference' in page and '<dt>resolution</dt><dd>64</dd>' in page
    for r in report.results:
        block = episode_block(page, r.task_id)
        assert get_task(r.task_id).instruction in block
        assert f'src="eval_media/{bag_name(r.task_id)}.gif"' in block
        assert all(html.escape(qa['answer']) in block for qa in r.dialogue)


# ------------------------------------------------------------------------------------------ in a browser

@pytest.fixture(scope='module')
def browser():
    if chromium_path() is None:
        pytest.skip('no chromium on PATH: `./dialfred setup` installs it as root with apt-get '
                    '(DIALFRED_NO_APT unset), or run `apt-get install chromium`')
    with Browser() as b:
        yield b


SET_FILTER = """(function () {{
  var s = document.getElementById('{select}');
  s.value = {value};
  s.dispatchEvent(new Event('change'));
  var shown = Array.prototype.filter.call(document.querySelectorAll('article.episode'), function (a) {{ return !a.hidden; }});
  return {{count: document.getElementById('shown-count').textContent, ids: shown.map(function (a) {{ return a.id; }}),
           fragment: location.hash}};
}})()"""


def set_filter(page, select: str, value: str) -> dict:
    return page.evaluate(SET_FILTER.format(select=select, value=json.dumps(value)))


@pytest.mark.slow   # a headless browser; fast: the page tests above
@needs_chromium
def test_chromiums_screenshot_of_the_page_is_not_blank(run, tmp_path):
    path, bags, _ = run
    page = build_report(path, bags)[0]
    shot = tmp_path / 'shot.png'
    proc = screenshot_cli(page.as_uri(), str(shot))
    assert proc.returncode == 0 and shot.is_file(), proc.stderr[-2000:]
    from PIL import Image
    with Image.open(shot) as img:
        assert img.size == (1200, 1600)
    png = shot.read_bytes()
    assert pixel_std(png) > 20 and blank_fraction(png) < 0.8
    # the check can fail: a blank page's screenshot is blank
    blank = tmp_path / 'blank.html'
    blank.write_text('<!DOCTYPE html><html><body></body></html>')
    assert screenshot_cli(blank.as_uri(), str(tmp_path / 'blank.png')).returncode == 0
    blank_png = (tmp_path / 'blank.png').read_bytes()
    assert pixel_std(blank_png) < 1 and blank_fraction(blank_png) > 0.99


@needs_chromium
def test_in_chromium_the_page_has_no_errors_its_gifs_load_and_its_filters_work(run, browser):
    path, bags, results = run
    page_path = build_report(path, bags)[0]
    page = browser.open(page_path.as_uri())
    assert page.evaluate('document.body.dataset.ready') == 'true'      # the script ran to its end
    # every GIF loads (lazy ones too) and is drawn at its size
    widths = page.evaluate("Promise.all(Array.from(document.images).map(function (i) { i.loading = 'eager'; "
                           "return i.decode().then(function () { return i.naturalWidth; }); }))")
    assert widths == [256] * 6
    assert page.errors == []
    png = page.screenshot()
    assert pixel_std(png) > 20 and blank_fraction(png) < 0.8

    ids = lambda pick: [r.task_id.replace('/', '_') for r in results if pick(r)]
    shown = set_filter(page, 'filter-type', 'Move & Pick')
    assert shown['count'] == '3' and shown['ids'] == ids(lambda r: r.task_type == 'Move & Pick')
    assert shown['fragment'] == '#type=Move+%26+Pick'
    shown = set_filter(page, 'filter-outcome', 'failure')
    assert shown['count'] == '1' and shown['ids'] == ['synthetic_000006']
    shown = set_filter(page, 'filter-type', 'all')
    assert shown['count'] == '4' and shown['ids'] == ids(lambda r: not r.success)
    shown = set_filter(page, 'filter-outcome', 'failure:max_steps')
    assert shown['ids'] == ['synthetic_000004'] and shown['fragment'] == '#outcome=failure%3Amax_steps'
    shown = set_filter(page, 'filter-type', 'Put')
    assert shown['count'] == '1'
    shown = set_filter(page, 'filter-type', 'Clean')          # nothing left: said so
    assert shown['count'] == '0' and page.evaluate("document.getElementById('none-shown').hidden") is False
    # a bar of the chart filters by its type; "show all" clears both filters
    page.evaluate("document.querySelector('[data-filter-type=\"Put\"]').dispatchEvent(new MouseEvent('click'))")
    assert page.evaluate("document.getElementById('filter-type').value") == 'Put'
    page.evaluate("document.getElementById('filter-reset').click()")
    assert page.evaluate("document.getElementById('shown-count').textContent") == '8'
    assert page.errors == []

    # a link to a filtered view opens filtered
    linked = browser.open(page_path.as_uri() + '#type=Clean&outcome=success')
    assert linked.evaluate("document.getElementById('shown-count').textContent") == '1'
    assert linked.errors == []


@needs_chromium
def test_the_browser_checks_catch_a_broken_script_a_console_error_and_a_missing_gif(run, browser, tmp_path):
    path, bags, _ = run
    page_path = build_report(path, bags)[0]
    text = page_path.read_text()
    broken = page_path.with_name('broken.html')
    broken.write_text(text.replace("var typeSelect = document.getElementById('filter-type');",
                                   "var typeSelect = document.getElementById('filter-typo');"))
    page = browser.open(broken.as_uri())
    assert any('uncaught exception: TypeError' in e for e in page.errors), page.errors
    assert page.evaluate('document.body.dataset.ready') is None        # the filters never came to life
    noisy = page_path.with_name('noisy.html')
    noisy.write_text(text.replace('<main>', "<main><script>console.error('synthetic failure');</script>"))
    assert browser.open(noisy.as_uri()).errors == ['console.error: synthetic failure']
    shutil.rmtree(page_path.parent / 'run_media')
    page = browser.open(page_path.as_uri())
    page.evaluate("Promise.all(Array.from(document.images).map(function (i) { i.loading = 'eager'; "
                  "return i.decode().catch(function () { return 0; }); }))")
    assert any('ERR_FILE_NOT_FOUND' in e for e in page.errors), page.errors



def test_a_chained_runs_page_gives_its_episodes_figures_and_each_tasks_place(tmp_path):
    from dialfred_bringup.evaluation import EvalConfig, run_eval
    out = tmp_path / 'chained.jsonl'
    report = run_eval(EvalConfig(split='valid_unseen', agent='random', resolution=64, limit=16, local=True,
                                 workers=2, protocol='chained', out=out), progress=False)
    page = build_report(out)[0].read_text()
    episodes = report.summary['episodes']
    assert f'Chained (DialFRED&#x27;s challenge test): {episodes["episodes"]} episodes' in page
    first = report.results[0]
    total = sum(r.episode_id == first.episode_id for r in report.results)
    assert f'episode {first.episode_id}, task 1 of {total}' in page
    if episodes['held_at_start']:
        assert 'its goal held at its chained start' in page
