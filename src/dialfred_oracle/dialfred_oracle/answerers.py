"""Answerers: who puts the oracle's answer into words (ROS-free).

The oracle decides what is true (dialfred_oracle.answers); an answerer decides how it is said, as a
person would say it. `--answers` names one:

- `oracle`: the oracle's own template words (no answerer);
- `swapped`: a control, another task's answers (dialfred_oracle.swap, not an answerer of this module);
- `human`: a person in the terminal (the oracle node's human mode, `--human`);
- a FILE of JSON lines, `{"task": ..., "type": ..., "noun": ..., "answer": ...}`: a person's words for
  each (task, question), so a run with a person's answers plays again exactly (`AnswersFile`);
- `package.module:ClassName`: a class of yours, constructed without arguments, whose
  `say(asked, content)` gets the question (`Asked`) and the oracle's answer in parts
  (`annotator.AnswerContent`: where, preposition, receptacle, held, colour, material, and the oracle's
  own text) and returns the words to say, or None for the oracle's own. A scripted person, a
  paraphraser (`dialfred_oracle.wording:HeldOutWording`) or a language model of yours.

An answerer speaks only where the oracle has an answer: a question the oracle refuses (no such object,
no task) stays refused, and the perturbation's withheld "I don't know." stays withheld. Results record
the answerer (`label`), so runs of different answerers never mix or resume one another. An answerer is
called once for each copy of a question that reaches the oracle, so it must say the same thing each
time it is given the same question in the same state (seed it from its arguments, as HeldOutWording
does).

`python -m dialfred_oracle.answerers export RESULTS [--out FILE]` writes the answers recorded in a
results file (a run with a person, say) as an answers FILE.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Optional, Protocol, runtime_checkable

from dialfred_sim.agents import load_class
from dialfred_sim.metrics import load_results
from dialfred_sim.protocol import names_object, question_types

from .annotator import AnswerContent, answer_content
from .answers import WITHHELD, Answer, parse_question_type, question_text

BUILT_IN = ('oracle', 'swapped', 'human')    # the --answers that name no answerer of this module
ANSWERER_PREFIX = 'answers:'                 # results' oracle field for an answerer: 'answers:<label>'
FILE_KEYS = ('task', 'type', 'noun', 'answer')
MAX_WORDS_CHARS = 2000                       # longer answers are refused, as the node refuses long nouns


@dataclass(frozen=True)
class Asked:
    """The question an answerer answers: about task `task_id` ('' when the simulator plays none), of
    `question_type` ('location', 'appearance', 'direction'), about `object_noun` ('' for direction);
    `text` as a person reads it ('Where is the apple?')."""

    task_id: str
    question_type: str
    object_noun: str
    text: str


@runtime_checkable
class Answerer(Protocol):
    def say(self, asked: Asked, content: AnswerContent) -> Optional[str]:
        """The words to say for the oracle's answer `content` to `asked`; None: the oracle's own."""


class AnswersError(ValueError):
    """An answerer that cannot be made (a bad file, a class that cannot be loaded)."""


def is_answerer_spec(spec: str) -> bool:
    """Whether `--answers spec` names an answerer of this module (a FILE or a class), not a built-in."""
    return bool(spec) and spec not in BUILT_IN


def is_class_spec(spec: str) -> bool:
    """'package.module:ClassName' (no path separator before the colon), not a file."""
    module, colon, name = spec.partition(':')
    return bool(colon) and bool(module) and name.isidentifier() and '/' not in module and \
        all(part.isidentifier() for part in module.split('.'))


def _names_a_class(spec: str) -> bool:
    """A class spec that is not also the name of a file here (a file of that name wins)."""
    return is_class_spec(spec) and not Path(spec).expanduser().exists()


# ------------------------------------------------------------------------------------------ a file

def file_key(task_id: str, question_type: str, noun: str) -> tuple[str, str, str]:
    """How a file's line and a question are matched: the task, the type, the noun in lower case ('' for a
    type that names no object)."""
    qtype = parse_question_type(question_type) or question_type
    return task_id, qtype, ' '.join(noun.split()).lower() if names_object(qtype) else ''


class AnswersFile:
    """A person's words from a JSON-lines file: one line per (task, question). A question the file does not
    hold is answered "I don't know." (the person was not asked it); `missing` counts them."""

    def __init__(self, path):
        self.path = Path(path).expanduser()
        try:
            raw = self.path.read_bytes()
        except OSError as exc:
            raise AnswersError(f'cannot read answers file {self.path}: {exc.strerror or exc}') from None
        self.sha256 = hashlib.sha256(raw).hexdigest()
        self.words: dict[tuple[str, str, str], str] = {}
        self.missing = 0
        seen: dict[tuple[str, str, str], int] = {}
        try:
            text = raw.decode('utf-8')
        except UnicodeDecodeError as exc:
            raise AnswersError(f'{self.path}: not UTF-8 text (byte {exc.start})') from None
        for number, line in enumerate(text.splitlines(), 1):
            if not line.strip():
                continue
            key, words = self._parse(line, number)
            if key in self.words and self.words[key] != words:
                raise AnswersError(f'{self.path}:{number}: a second answer to {key[1]} {key[2]!r} of {key[0]} '
                                   f'(the first at line {seen[key]}); one answer a question')
            self.words[key], seen[key] = words, number
        if not self.words:
            raise AnswersError(f'{self.path}: no answers in it (JSON lines: {{"task", "type", "noun", "answer"}})')

    def _parse(self, line: str, number: int) -> tuple[tuple[str, str, str], str]:
        where = f'{self.path}:{number}'
        try:
            entry = json.loads(line)
        except ValueError as exc:
            raise AnswersError(f'{where}: not JSON ({exc.msg} at column {exc.colno})') from None
        if not isinstance(entry, dict):
            raise AnswersError(f'{where}: a line is an object {{"task", "type", "noun", "answer"}}')
        unknown = sorted(set(entry) - set(FILE_KEYS))
        absent = [k for k in ('task', 'type', 'answer') if k not in entry]
        if unknown or absent:
            what = '; '.join(filter(None, [f'unknown keys {unknown}' if unknown else '',
                                           f'missing {absent}' if absent else '']))
            raise AnswersError(f'{where}: {what} (keys: {", ".join(FILE_KEYS)}; noun may be left out for direction)')
        bad = [k for k in FILE_KEYS if k in entry and not isinstance(entry[k], str)]
        if bad:
            raise AnswersError(f'{where}: {", ".join(bad)} must be text')
        qtype = parse_question_type(entry['type'])
        if qtype is None:
            raise AnswersError(f'{where}: unknown question type {entry["type"][:32]!r}; expected one of '
                               f'{", ".join(question_types())}')
        noun = entry.get('noun', '')
        if names_object(qtype) and not noun.strip():
            raise AnswersError(f'{where}: a {qtype} question names an object ("noun")')
        words = ' '.join(entry['answer'].split())
        if not words or len(words) > MAX_WORDS_CHARS:
            raise AnswersError(f'{where}: an answer is 1 to {MAX_WORDS_CHARS} characters of text')
        return file_key(entry['task'], qtype, noun), words

    @property
    def label(self) -> str:
        """The file as results record it: its name and its content's digest (two files never mix)."""
        return f'file-{self.path.stem}-{self.sha256[:8]}'

    def say(self, asked: Asked, content: AnswerContent) -> Optional[str]:
        words = self.words.get(file_key(asked.task_id, asked.question_type, asked.object_noun))
        if words is None:
            self.missing += 1
            return WITHHELD
        return words


