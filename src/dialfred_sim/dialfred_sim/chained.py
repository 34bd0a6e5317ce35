"""The chained protocol, DialFRED's own challenge test: an episode's tasks in order, each played from the
state the agent's own actions left (no ROS).

Under the paper's protocol (`expert`, the default) every task starts from the expert's state at its first
action, and the simulator ends it at success. Under `chained`:

- an episode (`ChainedEpisode`: the tasks of a split cut from one expert demonstration, in order) is
  reset once, to its first task's start (`DialfredEnv.reset(options={'task': t, 'protocol': 'chained'})`);
- every later task starts where the last one ended (`DialfredEnv.continue_task`), with its own
  instruction (its `PublicTask`), its step and failure counts at 0;
- a task ends only with the agent's Stop or at its limits (1,000 steps, 10 failed actions), and is judged
  in the state at that moment: the agent is never told it succeeded;
- a task whose whole goal already holds when it starts is played but scores as not done ("held at
  start": `EpisodeResult.held_at_start`), so that doing nothing never scores; GC counts the conditions
  that did not hold at its start, as under the expert protocol;
- the oracle answers about the current task in the world as it is (the simulator's ground truth follows
  the task), the expert plays each task's whole recorded stretch of the demonstration and then stops
  (`expert_reference`), and an agent that is `protocol.Continuing` carries what it knows over from one
  task to the next; any other agent is reset before every task.

`chain_episodes` groups the (index, task) pairs an evaluation selected into episodes; `episode_metrics`
gives the per-episode figures of a chained run's results.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Iterable, Optional, Sequence

from .protocol import DEFAULT_PROTOCOL, PROTOCOLS


def check_protocol(protocol: str) -> str:
    """`protocol` if it is one of protocol.PROTOCOLS; ValueError naming them otherwise."""
    if protocol not in PROTOCOLS:
        raise ValueError(f'unknown protocol {protocol!r}: expected one of {", ".join(PROTOCOLS)}')
    return protocol


@dataclass(frozen=True)
class ChainedEpisode:
    """One chained episode: its episode id and its tasks in order, each with its index in the split
    (which seeds its agent, as under the expert protocol)."""

    episode_id: str
    tasks: tuple

    @property
    def task_ids(self) -> list[str]:
        return [t.task_id for _, t in self.tasks]


def episode_key(task) -> str:
    """The chained episode a task belongs to: its episode's id ('valid_unseen/ep000003': split and number)."""
    return task.episode.episode_id


def chain_episodes(selected: Iterable[tuple]) -> list[ChainedEpisode]:
    """The (index, task) pairs of `selected` grouped into chained episodes, in the order their first tasks
    come, each episode's tasks in the order they were cut from its demonstration. ValueError when an
    episode's tasks are not one unbroken run of it (a task missing in the middle or out of order):
    chaining plays an episode from its first task on."""
    groups: dict[str, list] = {}
    for index, task in selected:
        groups.setdefault(episode_key(task), []).append((index, task))
    episodes = []
    for key, tasks in groups.items():
        for (_, a), (_, b) in zip(tasks, tasks[1:]):
            if b.start < a.primitives[-1].end:
                raise ValueError(f'episode {key}: task {b.task_id} does not follow {a.task_id} in its demonstration')
        indices = [k for k, _ in tasks]
        if indices != list(range(indices[0], indices[0] + len(indices))):
            raise ValueError(f'episode {key}: its tasks are not consecutive in the split (indices {indices}); '
                             'a chained run plays every task of an episode from its first')
        episodes.append(ChainedEpisode(key, tuple(tasks)))
    return episodes


def segment(tasks: Sequence, k: int) -> tuple[int, int]:
    """The expert's actions [start, end) for task k of a chained episode's `tasks`: from where the task
    before it left off (its own start for the first) to the end of its last step, so that the stretches
    of an episode's tasks join up and the expert walks the whole demonstration."""
    task = tasks[k]
    start = task.start if k == 0 else tasks[k - 1].primitives[-1].end
    return start, task.primitives[-1].end


def expert_reference(tasks: Sequence, k: int):
    """Task k as the privileged expert is told it under chaining: the same task with its stretch of the
    demonstration (`segment`), which the expert plays before its Stop."""
    start, end = segment(tasks, k)
    return replace(tasks[k], start=start, end=end)


def reference_length(tasks: Sequence, k: int) -> int:
    """L* of PWSR for task k under chaining: the expert's actions over its stretch and its Stop."""
    start, end = segment(tasks, k)
    return end - start + 1


def is_chained(protocol: Optional[str]) -> bool:
    return (protocol or DEFAULT_PROTOCOL) == 'chained'


def episode_metrics(results: Iterable) -> dict:
    """Per-episode figures of a chained run's results (EpisodeResult lines with `episode_id`):
    {'episodes', 'all_succeeded' (percent of episodes whose every task succeeded), 'in_order' (mean tasks
    done in order before the first failure), 'tasks_per_episode', 'questions_per_episode', 'held_at_start'
    (tasks whose goal held when they began), 'episodes_with_held'}. The tasks of an episode count in
    the order they were played (their task ids)."""
    by_episode: dict[str, list] = {}
    for r in results:
        by_episode.setdefault(r.episode_id, []).append(r)
    n = len(by_episode)
    if n == 0:
        return {'episodes': 0, 'all_succeeded': 0.0, 'in_order': 0.0, 'tasks_per_episode': 0.0,
                'questions_per_episode': 0.0, 'held_at_start': 0, 'episodes_with_held': 0}
    in_order = []
    for rows in by_episode.values():
        rows.sort(key=lambda r: r.task_id)
        done = 0
        for r in rows:
            if not r.success:
                break
            done += 1
        in_order.append(done)
    held = [sum(r.held_at_start for r in rows) for rows in by_episode.values()]
    return {
        'episodes': n,
        'all_succeeded': 100.0 * sum(all(r.success for r in rows) for rows in by_episode.values()) / n,
        'in_order': sum(in_order) / n,
        'tasks_per_episode': sum(len(rows) for rows in by_episode.values()) / n,
        'questions_per_episode': sum(r.questions for rows in by_episode.values() for r in rows) / n,
        'held_at_start': sum(held),
        'episodes_with_held': sum(h > 0 for h in held),
    }
