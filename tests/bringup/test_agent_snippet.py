"""The agent of docs/evaluation.md ("Agents of your own"), evaluated as written: at most 20 lines, it
plays two valid_unseen tasks through the graph and the same two episodes without ROS (`--local`), from the
typed observation alone (`step_count`, `last_action_success`)."""

from __future__ import annotations

import os
import re
from pathlib import Path

from dialfred_bringup.evaluation import EvalConfig, run_eval

REPO = Path(__file__).resolve().parents[2]


def snippet() -> str:
    text = (REPO / 'docs' / 'evaluation.md').read_text()
    return re.search(r'<!-- snippet: an agent -->\n```python\n(.*?)```', text, re.S).group(1)


def test_the_documented_agent_plays_the_same_episodes_through_the_graph_and_locally(tmp_path, monkeypatch):
    code = snippet()
    assert len(code.strip().splitlines()) <= 20
    (tmp_path / 'doc_agent.py').write_text(code)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv('PYTHONPATH', f'{tmp_path}:{os.environ.get("PYTHONPATH", "")}')
    runs = {}
    for path in ('graph', 'local'):
        report = run_eval(EvalConfig(split='valid_unseen', agent='doc_agent:Wanderer', limit=2, workers=1,
                                     out=tmp_path / f'{path}.jsonl', local=path == 'local', resolution=64),
                          progress=False)
        runs[path] = [(r.task_id, r.success, r.steps, r.failed_actions, r.end_reason) for r in report.results]
    assert runs['graph'] == runs['local'] and len(runs['graph']) == 2
    for _, success, steps, failed, reason in runs['graph']:
        # it stops at its 31st action unless it reached the goal or ten blocked moves ended the episode first
        assert ((reason, steps) == ('stop', 31) or (reason, failed) == ('max_failures', 10)
                or (success and reason == 'success' and steps <= 30)), (reason, steps, failed)
