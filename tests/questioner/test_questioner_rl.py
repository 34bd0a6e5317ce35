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


def test_the_group_baseline_is_the_mean_of_the_other_episodes_of_the_group():
    from dialfred_questioner.rl import group_baseline
    b = group_baseline([1.0, 0.0, 0.5, 0.2], groups=[0, 0, 0, 1], decisions=[2, 1, 1, 3])
    assert b.tolist() == pytest.approx([0.25, 0.25, 0.75, 0.5, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError):
        group_baseline([1.0], [0, 1], [1])


def test_with_a_group_baseline_the_policy_moves_to_the_better_action_of_the_same_task():
    """Two tasks, one easy (return 1 whatever is done), one hard (return 0 whatever); asking adds
    +0.2 on both. Against the group baseline only the asking matters, and the policy learns to ask."""
    from dialfred_questioner.rl import actor_critic_loss, group_baseline
    torch.manual_seed(0)
    logits = torch.zeros(2, requires_grad=True)      # [no question, question]
    opt = torch.optim.SGD([logits], lr=2.0)
    for _ in range(150):
        p = torch.softmax(logits, 0)
        actions = torch.multinomial(p.detach().expand(8, 2), 1)[:, 0]
        tasks = torch.tensor([0, 0, 0, 0, 1, 1, 1, 1])
        returns = (tasks == 0).float() + 0.2 * actions.float()
        base = group_baseline(returns.tolist(), tasks.tolist(), [1] * 8)
        loss, _ = actor_critic_loss(torch.log_softmax(logits, 0)[actions], torch.zeros(8), torch.zeros(8),
                                    returns, value_weight=0.0, entropy_weight=0.0, normalise=False, baseline=base)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert torch.softmax(logits, 0)[1] > 0.9
