"""The question types, one module each (`location`, `appearance`, `direction`): the oracle's rule and
the answer's wording, the words read back, the check against the ground truth, and the synthetic
annotator's rule. `base` holds the interface (`OracleQuestion`) and the registry; importing this
package registers the paper's three. A type of one's own is one module with an `OracleQuestion`
subclass and `register(...)` (docs/questioner.md, "Adding a question type")."""

from .base import (DIRECTION_BINS, Answer, AnswerContent, OracleQuestion, direction_bin, oracle_question,
                   oracle_questions, register, unregister)
from . import appearance, direction, location  # noqa: F401  (each registers its type, in the paper's order)

__all__ = ['DIRECTION_BINS', 'Answer', 'AnswerContent', 'OracleQuestion', 'direction_bin', 'oracle_question',
           'oracle_questions', 'register', 'unregister']