# ------------------------------------------------------------------------------------------ any answerer

def class_label(spec: str) -> str:
    """A class answerer as results record it: 'package.module.ClassName' (no colon in a file name)."""
    return spec.replace(':', '.')


def load_answerer(spec: str):
    """The answerer `spec` names: an AnswersFile for a file, an instance of the class for
    package.module:ClassName; AnswersError saying what is wrong otherwise."""
    if not is_answerer_spec(spec):
        raise AnswersError(f'--answers {spec!r} is built in, not an answerer')
    if _names_a_class(spec):
        try:
            cls = load_class(spec, kind='answerer', methods=('say',))
            return cls()
        except ValueError as exc:
            raise AnswersError(str(exc)) from None
        except Exception as exc:        # its constructor is the user's code
            raise AnswersError(f'answerer {spec!r} could not be made: {exc!r}') from None
    if not Path(spec).expanduser().is_file():
        raise AnswersError(f'--answers {spec!r}: no such file, and not one of {", ".join(BUILT_IN)} or '
                           'package.module:ClassName')
    return AnswersFile(spec)


def answerer_label(spec: str, answerer=None) -> str:
    """What results record for the answerer `spec` (made from `answerer` when given)."""
    if isinstance(answerer, AnswersFile):
        return answerer.label
    if _names_a_class(spec):
        return class_label(spec)
    return AnswersFile(spec).label


