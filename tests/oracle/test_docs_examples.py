"""The docs' examples are the shipped splits' tasks as they are: the oracle's answers that docs/oracle.md
shows for the start of a task are what the oracle says there now, and the task is the one it names."""

from __future__ import annotations

import json
import re
from pathlib import Path

from dialfred_oracle.annotator import answer_content
from dialfred_oracle.answerers import AnswersFile
from dialfred_oracle.in_process import answer_now
from dialfred_sim.agents import task_nouns
from dialfred_sim.env import DialfredEnv
from dialfred_sim.tasks import get_task

REPO = Path(__file__).resolve().parents[2]


def test_the_oracle_page_shows_the_answers_the_oracle_gives_at_the_start_of_its_task():
    text = (REPO / 'docs' / 'oracle.md').read_text()
    intro = re.search(r'The start of `([^`]+)` \("([^"]+)"\) gives these', text)
    task = get_task(intro.group(1))
    assert task.instruction == intro.group(2)
    table = text[intro.end():].split('\n\n')[1]
    rows = [[c.strip() for c in line.strip('|').split('|')] for line in table.splitlines()[2:]]
    assert len(rows) >= 5
    env = DialfredEnv(resolution=128)
    try:
        env.reset(options={'task': task})
        for question, valid, said in rows:
            qtype, *rest = question.split(',')
            nouns = re.findall(r'`([^`]+)`', ','.join(rest)) or ['']
            for noun in nouns:
                answer = answer_now(env, qtype.strip(), noun)
                assert answer.valid == (valid == 'yes') and (answer.text if answer.valid else answer.reason) == said, \
                    (question, noun, answer)
    finally:
        env.close()


def test_the_answers_file_example_is_a_line_a_file_takes_and_says_what_the_oracle_says_there(tmp_path):
    text = (REPO / 'docs' / 'oracle.md').read_text()
    line = re.search(r'```json\n(\{"task".*\})\n```', text).group(1)
    entry = json.loads(line)
    path = tmp_path / 'person.jsonl'
    path.write_text(line + '\n')
    assert AnswersFile(path).words      # a line the file reader takes
    task = get_task(entry['task'])
    assert entry['noun'] in task.instruction.lower() or entry['noun'] in task_nouns(task)
    env = DialfredEnv(resolution=64)
    try:
        env.reset(options={'task': task})
        content = answer_content(answer_now(env, entry['type'], entry['noun']), entry['type'], entry['noun'])
    finally:
        env.close()
    assert content.receptacle and content.receptacle in entry['answer'] and content.where in entry['answer']
