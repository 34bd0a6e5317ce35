"""The question types' registry (protocol.QUESTION_KINDS): what lists the types derives from it.

Claims: the paper's three types in order, with their templates, the object-naming ones and the short
tokens that the oracle accepts and the performer's input marks; the lists that used to be written out
(the questioner's outputs, the performer's marks and token types, the oracle's aliases and rules, All
QAs' questions) are the registry's; a name or token that is taken cannot be registered; and a toy type
registered by this test alone (in a fresh interpreter: its entry, the oracle's rule, nothing else) is
asked by the All QAs questioner, answered by the oracle's rule through the episode loop, and heard by
an Episodic Transformer performer, whose input marks it with its own token type, for one episode.
Unregistered, the same question is refused by the oracle.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from dialfred_oracle.answers import QUESTION_ALIASES, RULES, answer
from dialfred_performer.preprocess import N_TOKEN_TYPES, TYPE_MARKS
from dialfred_questioner.model import NEEDS_OBJECT, TYPE_TOKENS
from dialfred_sim.protocol import (OBJECT_QUESTION_TYPES, QUESTION_KINDS, QUESTION_TEMPLATES, QUESTION_TYPES, Question,
                                   QuestionType, every_question, register_question_type)


def test_the_paper_types_and_everything_derived_from_them():
    assert QUESTION_TYPES == ('location', 'appearance', 'direction') and OBJECT_QUESTION_TYPES == QUESTION_TYPES[:2]
    assert QUESTION_TEMPLATES['location'] == 'Where is the {noun}?'
    assert TYPE_TOKENS == ('none', *QUESTION_TYPES) and NEEDS_OBJECT == OBJECT_QUESTION_TYPES
    assert TYPE_MARKS == {'location': '<loc>', 'appearance': '<app>', 'direction': '<dir>'} and N_TOKEN_TYPES == 5
    assert QUESTION_ALIASES == {'loc': 'location', 'app': 'appearance', 'dir': 'direction'}
    assert set(RULES) == set(QUESTION_TYPES)
    assert every_question(['apple', 'fridge']) == [
        Question('location', 'apple'), Question('appearance', 'apple'), Question('location', 'fridge'),
        Question('appearance', 'fridge'), Question('direction')]
    for taken in (QuestionType('location', '{noun}?', True, 'xyz'), QuestionType('count', '{noun}?', True, 'loc')):
        with pytest.raises(ValueError, match='exists'):
            register_question_type(taken)
    assert len(QUESTION_KINDS) == 3
    assert not answer(None, 'count', 'apple').valid                    # not a type here


TOY = r'''
import json
from dialfred_sim import protocol
protocol.register_question_type(protocol.QuestionType('count', 'How many {noun}s are there?', True, 'cnt'))

from dialfred_oracle import answers


def count_answer(snapshot, object_id):
    noun = snapshot.objects[object_id].noun
    n = sum(f.noun == noun for f in snapshot.objects.values())
    return answers.Answer(True, f'There are {n} of them.', question_type='count', object_noun=noun, object_id=object_id)


answers.RULES['count'] = count_answer

from dialfred_oracle.in_process import EnvServer
from dialfred_performer.agent import PerformerAgent
from dialfred_performer.model import Performer, PerformerConfig
from dialfred_performer.preprocess import TYPE_OF_QUESTION, Vocabulary
from dialfred_questioner.baselines import AllQuestioner, with_questioner
from dialfred_questioner.model import TYPE_TOKENS
from dialfred_sim.env import DialfredEnv
from dialfred_sim.episode import play, run
from dialfred_sim.tasks import load_split

task = next(t for t in load_split('valid_unseen') if t.public().object_nouns)
vocab = Vocabulary.build([task.instruction, 'there are 2 of them .'])
performer = PerformerAgent(Performer(PerformerConfig(resolution=32, d_model=32, heads=2, layers=1, ff=32), len(vocab)),
                           vocab)
env = DialfredEnv(resolution=32, max_steps=2)
state = run(play(with_questioner(performer, AllQuestioner()), seed=0), EnvServer(env, task))
print(json.dumps({'types': protocol.QUESTION_TYPES, 'tokens': TYPE_TOKENS, 'steps': state.steps,
                  'dialogue': [[qa.question.question_type, qa.question.text, qa.valid, qa.answer] for qa in state.dialogue],
                  'count_type': TYPE_OF_QUESTION['count'],
                  'heard_types': sorted(set(performer.language_input().types))}))
'''


def test_a_toy_question_type_is_asked_answered_and_heard_in_one_episode():
    done = subprocess.run([sys.executable, '-c', TOY], capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out['types'] == ['location', 'appearance', 'direction', 'count']
    assert out['tokens'] == ['none', 'location', 'appearance', 'direction', 'count']
    counts = [d for d in out['dialogue'] if d[0] == 'count']
    assert counts and all(valid and text.startswith('How many ') and said.startswith('There are ')
                          for _, text, valid, said in counts)
    assert out['dialogue'][-1][0] == 'direction'                       # types that name no object come last
    assert out['count_type'] in out['heard_types'] and out['steps'] >= 1
