"""Actor-critic pieces of the questioner's RL fine-tuning (DialFRED paper, "Questioner fine-tuning
using RL"; no ROS). The rollouts and the training loop (`finetune.py`) build on these.

The paper's MDP: a decision of the questioner is a step (ask a question, or none); the performer
then acts until the questioner's next chance. Rewards (`Rewards`): +1.0 for success, -0.01 per
performer step, -0.05 per question, -0.1 per invalid question (Fixed-1 in the paper: -0.002 and
-0.01). The original's actor-critic wrapped the critic's value in a new leaf tensor, so the critic
never got a gradient, and summed rewards and log-probabilities as running totals. Here:

- `discounted_returns`: R_t = r_t + gamma R_{t+1} within an episode, restarting at its end;
- `actor_critic_loss`: advantages A_t = R_t - V(s_t) with the value detached for the policy term
  (-A_t log pi(a_t|s_t)), the critic regressed on R_t (its gradient reaches the critic), an entropy
  bonus; advantages may be normalised over the batch;
- `group_baseline`: a baseline from the other episodes of the same task and start (a leave-one-out
  mean of their returns). The env and the frozen performer are deterministic, so episodes of one
  task from one seed differ only by the questioner's choices: this baseline removes the task's
  difficulty from the advantage, which the critic, seeing only the instruction and the dialogue so
  far, the frame and the step, cannot do well (measured in docs/figures.md). It does not depend on the episode's own
  actions, so the policy gradient stays unbiased.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import torch
import torch.nn.functional as F


@dataclass(frozen=True)
class Rewards:
    success: float = 1.0
    step: float = -0.01              # per performer step
    question: float = -0.05          # per question asked
    invalid: float = -0.1            # per question the oracle could not answer

    @classmethod
    def fixed_1(cls) -> 'Rewards':
        """The paper's penalties for asking at every step (Table IV, Fixed 1)."""
        return cls(question=-0.002, invalid=-0.01)

    def of_episode(self, success: bool, steps: int, questions: int, invalid_questions: int) -> float:
        """An episode's undiscounted return: the sum of its decisions' rewards."""
        return (self.success * bool(success) + self.step * steps + self.question * questions
                + self.invalid * invalid_questions)

    def of_decision(self, asked: bool, valid: bool, performer_steps: int, success: bool) -> float:
        """The reward of one questioner decision: its question's cost, the performer steps until the
        next decision, and the success bonus if the episode ended in success there."""
        r = self.step * performer_steps
        if asked:
            r += self.question + (0.0 if valid else self.invalid)
        return r + (self.success if success else 0.0)


def discounted_returns(rewards: Sequence[float], episode_ends: Sequence[bool], gamma: float) -> torch.Tensor:
    """R_t = r_t + gamma * R_{t+1}, with R restarting after each step where `episode_ends` is True
    (the last step of a batch must end an episode: there is no bootstrap value here)."""
    if len(rewards) != len(episode_ends):
        raise ValueError(f'{len(rewards)} rewards but {len(episode_ends)} episode-end flags')
    if rewards and not episode_ends[-1]:
        raise ValueError('the last decision of a batch must end its episode (complete episodes only)')
    out = [0.0] * len(rewards)
    running = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        if episode_ends[t]:
            running = 0.0
        running = rewards[t] + gamma * running
        out[t] = running
    return torch.tensor(out, dtype=torch.float32)


def actor_critic_loss(log_probs: torch.Tensor, values: torch.Tensor, entropies: torch.Tensor,
                      returns: torch.Tensor, value_weight: float = 0.5, entropy_weight: float = 0.01,
                      normalise: bool = True, baseline: Optional[torch.Tensor] = None) -> tuple[torch.Tensor, dict]:
    """(loss, parts) over a batch of decisions: log pi(a_t|s_t), V(s_t), the policy's entropy at s_t,
    and the returns R_t. The policy term uses A_t = R_t - V(s_t) with V detached (or R_t - baseline_t
    when a `baseline` is given, e.g. `group_baseline`); the critic term is the squared error of V(s_t)
    against R_t, so its gradient flows into the critic either way."""
    advantages = returns - (values.detach() if baseline is None else baseline)
    if normalise and advantages.numel() > 1:
        advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
    policy = -(advantages * log_probs).mean()
    critic = F.mse_loss(values, returns)
    entropy = entropies.mean()
    loss = policy + value_weight * critic - entropy_weight * entropy
    return loss, {'policy': float(policy.detach()), 'critic': float(critic.detach()),
                  'entropy': float(entropy.detach()), 'advantage_mean': float((returns - values.detach()).mean())}


def group_baseline(first_returns: Sequence[float], groups: Sequence[int], decisions: Sequence[int]) -> torch.Tensor:
    """A baseline per decision: for each episode (its return from its first decision, its group, its
    number of decisions), the mean first-decision return of the other episodes of its group, repeated
    for each of its decisions; 0.0 for an episode alone in its group."""
    if not len(first_returns) == len(groups) == len(decisions):
        raise ValueError('first_returns, groups and decisions must have one entry per episode')
    totals: dict = {}
    for g, r in zip(groups, first_returns):
        n, s = totals.get(g, (0, 0.0))
        totals[g] = (n + 1, s + r)
    out = []
    for g, r, d in zip(groups, first_returns, decisions):
        n, s = totals[g]
        out.extend([(s - r) / (n - 1) if n > 1 else 0.0] * d)
    return torch.tensor(out, dtype=torch.float32)
