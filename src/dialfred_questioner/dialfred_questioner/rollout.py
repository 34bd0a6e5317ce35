"""Episodes of a questioner with a frozen performer in one process (no ROS): the RL fine-tuning's
rollouts (the paper's MDP, "Questioner fine-tuning using RL").

`play_rollout(env, performer, policy, task_id, seed, timing, rewards)` resets `env` (a DialfredEnv) to the
task, and before each performer action where `timing` gives the questioner a chance, asks `policy`
for a question or none; the in-process oracle (`dialfred_oracle.in_process.answer_now`, the node's rules)
answers and the performer hears it, as the graph does through `/questioner/ask` and `/oracle/answer`.
The performer is handed the observation as the graph's Observation carries it (the RGB frame and
whether the last action succeeded, which the map performer dead-reckons from).
Each chance is a `Decision` with its reward (`rl.Rewards`: the question's cost, the performer steps
until the next chance, the success bonus at the end; steps before the first chance, which only the
confusion timing can have, are charged to nobody), and `record`: whatever the policy returned to
keep for its update (its inputs, so log-probabilities can be recomputed).

`play_chained_rollout` plays the tasks of a chained episode (dialfred_sim.chained) in order in one world, each
task an episode of its own for the MDP (its own decisions, rewards and success), each later one from the
state the last one left; the performer carries on where it can (protocol.Continuing).

Timings (`Timing`): `begin` (a chance at step 0 only: RL begin), `anytime` with a `gap` (a chance at
steps 0, gap, 2 gap, ...: RL anytime, the paper's Fixed 1 / 5 / 10), and `confusion` (a chance
before each action whose top-2 action-probability gap is below `epsilon`: the MC setting).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Optional

from dialfred_oracle.in_process import EnvServer
from dialfred_performer.preprocess import AskedQA
from dialfred_sim.episode import EpisodeObserver, run
from dialfred_sim.episode import play as play_episode
from dialfred_sim.protocol import QA, Continuing, Question, top2_gap
from dialfred_sim.tasks import get_task

from .rl import Rewards

TIMINGS = ('begin', 'anytime', 'confusion')
# policy(rgb, task, dialogue (AskedQA of dialfred_performer.preprocess so far), step) -> (Question or None, record)
Policy = Callable[[Any, Any, list, int], tuple[Optional[Question], Any]]


@dataclass(frozen=True)
class Timing:
    mode: str = 'anytime'
    gap: int = 5
    epsilon: float = 0.5

    def __post_init__(self):
        if self.mode not in TIMINGS:
            raise ValueError(f'timing must be one of {TIMINGS}, got {self.mode!r}')
        if self.gap < 1:
            raise ValueError(f'gap must be at least 1, got {self.gap}')
        if not 0.0 <= self.epsilon <= 1.0:
            raise ValueError(f'epsilon must be in [0, 1], got {self.epsilon}')

    def chance(self, step: int, performer, observation) -> bool:
        if self.mode == 'begin':
            return step == 0
        if self.mode == 'anytime':
            return step % self.gap == 0
        return top2_gap(performer.action_probabilities(observation)) < self.epsilon


@dataclass
class Decision:
    step: int
    question: Optional[Question]
    valid: bool = True
    record: Any = None
    reward: float = 0.0


@dataclass
class Episode:
    task_id: str
    seed: int
    success: bool = False
    steps: int = 0
    end: str = ''
    decisions: list[Decision] = field(default_factory=list)
    dialogue: list[QA] = field(default_factory=list)
    asked_at: list[int] = field(default_factory=list)     # the step of each QA of `dialogue`

    @property
    def questions(self) -> int:
        return sum(d.question is not None for d in self.decisions)

    @property
    def invalid_questions(self) -> int:
        return sum(d.question is not None and not d.valid for d in self.decisions)

    @property
    def rewards(self) -> list[float]:
        return [d.reward for d in self.decisions]


class RolloutAgent(EpisodeObserver):
    """The frozen performer with the questioner being trained, as the episode loop's dialogue agent: at
    each chance `timing` gives (at most one a step), `policy` decides on a question or none; each chance
    is a `Decision` of `episode`, whose rewards this observer adds up as the steps go by."""

    def __init__(self, performer, policy: Policy, timing: Timing, rewards: Rewards, episode: 'Episode'):
        self.performer, self.policy, self.timing, self.rewards, self.episode = performer, policy, timing, rewards, episode
        self.steps_since = 0
        self.had_chance = False        # this step's chance was given (asked or not)

    def reset(self, task, seed: int) -> None:
        self.task = task
        self.performer.reset(task, seed)

    def carry_on(self, task, seed: int) -> None:
        """The next task of a chained episode: the performer carries on if it can, else starts afresh."""
        self.task = task
        if isinstance(self.performer, Continuing):
            self.performer.carry_on(task, seed)
        else:
            self.performer.reset(task, seed)

    def ask(self, observation) -> Optional[Question]:
        episode = self.episode
        if self.had_chance:
            return None
        self.had_chance = True
        if not self.timing.chance(episode.steps, self.performer, observation):
            return None
        if episode.decisions:
            episode.decisions[-1].reward += self.rewards.step * self.steps_since
        self.steps_since = 0
        asked = [AskedQA(qa, t) for qa, t in zip(episode.dialogue, episode.asked_at)]
        question, record = self.policy(observation.rgb, self.task, asked, episode.steps)
        episode.decisions.append(Decision(episode.steps, question, record=record))
        return question

    def hear(self, qa: QA) -> None:
        decision = self.episode.decisions[-1]
        decision.valid = qa.valid
        decision.reward += self.rewards.question + (0.0 if qa.valid else self.rewards.invalid)
        self.episode.dialogue.append(qa)
        self.episode.asked_at.append(self.episode.steps)
        self.performer.hear(qa)

    def act(self, observation):
        self.had_chance = False
        return self.performer.act(observation)

    def on_stepped(self, state, reply, action: str, x: int, y: int) -> None:
        self.episode.steps += 1
        self.steps_since += 1
        self.episode.success = bool(reply.success)


def play_rollout(env, performer, policy: Policy, task_id: str, seed: int, timing: Timing, rewards: Rewards = Rewards(),
         perturbation=None) -> Episode:
    """One episode of `task_id`; see the module's doc."""
    return _play(env, performer, policy, get_task(task_id), seed, timing, rewards, perturbation)


