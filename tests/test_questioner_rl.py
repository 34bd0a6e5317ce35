"""Actor-critic pieces of the questioner's RL fine-tuning (dialfred_questioner.rl, no ROS).

Claims: returns are discounted within an episode and restart at its end; the paper's rewards per
decision (and Fixed-1's); on a toy bandit the critic's loss falls as it learns (its gradient is not
cut off, the original's bug) and the policy gradient raises the probability of the rewarded action.
"""

from __future__ import annotations

import pytest
import torch

from dialfred_questioner.rl import Rewards, actor_critic_loss, discounted_returns


def test_returns_are_discounted_within_episodes_and_restart_at_their_end():
    r = discounted_returns([1.0, 0.0, 2.0, 1.0], [False, True, False, True], gamma=0.5)
    assert r.tolist() == [1.0, 0.0, 2.5, 1.0]
    with pytest.raises(ValueError, match='complete episodes'):
        discounted_returns([1.0], [False], 0.9)


def test_the_papers_rewards_per_decision():
    rw = Rewards()
    assert rw.of_decision(asked=True, valid=False, performer_steps=5, success=False) == pytest.approx(-0.2)
    assert rw.of_decision(asked=False, valid=True, performer_steps=3, success=True) == pytest.approx(0.97)
    assert Rewards.fixed_1().of_decision(True, True, 1, False) == pytest.approx(-0.012)


def test_on_a_toy_bandit_the_critic_learns_and_the_policy_moves_to_the_rewarded_action():
    torch.manual_seed(0)
    state = torch.ones(64, 3)
    actor = torch.nn.Linear(3, 2)
    critic = torch.nn.Linear(3, 1)
    opt = torch.optim.SGD([*actor.parameters(), *critic.parameters()], lr=0.1)
    p_before = torch.softmax(actor(state[:1]), -1)[0, 1].item()
    critic_losses = []
    for _ in range(60):
        logp_all = torch.log_softmax(actor(state), -1)
        actions = torch.multinomial(logp_all.exp(), 1)[:, 0]
        rewards = (actions == 1).float()                         # action 1 pays 1, action 0 nothing
        returns = discounted_returns(rewards.tolist(), [True] * len(rewards), gamma=0.9)
        values = critic(state).squeeze(-1)
        entropy = -(logp_all.exp() * logp_all).sum(-1)
        loss, parts = actor_critic_loss(logp_all.gather(1, actions[:, None])[:, 0], values, entropy, returns)
        opt.zero_grad()
        loss.backward()
        assert critic.weight.grad is not None and critic.weight.grad.abs().sum() > 0
        opt.step()
        critic_losses.append(parts['critic'])
    assert sum(critic_losses[-10:]) < sum(critic_losses[:10])
    assert torch.softmax(actor(state[:1]), -1)[0, 1].item() > p_before + 0.2
