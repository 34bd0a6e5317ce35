"""`--record DIR` through the real graph: episode bags written by the performer node (eval --performer
et), by the launcher's in-process agent path and by the `dialogue` job.

Claims: every evaluated task has a bag whose actions, questions and outcome are those of its results
line, with a camera frame and a pose for the reset and every action; the same seeded evaluation
recorded twice gives byte-identical bags; a PNG recording decodes to the raw recording's frames;
`replay` renders a recorded episode from the bag alone; the dialogue job records what it asked.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest


from dialfred_bringup.evaluation import EvalConfig, run_eval
from dialfred_sim.bag import bag_name, read_bag, read_episode
from dialfred_bringup.replay import main as replay_main
from dialfred_bringup.report import build_report
from dialfred_sim.traces import load_traces

REPO = Path(__file__).resolve().parents[2]
RES = 64


def check_bags_match_results(report, folder: Path) -> None:
    assert sorted(p.name for p in folder.iterdir()) == sorted(bag_name(r.task_id) for r in report.results)
    for r in report.results:
        ep = read_episode(folder / bag_name(r.task_id))
        assert ep.task['task_id'] == r.task_id
        assert [a[0] for a in ep.actions] == list(range(1, r.steps + 1))
        assert len(ep.frames) == r.steps + 1 and len(ep.poses) == r.steps + 1
        assert [(q[1], q[2], q[5], q[4]) for q in ep.dialogue] == \
            [(d['type'], d['noun'], d['valid'], d['answer']) for d in r.dialogue]
        assert len(ep.dialogue) == r.questions
        assert (ep.result['success'], ep.result['steps'], ep.result['questions'], ep.result['end_reason']) == \
            (r.success, r.steps, r.questions, r.end_reason)
        assert sum(not a[4] for a in ep.actions) == r.failed_actions


def check_chained_bags(report, folder: Path, results: Path, traced: bool = True) -> None:
    """One bag a chained episode, `<first task>_chained`, that holds its tasks in the order played, each as its
    results line says; the report page shows every task with its episode's one GIF."""
    episodes: dict = {}
    for r in report.results:
        episodes.setdefault(r.episode_id, []).append(r)
    assert len(episodes) >= 2
    traces = load_traces(results) if traced else {}   # performer-node runs keep no trace
    assert sorted(p.name for p in folder.iterdir()) == sorted(bag_name(rs[0].task_id, chained=True)
                                                              for rs in episodes.values())
    for rs in episodes.values():
        parts = read_bag(folder / bag_name(rs[0].task_id, chained=True))
        assert [p.task['task_id'] for p in parts] == [r.task_id for r in rs]
        for ep, r in zip(parts, rs):
            assert [a[0] for a in ep.actions] == list(range(1, r.steps + 1))
            if traced:
                assert [(a[1], a[2], a[3]) for a in ep.actions] == [tuple(a) for a in traces[r.task_id]['actions']]
            assert len(ep.frames) == r.steps + 1
            assert [(q[1], q[2], q[4]) for q in ep.dialogue] == [(d['type'], d['noun'], d['answer']) for d in r.dialogue]
            assert (ep.result['success'], ep.result['steps'], ep.result['end_reason']) == (r.success, r.steps,
                                                                                           r.end_reason)
    page, rep, counts = build_report(results, bags=folder)
    assert counts == {'gifs': len(report.results), 'missing': 0, 'unreadable': 0, 'mismatched': 0}
    gifs = {v.result.task_id: v.gif for v in rep.episodes}
    for rs in episodes.values():
        assert len({gifs[r.task_id] for r in rs}) == 1 and gifs[rs[0].task_id]
    assert len(set(gifs.values())) == len(episodes)


def test_a_chained_episode_is_recorded_as_one_bag_with_its_tasks(tmp_path):
    """The in-process agent path (the simulator and oracle nodes); the performer node's: below."""
    report = run_eval(EvalConfig(split='valid_unseen', agent='random', questioner='random', limit=17, workers=1,
                                 resolution=RES, protocol='chained', out=tmp_path / 'c.jsonl', record=tmp_path / 'bags'),
                      progress=False)
    assert sum(r.questions for r in report.results) > 0
    check_chained_bags(report, tmp_path / 'bags', tmp_path / 'c.jsonl')


@pytest.mark.slow   # a chained graph run through the performer node; fast: the in-process path above
def test_the_performer_node_records_a_chained_episode_as_one_bag(checkpoint, tmp_path):
    report = run_eval(EvalConfig(split='valid_unseen', performer='et', questioner='all', limit=17, workers=1,
                                 resolution=RES, protocol='chained', checkpoint=checkpoint, out=tmp_path / 'c.jsonl',
                                 record=tmp_path / 'bags'), progress=False)
    check_chained_bags(report, tmp_path / 'bags', tmp_path / 'c.jsonl', traced=False)


