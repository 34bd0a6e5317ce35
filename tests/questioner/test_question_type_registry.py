"""Question types, each whole in one module of dialfred_oracle.questions (the oracle's rule and wording,
the words read back, the check, the annotator's rule), listed by the protocol's registry when asked.

Claims: the paper's three types in order, with their templates, the object-naming ones and the short
tokens that the oracle accepts and the performer's input marks; everything that lists the types (the
questioner's outputs, the performer's marks and token types, the oracle's aliases and rules, the
annotator's choices, All QAs' questions) reads the registry when it is called, so a toy fourth type
registered after every import is seen by all of them: in one episode it is answered by the oracle,
chosen and paraphrased by the annotator into a pre-training row, an output of a questioner made then,
marked with its own token type by the performer's tokenizer, asked by All QAs through the episode loop
and heard by an Episodic Transformer. Unregistered, its questions are refused again. A name or token
that is taken cannot be registered.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from dialfred_oracle.annotator import (ChoiceModel, Situation, TaskDialogues, annotate, answer_content, categories,
                                       choice_model, dialogue_statistics, target_choice_shares)
from dialfred_oracle.answers import answer, check_answer, parse_question_type, question_aliases
from dialfred_oracle.in_process import EnvServer
from dialfred_oracle.questions import Answer, OracleQuestion, oracle_question, oracle_questions, register, unregister
from dialfred_oracle.questions.base import one_of
from dialfred_performer.agent import PerformerAgent
from dialfred_performer.model import CheckpointError, Performer, PerformerConfig
from dialfred_performer.model_registry import load_policy
from dialfred_performer.shipped import SHIPPED_CHECKPOINT
from dialfred_performer.preprocess import Vocabulary, n_token_types, qa_tokens, type_marks, type_of_question
from dialfred_questioner.baselines import AllQuestioner, random_qa_choices, with_questioner
from dialfred_questioner.data import catalog_nouns, pretraining_examples
from dialfred_questioner.model import Questioner, QuestionerConfig, type_tokens
from dialfred_sim.env import DialfredEnv
from dialfred_sim.episode import play, run
from dialfred_sim.ground_truth import snapshot
from dialfred_sim.protocol import (PAPER_QUESTION_TYPES, QA, Question, QuestionType, every_question, object_question_types,
                                   question_text, question_types, register_question_type, unregister_question_type)
from dialfred_sim.tasks import load_split


def test_the_paper_types_and_everything_listed_from_them():
    assert question_types() == PAPER_QUESTION_TYPES == ('location', 'appearance', 'direction')
    assert object_question_types() == PAPER_QUESTION_TYPES[:2]
    assert question_text('location', 'apple') == 'Where is the apple?'
    assert type_tokens() == ('none', *PAPER_QUESTION_TYPES)
    assert type_marks() == {'location': '<loc>', 'appearance': '<app>', 'direction': '<dir>'} and n_token_types() == 5
    assert question_aliases() == {'loc': 'location', 'app': 'appearance', 'dir': 'direction'}
    assert [q.name for q in oracle_questions()] == list(PAPER_QUESTION_TYPES)
    assert [oracle_question(t).reads_looks for t in PAPER_QUESTION_TYPES] == [False, True, False]
    assert categories() == ('none', *PAPER_QUESTION_TYPES) and len(choice_model().bias) == 4
    assert random_qa_choices() == (*PAPER_QUESTION_TYPES, None)
    assert every_question(['apple', 'fridge']) == [
        Question('location', 'apple'), Question('appearance', 'apple'), Question('location', 'fridge'),
        Question('appearance', 'fridge'), Question('direction')]
    for taken in (QuestionType('location', '{noun}?', True, 'xyz'), QuestionType('count', '{noun}?', True, 'loc')):
        with pytest.raises(ValueError, match='exists'):
            register_question_type(taken)
    with pytest.raises(ValueError, match="paper's question types"):
        unregister_question_type('location')
    assert not answer(None, 'count', 'apple').valid                    # not a type here


_COUNTED = re.compile(r'^there (?:is|are) (?P<n>\d+) of them\.$', re.I)


class Count(OracleQuestion):
    """A toy type, whole: "How many apples are there?" - "There are 2 of them."."""

    kind = QuestionType('count', 'How many {noun}s are there?', True, 'cnt')
    human_share = 0.05
    choice_bias = -1.0

    def answer(self, snapshot, object_id):
        noun = snapshot.objects[object_id].noun
        n = sum(f.noun == noun for f in snapshot.objects.values())
        return Answer(True, f'There {"is" if n == 1 else "are"} {n} of them.', question_type=self.name,
                      object_noun=noun, object_id=object_id)

    def parts(self, text):
        m = _COUNTED.match(text.strip())
        return {'where': m.group('n')} if m else None

    def evidence(self, s):
        return float(bool(s.distractor_nouns))

    def covered(self, c):
        return bool(c.where)

    def candidate(self, c, rng, distractor):
        return one_of(rng, (c.where, f'there are {c.where}', f'I count {c.where}', f'{c.where} of them'))


@pytest.fixture
def count_type():
    question = register(Count())
    try:
        yield question
    finally:
        unregister('count')
        unregister_question_type('count')


def test_a_toy_fourth_type_through_the_oracle_the_annotator_the_questioner_and_the_performer(count_type):
    assert question_types() == (*PAPER_QUESTION_TYPES, 'count') and type_tokens()[-1] == 'count'
    assert type_marks()['count'] == '<cnt>' and n_token_types() == 6 and parse_question_type(' CNT ') == 'count'
    task = next(t for t in load_split('valid_unseen') if t.public().object_nouns)
    noun = task.public().object_nouns[0]
    env = DialfredEnv(resolution=32, max_steps=2)
    try:
        env.reset(options={'task': task})
        snap = snapshot(env)
        # the oracle: its rule, its words read back, no check of the paper's applies
        said = answer(snap, 'cnt', noun)
        assert said.valid and said.question_type == 'count' and _COUNTED.match(said.text), said
        assert check_answer(snap, said) == {'receptacle_ok': None, 'direction_ok': None, 'colour_ok': None}
        content = answer_content(said, 'count', noun)
        assert content.where == _COUNTED.match(said.text).group('n')
        # the annotator: five categories, its intercept, its share; forced to choose it, a paraphrase
        assert categories()[-1] == 'count' and choice_model().bias[-1] == -1.0 and len(target_choice_shares()) == 5
        situation = Situation.of(task, snap)
        forced = ChoiceModel(0.0, tuple(50.0 if c == 'count' else -50.0 for c in categories()))
        note = annotate(task, snap, np.random.default_rng(0), 0, situation=situation, model=forced)
        assert note.question_type == 'count' and note.question == f'How many {note.object_noun}s are there?'
        assert note.valid and re.search(r'\d', note.answer) and note.oracle_answer.startswith('There ')
        assert dialogue_statistics([[note, note]])['type_shares'] == {**dict.fromkeys(PAPER_QUESTION_TYPES, 0.0),
                                                                        'count': 1.0}
        # a pre-training row of the questioner, and a questioner made now has an output for it
        row = TaskDialogues(task.task_id, task.task_type, task.instruction, situation, (note,))
        (example,), skipped = pretraining_examples([row], {task.task_id: 0}, catalog_nouns())
        assert skipped == 0 and example.qtype == type_tokens().index('count') == 4
        assert example.noun == catalog_nouns().index(note.object_noun)
        vocab = Vocabulary.build([task.instruction, said.text])
        questioner = Questioner(QuestionerConfig(embedding=8, hidden=8, image=8), len(vocab), catalog_nouns())
        assert questioner.type_tokens[-1] == 'count' and questioner.token_type.num_embeddings == 6
        # the performer's tokenizer: its mark, its own token type
        assert qa_tokens(QA(Question('count', noun), True, said.text))[:2] == ['<q>', '<cnt>']
        assert '<cnt>' in vocab.words[:9] and type_of_question()['count'] == 5
        # one episode: All QAs asks it, the oracle answers it through the loop, the performer hears it
        performer = PerformerAgent(Performer(PerformerConfig(resolution=32, d_model=32, heads=2, layers=1, ff=32),
                                             len(vocab)), vocab)
        state = run(play(with_questioner(performer, AllQuestioner()), seed=0), EnvServer(env, task))
    finally:
        env.close()
    counts = [qa for qa in state.dialogue if qa.question.question_type == 'count']
    assert counts and all(qa.valid and qa.question.text.startswith('How many ') and _COUNTED.match(qa.answer)
                          for qa in counts)
    assert state.dialogue[-1].question.question_type == 'direction'      # types that name no object come last
    assert type_of_question()['count'] in set(performer.language_input().types) and state.steps >= 1


def test_an_unregistered_type_is_refused_again(count_type):
    unregister('count')
    refused = answer(None, 'count', 'apple')
    assert not refused.valid and 'no rule' in refused.reason
    register(count_type)             # the fixture removes it again, protocol entry and all
    assert oracle_question('count') is count_type


def test_a_checkpoint_trained_before_a_type_was_added_says_so(count_type):
    with pytest.raises(CheckpointError, match='trained for 3 question types and 4 are registered'):
        load_policy('et', SHIPPED_CHECKPOINT)
