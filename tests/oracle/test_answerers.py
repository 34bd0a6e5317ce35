"""Answerers (`--answers FILE | package.module:Class`, dialfred_oracle/answerers.py) and the held-out wording
(dialfred_oracle/wording.py): a file's words are said for its questions and "I don't know." for the rest; a bad
file is refused naming its line; a class words the oracle's answers and nothing else; a run records its answerer,
is named apart, never resumes with another, and scores by replay (no ROS; the graph's oracle node plays the same
episodes in tests/bringup/test_eval_local.py)."""

from __future__ import annotations

import json
import re

import pytest

from dialfred_bringup.evaluation import EvalConfig, EvalRun, run_eval
from dialfred_bringup.score import score
from dialfred_oracle.annotator import answer_content
from dialfred_oracle.answerers import (WITHHELD, Asked, AnswersError, AnswersFile, Speaking, export, load_answerer,
                                       speaking)
from dialfred_oracle.answers import Answer
from dialfred_oracle.in_process import answer_now
from dialfred_oracle.wording import SYNONYMS, WHERE, HeldOutWording
from dialfred_sim.agents import task_nouns
from dialfred_sim.metrics import ResultsFileError
from dialfred_sim.tasks import load_split
from dialfred_sim.tasks.instructions import tokenize

SPLIT = 'valid_unseen'
HELD_OUT = 'dialfred_oracle.wording:HeldOutWording'


def write_lines(path, lines) -> str:
    path.write_text(''.join((line if isinstance(line, str) else json.dumps(line)) + '\n' for line in lines))
    return str(path)


def asked(task='valid_unseen/000000', qtype='location', noun='counter', text='Where is the counter?'):
    return Asked(task, qtype, noun, text)


def test_a_file_says_its_words_and_i_dont_know_for_questions_it_does_not_hold(tmp_path):
    path = write_lines(tmp_path / 'person.jsonl', [
        {'task': 'valid_unseen/000000', 'type': 'location', 'noun': 'The Counter ', 'answer': "  it's  by the sink "},
        {'task': 'valid_unseen/000000', 'type': 'dir', 'answer': 'turn left'},
        '',
        {'task': 'valid_unseen/000000', 'type': 'location', 'noun': 'counter', 'answer': "it's by the sink"}])
    f = AnswersFile(path)
    assert re.fullmatch(r'file-person-[0-9a-f]{8}', f.label)
    oracle = answer_content(Answer(True, 'The counter is to your left.', question_type='location'), 'location',
                            'counter')
    assert f.say(asked(noun='counter'), oracle) == "it's by the sink"
    assert f.say(asked(qtype='direction', noun='', text='Which direction should I turn to?'), oracle) == 'turn left'
    assert f.missing == 0
    assert f.say(asked(task='valid_unseen/000001'), oracle) == WITHHELD and f.missing == 1
    # another file of other words is another answerer
    other = AnswersFile(write_lines(tmp_path / 'person2.jsonl', [
        {'task': 'valid_unseen/000000', 'type': 'location', 'noun': 'counter', 'answer': 'left'}]))
    assert other.label != f.label


@pytest.mark.parametrize('lines, error', [
    (['{"task": "a", "type": "location", "noun": "x", "answer": "y"}', 'not json'], r'bad\.jsonl:2: not JSON'),
    ([{'task': 'a', 'type': 'smell', 'noun': 'x', 'answer': 'y'}], r':1: unknown question type'),
    ([{'task': 'a', 'type': 'location', 'answer': 'y'}], r':1: a location question names an object'),
    ([{'task': 'a', 'type': 'location', 'noun': 'x', 'answer': 'y', 'when': 3}], r"unknown keys \['when'\]"),
    ([{'task': 'a', 'type': 'location', 'noun': 'x'}], r"missing \['answer'\]"),
    ([{'task': 'a', 'type': 'location', 'noun': 'x', 'answer': 5}], r'answer must be text'),
    ([{'task': 'a', 'type': 'location', 'noun': 'x', 'answer': '   '}], r'an answer is 1 to'),
    ([{'task': 'a', 'type': 'location', 'noun': 'x', 'answer': 'y'},
      {'task': 'a', 'type': 'loc', 'noun': 'X', 'answer': 'z'}], r':2: a second answer .* first at line 1'),
    (['[1, 2]'], r':1: a line is an object'),
    ([''], r'no answers in it'),
])
def test_a_bad_answers_file_is_refused_naming_its_line(tmp_path, lines, error):
    path = write_lines(tmp_path / 'bad.jsonl', lines)
    with pytest.raises(AnswersError, match=error):
        AnswersFile(path)


def test_what_is_not_an_answerer_is_refused_with_the_reason(tmp_path):
    with pytest.raises(AnswersError, match='no such file'):
        load_answerer(str(tmp_path / 'none.jsonl'))
    with pytest.raises(AnswersError, match='cannot import'):
        load_answerer('no_such_module_here:Person')
    with pytest.raises(AnswersError, match='has no class'):
        load_answerer('dialfred_oracle.wording:Nobody')
    with pytest.raises(AnswersError, match='lacks say'):
        load_answerer('dialfred_oracle.answerers:Asked')
    assert speaking('oracle') is None and speaking('swapped') is None and speaking('human') is None
    with pytest.raises(ValueError, match='no such file'):
        EvalRun(EvalConfig(split=SPLIT, agent='random', questioner='all', answers='nobody.jsonl',
                           out=tmp_path / 'x.jsonl'))
    with pytest.raises(ValueError, match='needs a questioner'):
        EvalRun(EvalConfig(split=SPLIT, agent='random', answers=HELD_OUT, out=tmp_path / 'x.jsonl'))
    with pytest.raises(ValueError, match='needs a questioner .* no --perturb-type'):
        EvalRun(EvalConfig(split=SPLIT, agent='random', questioner='all', answers=HELD_OUT, perturb_type='location',
                           out=tmp_path / 'x.jsonl'))


