"""Every questioner by name, in one place (no ROS): what `--questioner` of the evaluation and the
questioner node's `questioner` parameter accept.

- 'random', 'all', 'confusion': the baselines that need no training (`baselines.QUESTIONERS`);
- 'every:TYPES', 'every-N:TYPES': every question of those types before every (N-th) action
  (`baselines.ScheduleQuestioner`);
- a shipped learned questioner (`policy.SHIPPED_LEARNED`: 'pretrained', 'rl-begin', 'rl-anytime', ...):
  its checkpoint from the package's checkpoints folder, greedy, with the timing it was trained with;
- 'learned:PATH': the learned questioner of any questioner checkpoint, the same way;
- 'package.module:ClassName': a class of yours with reset(task, seed), ask(observation, step),
  hear(qa), constructed without arguments.

It sits above `baselines` and `policy` (which imports `baselines`), so that neither imports the other
back; torch (with `policy`) is imported only for a name that is not a baseline's.
"""

from __future__ import annotations

import difflib

from dialfred_sim.agents import load_class
from dialfred_sim.protocol import Questioner

from . import baselines


def make_questioner(name: str) -> Questioner:
    """A new questioner (one per worker: questioners keep per-episode state) of `name` (see the
    module's doc). ValueError for an unknown name, a missing or damaged checkpoint, a bad class."""
    if name in baselines.QUESTIONERS:
        return baselines.QUESTIONERS[name]()
    schedule = baselines.schedule_questioner(name)
    if schedule is not None:
        return schedule
    # lazy: pybullet, torch, which the rest of this module does without
    from .policy import SHIPPED_LEARNED, learned_checkpoint, learned_questioner
    if learned_checkpoint(name) is not None:
        return learned_questioner(name)
    if ':' not in name:
        near = difflib.get_close_matches(name, [*baselines.QUESTIONERS, *SHIPPED_LEARNED], n=1, cutoff=0.5)
        raise ValueError(f'unknown questioner {name!r}{f" (did you mean {near[0]}?)" if near else ""}; known: '
                         f'{", ".join(baselines.QUESTIONERS)}, every[-N]:TYPES, {", ".join(SHIPPED_LEARNED)}, learned:PATH, or '
                         'package.module:ClassName')
    return load_class(name, 'questioner', ('reset', 'ask', 'hear'))()