def play_chained_rollout(env, performer, policy: Policy, tasks: list, seeds: list[int], timing: Timing,
                         rewards: Rewards = Rewards(), perturbation=None) -> list[Episode]:
    """The tasks of one chained episode (dialfred_sim.chained: `tasks` in order, each with its seed), one
    Episode each; see the module's doc."""
    return [_play(env, performer, policy, task, seed, timing, rewards, perturbation, chained=True, continues=k > 0)
            for k, (task, seed) in enumerate(zip(tasks, seeds))]


def _play(env, performer, policy: Policy, task, seed: int, timing: Timing, rewards: Rewards, perturbation,
          chained: bool = False, continues: bool = False) -> Episode:
    episode = Episode(task.task_id, seed)
    agent = RolloutAgent(performer, policy, timing, rewards, episode)
    server = EnvServer(env, task, perturbation, with_depth=False, with_segmentation=False,    # RGB, as evaluations
                       protocol='chained' if chained else 'expert', continues=continues)
    state = run(play_episode(agent, seed=seed, told=task.public(), observers=[agent], carry_on=continues), server)
    if state.end_reason == 'error':
        raise RuntimeError(f'{task.task_id}: {state.error}')
    if episode.decisions:
        episode.decisions[-1].reward += rewards.step * agent.steps_since + (rewards.success if episode.success else 0.0)
    episode.end = 'success' if episode.success else ('max_steps' if state.end_reason == 'max_steps' else 'ended')
    return episode
