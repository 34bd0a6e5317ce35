"""The one episode loop (dialfred_sim.episode), alone: a scripted server stands in for the simulator and the
oracle, so each rule is seen without either. Claims: the requests come in the rule's order (reset, the
agent's questions until it asks none, one action, its step); the agent is reset after the simulator with
the task the reset names (or the one it is told); answers reach the agent and the observers; more than
max_questions in a row, a refused action or a request with no reply end the episode with an error; the
simulator's end (success, Stop, failures, the step limit) ends it with the matching reason; observers see
each event in order, and the episode's end once."""

from __future__ import annotations

import pytest

from dialfred_sim.episode import RESET, Ask, EpisodeObserver, Failed, Reset, SimReply, Step, play, run
from dialfred_sim.protocol import QA, Question


class ScriptedAgent:
    """Asks the questions of `asks` before each action (a list per action), then plays `actions` in turn."""

    def __init__(self, actions, asks=()):
        self.actions, self.asks = list(actions), [list(q) for q in asks]
        self.log = []

    def reset(self, task, seed):
        self.log.append(('reset', task, seed))
        self.turn = 0

    def ask(self, observation):
        pending = self.asks[self.turn] if self.turn < len(self.asks) else []
        return Question(pending.pop(0)) if pending else None

    def hear(self, qa):
        self.log.append(('hear', qa.question.question_type, qa.answer))

    def act(self, observation):
        self.log.append(('act', observation))
        name = self.actions[self.turn]
        self.turn += 1
        return name, -1, -1


class Server:
    """Answers requests as a simulator whose episode ends after `end_at` steps (terminated, `success`),
    and as an oracle that answers every question 'yes'; records every request."""

    def __init__(self, end_at=3, success=False, refuse_step=None, lose=None):
        self.end_at, self.success, self.refuse_step, self.lose = end_at, success, refuse_step, lose
        self.requests, self.steps = [], 0

    def __call__(self, request):
        self.requests.append(request)
        if self.lose is not None and isinstance(request, self.lose):
            return Failed('no reply')
        if isinstance(request, Reset):
            return SimReply(observation='frame0', task='the task', goal_conditions_total=2)
        if isinstance(request, Ask):
            return QA(request.question, True, 'yes')
        if self.refuse_step == self.steps + 1:
            return SimReply(ok=False, error='unknown action', step_count=self.steps)
        self.steps += 1
        done = self.steps >= self.end_at
        return SimReply(observation=f'frame{self.steps}', step_count=self.steps, goal_conditions_met=int(done),
                        goal_conditions_total=2, terminated=done, success=done and self.success)


class Log(EpisodeObserver):
    def __init__(self):
        self.events = []

    def on_started(self, state, reply):
        self.events.append('started')

    def on_question(self, state, qa, step):
        self.events.append(f'qa@{step}')

    def on_action(self, state, action, x, y):
        self.events.append(action)

    def on_stepped(self, state, reply, action, x, y):
        self.events.append(f'stepped{reply.step_count}')

    def on_ended(self, state):
        self.events.append(f'ended:{state.end_reason}')


def test_requests_come_reset_then_questions_until_none_then_an_action_and_its_step():
    agent = ScriptedAgent(['MoveAhead', 'RotateLeft', 'Stop'], asks=[['location', 'direction'], [], ['appearance']])
    server, log = Server(end_at=3, success=True), Log()
    state = run(play(agent, seed=7, observers=[log]), server)
    kinds = [type(r).__name__ + (f':{r.question.question_type}' if isinstance(r, Ask) else '') for r in server.requests]
    assert kinds == ['Reset', 'Ask:location', 'Ask:direction', 'Step', 'Step', 'Ask:appearance', 'Step']
    assert server.requests[0] is RESET and [r.step for r in server.requests if isinstance(r, Ask)] == [0, 0, 2]
    assert agent.log[0] == ('reset', 'the task', 7)              # after the simulator, with the task it named
    assert ('hear', 'location', 'yes') in agent.log
    assert [e for e in agent.log if e[0] == 'act'] == [('act', 'frame0'), ('act', 'frame1'), ('act', 'frame2')]
    assert log.events == ['started', 'qa@0', 'qa@0', 'MoveAhead', 'stepped1', 'RotateLeft', 'stepped2', 'qa@2', 'Stop',
                          'stepped3', 'ended:success']
    assert (state.success, state.steps, state.questions, state.goal_conditions_met) == (True, 3, 3, 1)
    assert [qa.question.question_type for qa in state.dialogue] == ['location', 'direction', 'appearance']


def test_the_agent_is_told_the_task_it_is_told_and_asks_nothing_without_asks():
    agent = ScriptedAgent(['Stop'], asks=[['location']])
    server = Server(end_at=1)
    state = run(play(agent, seed=0, told='the public view', asks=False), server)
    assert agent.log[0] == ('reset', 'the public view', 0)
    assert not any(isinstance(r, Ask) for r in server.requests) and state.questions == 0
    assert state.end_reason == 'stop' and not state.success


def test_more_than_max_questions_in_a_row_ends_the_episode_with_an_error_naming_the_asker():
    agent = ScriptedAgent(['Stop'], asks=[['direction'] * 5])
    state = run(play(agent, seed=0, max_questions=3, asker='questioner'), Server())
    assert state.questions == 3 and state.end_reason == 'error'
    assert state.error == 'the questioner asked more than 3 questions without acting'


@pytest.mark.parametrize('server, error', [
    (Server(refuse_step=2), 'unknown action'),          # the simulator refuses the second action
    (Server(lose=Step), 'no reply'),                    # a step with no usable reply
    (Server(lose=Ask), 'no reply'),                     # a question with no usable reply
    (Server(lose=Reset), 'no reply'),                   # the reset itself
])
def test_a_refused_action_or_a_lost_reply_ends_the_episode_with_an_error(server, error):
    agent = ScriptedAgent(['MoveAhead'] * 5, asks=[['location']])
    log = Log()
    state = run(play(agent, seed=0, observers=[log]), server)
    assert state.end_reason == 'error' and state.error == error and not state.success
    assert log.events.count('ended:error') == 1 and log.events[-1] == 'ended:error'


@pytest.mark.parametrize('actions, success, reason', [
    (['MoveAhead', 'Stop'], False, 'stop'),
    (['MoveAhead', 'PickupObject'], True, 'success'),
])
def test_the_simulators_end_ends_the_episode_with_the_matching_reason(actions, success, reason):
    state = run(play(ScriptedAgent(actions), seed=0), Server(end_at=2, success=success))
    assert (state.end_reason, state.success, state.steps) == (reason, success, 2)