@pytest.mark.slow   # two graph runs end to end; fast: the recording tests below
def test_the_performer_node_records_each_episode_and_a_rerun_gives_the_same_bytes(checkpoint, tmp_path):
    common = dict(split='valid_unseen', performer='et', questioner='all', limit=2, workers=1, resolution=RES,
                  seed=3, checkpoint=checkpoint)
    a = run_eval(EvalConfig(out=tmp_path / 'a.jsonl', record=tmp_path / 'bags_a', **common), progress=False)
    check_bags_match_results(a, tmp_path / 'bags_a')
    assert sum(r.questions for r in a.results) > 0
    b = run_eval(EvalConfig(out=tmp_path / 'b.jsonl', record=tmp_path / 'bags_b', **common), progress=False)
    assert [dataclasses.replace(r, wall_s=0.0) for r in b.results] == \
        [dataclasses.replace(r, wall_s=0.0) for r in a.results]        # the same episodes, wall time aside
    for r in a.results:
        for f in sorted((tmp_path / 'bags_a' / bag_name(r.task_id)).iterdir()):
            assert f.read_bytes() == (tmp_path / 'bags_b' / bag_name(r.task_id) / f.name).read_bytes(), f
    # replay from the bag alone
    bag = tmp_path / 'bags_a' / bag_name(a.results[0].task_id)
    assert replay_main([str(bag), '--gif', str(tmp_path / 'r.gif'), '--sheet', str(tmp_path / 'r.png')]) == 0
    assert (tmp_path / 'r.gif').stat().st_size > 1000 and (tmp_path / 'r.png').is_file()


@pytest.mark.slow   # fast: test_recording (PNG frames decode to the raw ones), the performer node's bags above
def test_the_in_process_agent_path_records_and_png_frames_equal_raw_ones(tmp_path):
    common = dict(split='valid_unseen', agent='expert', questioner='all', limit=2, workers=2, resolution=RES, seed=0)
    raw = run_eval(EvalConfig(out=tmp_path / 'raw.jsonl', record=tmp_path / 'raw', **common), progress=False)
    check_bags_match_results(raw, tmp_path / 'raw')
    png = run_eval(EvalConfig(out=tmp_path / 'png.jsonl', record=tmp_path / 'png', record_format='png', **common),
                   progress=False)
    for r in png.results:
        x, y = read_episode(tmp_path / 'raw' / bag_name(r.task_id)), read_episode(tmp_path / 'png' / bag_name(r.task_id))
        assert '/camera/image/compressed' in y.counts and len(x.frames) == len(y.frames)
        assert all(np.array_equal(f[2], g[2]) for f, g in zip(x.frames, y.frames))


def test_a_bad_record_format_is_refused_before_any_node_starts(tmp_path):
    with pytest.raises(ValueError, match='record-format'):
        run_eval(EvalConfig(split='valid_unseen', limit=1, record=tmp_path / 'r', record_format='gif'), progress=False)
    assert not (tmp_path / 'r').exists()


def test_the_dialogue_job_records_its_questions_and_the_experts_actions(tmp_path):
    from dialfred_bringup.launch import main
    assert main(['dialogue', '--tasks', '1', '--resolution', str(RES), '--record', str(tmp_path / 'bags')]) == 0
    (bag,) = (tmp_path / 'bags').iterdir()
    ep = read_episode(bag)
    assert [q[1] for q in ep.dialogue] == ['location', 'appearance', 'direction', 'location', 'colour', 'direction']
    assert [q[5] for q in ep.dialogue][3:5] == [False, False]             # the unicorn and the colour question
    assert ep.dialogue[-1][0] == len(ep.actions) - 1                      # asked before the expert's last action
    assert ep.result['success'] and len(ep.frames) == len(ep.actions) + 1


def test_the_map_performer_node_says_what_it_heard_on_dialogue_qa_and_its_bags_keep_it(tmp_path):
    from dialfred_performer.mapper.agent import MapAgent
    from dialfred_sim.protocol import QA, Question
    report = run_eval(EvalConfig(split='valid_unseen', performer='map', questioner='all', limit=1, workers=1,
                                 out=tmp_path / 'm.jsonl', record=tmp_path / 'bags'), progress=False)
    r, = report.results
    ep = read_episode(tmp_path / 'bags' / bag_name(r.task_id))
    reader = MapAgent.__new__(MapAgent)
    heard = [q[6] for q in ep.dialogue]
    assert len(heard) == r.questions > 0 and all(heard[k] for k, q in enumerate(ep.dialogue) if q[5])
    assert heard == [reader.understood(QA(Question(q[1], q[2]), q[5], q[4])) for q in ep.dialogue]