class _Says:
    def __init__(self, words):
        self.words, self.heard = words, []

    def say(self, asked, content):
        self.heard.append((asked, content))
        return self.words


def test_an_answerer_words_valid_answers_only_and_must_say_text():
    oracle = Answer(True, 'The apple is to your left on the counter.', question_type='location', object_noun='apple')
    person = _Says('over there')
    said = Speaking(person, 'p').apply(oracle, 'valid_unseen/000000', 'apple')
    assert said.text == 'over there' and said.valid
    (q, content), = person.heard
    assert (q.task_id, q.question_type, q.object_noun, q.text) == ('valid_unseen/000000', 'location', 'apple',
                                                                   'Where is the apple?')
    assert (content.where, content.preposition, content.receptacle) == ('to your left', 'on', 'counter')
    # refused and withheld answers are not the answerer's to word; None keeps the oracle's words
    refused = Answer(False, reason='no plum here', question_type='location')
    assert Speaking(person, 'p').apply(refused, 't', 'plum') is refused
    withheld = Answer(True, WITHHELD, question_type='location')
    assert Speaking(person, 'p').apply(withheld, 't', 'apple') is withheld
    assert Speaking(_Says(None), 'p').apply(oracle, 't', 'apple') is oracle
    with pytest.raises(AnswersError, match='said int'):
        Speaking(_Says(3), 'p').apply(oracle, 't', 'apple')
    with pytest.raises(AnswersError, match='said 0 characters'):
        Speaking(_Says('  '), 'p').apply(oracle, 't', 'apple')


def test_the_held_out_wording_says_the_oracles_facts_in_other_words_the_same_each_time(env):
    wording, seen, lengths, forms, facts, unsaid = HeldOutWording(), 0, [], set(), [], []
    for task in load_split(SPLIT)[:30]:
        env.reset(options={'task': task})
        for noun in task_nouns(task)[:2]:
            for qtype in ('location', 'appearance'):
                oracle = answer_now(env, qtype, noun)
                if not oracle.valid:
                    continue
                q = Asked(task.task_id, qtype, noun, '')
                content = answer_content(oracle, qtype, noun)
                words = wording.say(q, content)
                assert words == HeldOutWording().say(q, content)       # seeded by the question and the answer
                spoken = wording.spoken(q, content)
                assert spoken.text == words and spoken.unsaid <= {'bin', 'receptacle'}
                unsaid.append(bool(spoken.unsaid))
                assert words and words != oracle.text
                lengths.append(len(tokenize(words)))
                forms.add(words.lower())
                seen += 1
                if qtype == 'location' and content.receptacle and content.where in WHERE:
                    # the place or the direction, in its own words (a misspelling may hide one of them)
                    names = (content.receptacle, *SYNONYMS.get(content.receptacle, ()))
                    facts.append(any(n in words.lower() for n in names) or
                                 any(w.lower() in words.lower() for w in WHERE[content.where]))
    assert seen >= 60 and len(forms) > 0.8 * seen
    assert len(facts) >= 10 and sum(facts) >= 0.75 * len(facts)
    assert 2 <= sum(lengths) / len(lengths) <= 12
    assert 0 < sum(unsaid) < len(unsaid)                    # a detail left unsaid in some location answers


def test_an_evaluation_records_its_answerer_never_resumes_with_another_and_scores_by_replay(tmp_path):
    settings = dict(split=SPLIT, agent='random', questioner='all', limit=2, workers=1, resolution=64, local=True)
    held = tmp_path / 'held.jsonl'
    run = EvalRun(EvalConfig(**settings, answers=HELD_OUT))
    assert run.oracle == 'answers:dialfred_oracle.wording.HeldOutWording'
    assert run.results_path.name.endswith('_answers-dialfred_oracle.wording.HeldOutWording.jsonl')
    report = run_eval(EvalConfig(**settings, answers=HELD_OUT, out=held), progress=False)
    assert all(r.oracle == run.oracle and r.dialogue for r in report.results)
    # the answers exported from it are a file that plays the same episodes again
    answers = tmp_path / 'answers.jsonl'
    counts = export(held, answers)
    assert counts['answers'] == sum(len(r.dialogue) for r in report.results) and counts['repeated'] == 0
    again = run_eval(EvalConfig(**settings, answers=str(answers), out=tmp_path / 'file.jsonl'), progress=False)
    assert [(r.task_id, r.steps, r.success, r.dialogue) for r in again.results] == \
        [(r.task_id, r.steps, r.success, r.dialogue) for r in report.results]
    assert again.results[0].oracle == 'answers:' + AnswersFile(answers).label
    # a resumed run refuses another answerer, or none
    for other in (str(answers), 'oracle'):
        with pytest.raises(ResultsFileError, match='oracle'):
            run_eval(EvalConfig(**settings, answers=other, out=held), progress=False)
    # anyone can score both by replay; a changed answers file is not the one that answered
    assert score(held, workers=1, progress=False)['refused'] is None
    assert score(tmp_path / 'file.jsonl', workers=1, progress=False)['refused'] is None
    moved = tmp_path / 'moved.jsonl'
    moved.write_bytes(answers.read_bytes())
    assert score(tmp_path / 'file.jsonl', workers=1, progress=False, answers=moved)['refused'] is None
    moved.write_text(answers.read_text().replace('"answer": "', '"answer": "um, '))
    with pytest.raises(ResultsFileError, match='not the answerer'):
        score(tmp_path / 'file.jsonl', workers=1, progress=False, answers=moved)