def same_answerer(label: str, other: str) -> bool:
    """Whether two labels name one answerer: the same class, or files of the same content (renamed or not)."""
    if label.startswith('file-') and other.startswith('file-'):
        return label.rsplit('-', 1)[-1] == other.rsplit('-', 1)[-1]
    return label == other


def resolved_spec(spec: str) -> str:
    """The spec as another process (a node elsewhere) can load it: a file's absolute path."""
    if _names_a_class(spec):
        return spec
    return str(Path(spec).expanduser().resolve())


class Speaking:
    """An answerer in the oracle's place where it speaks: `apply(answer, task_id, noun)` (as
    swap.AnswerSwap's) gives the oracle's `answer` in the answerer's words. A refused answer stays refused
    and a withheld one withheld; an answerer that fails or returns something other than text raises
    AnswersError (a run must not go on with answers nobody gave)."""

    def __init__(self, answerer, label: str):
        if not callable(getattr(answerer, 'say', None)):
            raise AnswersError(f'answerer {label!r} has no say(asked, content)')
        self.answerer, self.label = answerer, label

    def apply(self, ans: Answer, task_id: str, object_noun: str) -> Answer:
        if not ans.valid or ans.text == WITHHELD:
            return ans
        qtype = parse_question_type(ans.question_type) or ans.question_type
        noun = object_noun if names_object(qtype) else ''
        asked = Asked(task_id, qtype, noun, question_text(qtype, noun))
        try:
            words = self.answerer.say(asked, answer_content(ans, qtype, noun))
        except Exception as exc:
            raise AnswersError(f'answerer {self.label} failed on {asked.text!r} ({task_id}): {exc!r}') from None
        if words is None:
            return ans
        if not isinstance(words, str):
            raise AnswersError(f'answerer {self.label} said {type(words).__name__} to {asked.text!r}, not text')
        words = ' '.join(words.split())
        if not words or len(words) > MAX_WORDS_CHARS:
            raise AnswersError(f'answerer {self.label} said {len(words)} characters to {asked.text!r} '
                               f'({task_id}); an answer is 1 to {MAX_WORDS_CHARS}')
        return replace(ans, text=words, reason='')


def speaking(spec: str) -> Optional[Speaking]:
    """The Speaking answerer of `--answers spec`, None for a built-in; AnswersError for a bad one."""
    if not is_answerer_spec(spec):
        return None
    answerer = load_answerer(spec)
    return Speaking(answerer, answerer_label(spec, answerer))


# ------------------------------------------------------------------------------------------ export

def export(results_path, out=None) -> dict:
    """The answers of a results file's dialogues as an answers file (to `out`, or stdout): {'answers',
    'tasks', 'repeated'}: a question asked again with other words keeps its first answer."""
    lines, first, repeated, tasks = [], {}, 0, set()
    for result in load_results(results_path):
        for qa in result.dialogue:
            if not qa.get('valid') or not qa.get('answer'):
                continue
            key = file_key(result.task_id, qa['type'], qa.get('noun', ''))
            if key in first:
                repeated += first[key] != qa['answer']
                continue
            first[key] = qa['answer']
            tasks.add(result.task_id)
            lines.append(json.dumps({'task': result.task_id, 'type': key[1], 'noun': qa.get('noun', '') if key[2]
                                     else '', 'answer': qa['answer']}))
    text = ''.join(line + '\n' for line in lines)
    if out is None:
        sys.stdout.write(text)
    else:
        Path(out).write_text(text)
    return {'answers': len(lines), 'tasks': len(tasks), 'repeated': repeated}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog='python -m dialfred_oracle.answerers',
                                 description='Answers files: export the answers of a results file.')
    sub = ap.add_subparsers(dest='command', required=True)
    ex = sub.add_parser('export', help='write the answers recorded in a results file as an answers file')
    ex.add_argument('results', type=Path, help='a results file of `launch eval` (its dialogues are read)')
    ex.add_argument('--out', type=Path, default=None, help='the answers file to write (default: stdout)')
    args = ap.parse_args(argv)
    try:
        counts = export(args.results, args.out)
    except (OSError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    print(json.dumps(counts), file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
