"""The expert never walks inside an interaction: its go-to ends where what follows needs at most a look up
or down, a closed container's contents and a put's landing spot included (no ROS)."""

from __future__ import annotations

import pytest

from dialfred_sim.env import DialfredEnv
from dialfred_sim.tasks import load_split
from dialfred_sim.tasks.expert import MARGIN, TILT, Expert, ExpertFailed
from dialfred_sim.tasks.goals import is_reachable

from helpers import first_of, reset, spawn_held, spawn_on
from world_helpers import clear_small_objects

LOOKS = ('LookUp', 'LookDown')


@pytest.fixture(scope='module')
def env():
    e = DialfredEnv(resolution=128)
    yield e
    e.close()


def _sees(env, object_id: str) -> bool:
    _, depth, seg = env.world.render()
    return is_reachable(env.world, object_id, depth, seg, MARGIN)


@pytest.mark.parametrize('split', ['valid_seen', 'valid_unseen'])
def test_no_interaction_of_the_expert_walks_or_turns(split):
    """Every object primitive of every task is at most a few looks and then its one interaction."""
    walking = []
    for task in load_split(split):
        first = task.primitives[0].start
        for p in task.primitives:
            if p.kind == 'goto':
                continue
            actions = [a.action for a in task.expert_actions[p.start - first:p.end - first]]
            if any(a not in LOOKS for a in actions[:-1]) or actions[-1] in LOOKS:
                walking.append((task.task_id, p.kind, actions))
    assert walking == [], f'{len(walking)} interactions walk, the first: {walking[:3]}'


@pytest.mark.parametrize('split', ['valid_seen', 'valid_unseen'])
def test_every_go_to_walks_as_alfreds_planner_does(split):
    """Each go-to of each episode tilts the camera to 45 degrees down, walks (moves and turns only) and
    then looks to its end pitch, as ALFRED's `Graph.navigate_to_goal` does."""
    wrong, gotos = [], 0
    episodes = {id(t.episode): t.episode for t in load_split(split)}.values()
    for episode in episodes:
        for p in episode.primitives:
            if p.kind != 'goto':
                continue
            gotos += 1
            actions = [a.action for a in episode.actions[p.start:p.end]]
            pitch = episode.poses[p.start][3]
            n = round(abs(TILT - pitch) / 15)
            tilt, walk = actions[:n], actions[n:]
            while walk and walk[-1] in LOOKS:
                walk.pop()
            if tilt != ['LookDown' if pitch < TILT else 'LookUp'] * n or any(a in LOOKS for a in walk):
                wrong.append((episode.episode_id, pitch, actions))
    assert gotos > 700 and wrong == [], f'{len(wrong)} of {gotos} go-tos are not tilt, walk, look: {wrong[:3]}'


def test_a_go_to_for_a_put_into_the_fridge_ends_where_the_put_lands_in_view(env):
    """FloorPlan10's designated pose for its fridge is beside it: the fridge shows, its inside does not.
    A go-to that is to put something in ends in front of it instead, and the put lands in view."""
    reset(env, 'FloorPlan10', 0)
    clear_small_objects(env)
    cup = spawn_held(env, 'Cup')
    fridge = first_of(env, 'Fridge').object_id
    e = Expert(env.world)
    beside, _ = e.find_pose([fridge])
    facing, _ = e.find_pose([fridge], put=cup.object_id)
    assert beside != facing
    start = e.pose()
    e._set_pose(beside)
    assert not e._ready_inside([fridge], [], cup.object_id)
    e._set_pose(start)

    e.goto(fridge, [fridge], put=cup.object_id)
    assert e.pose() == facing
    e.act('open', fridge)
    e.act('put', cup.object_id, fridge)
    assert env.world.objects[cup.object_id].parent == fridge
    assert _sees(env, cup.object_id)
    e.act('close', fridge)
    e.act('open', fridge)
    e.act('pickup', cup.object_id)       # from where the go-to ended: no walking
    assert env.world.held == cup.object_id
    assert [a.action for a in e.actions[-5:]] == ['Open', 'Put', 'Close', 'Open', 'Pickup']


def test_a_fetch_from_a_closed_cabinet_ends_where_its_contents_show_once_open(env):
    reset(env, 'FloorPlan10', 0)
    clear_small_objects(env)
    w = env.world
    cabinets = sorted((o for o in w.objects.values() if o.type_name == 'Cabinet' and o.spec.surfaces),
                      key=lambda o: o.object_id)
    found = 0
    for cab in cabinets:
        cup = spawn_on(env, 'Cup', cab.object_id)
        e = Expert(w)
        try:
            e.goto(cab.object_id, [cab.object_id], inside=[cup.object_id])
        except ExpertFailed:       # no pose sees into this cabinet; another will do
            w.remove(cup.object_id)
            continue
        e.act('open', cab.object_id)
        assert _sees(env, cup.object_id) or _sees_after_a_look(e, env, cup.object_id), cab.object_id
        e.act('pickup', cup.object_id)
        assert w.held == cup.object_id
        assert all(a.action in LOOKS for a in e.actions[e.primitives[-1].start:-1])
        found += 1
        break
    assert found, 'no cabinet of FloorPlan10 could be fetched from'


def _sees_after_a_look(e: Expert, env, object_id: str) -> bool:
    here = e.pose()
    try:
        for dh in (15, -15, 30, -30):
            if -30 <= here[3] + dh <= 60:
                e._set_pose((*here[:3], here[3] + dh))
                if _sees(env, object_id):
                    return True
        return False
    finally:
        e._set_pose(here)


def test_a_put_lands_where_the_agent_sees_it_when_some_spot_allows(env):
    """The expert's put pixel: of the fridge's pixels, one whose landing spot is in view, when the agent
    faces the open fridge; from beside it, none (strict) and the first pixel otherwise."""
    reset(env, 'FloorPlan10', 0)
    clear_small_objects(env)
    cup = spawn_held(env, 'Cup')
    fridge = first_of(env, 'Fridge')
    e = Expert(env.world)
    beside, _ = e.find_pose([fridge.object_id])
    facing, _ = e.find_pose([fridge.object_id], put=cup.object_id)
    env.world.set_open(fridge, True)
    try:
        for pose, expect in ((facing, True), (beside, False)):
            e._set_pose(pose)
            _, depth, seg = env.world.render()
            strict = e._put_pixel(cup.object_id, fridge.object_id, depth, seg, strict=True)
            loose = e._put_pixel(cup.object_id, fridge.object_id, depth, seg)
            assert (strict is not None) == expect, pose
            assert loose == (strict if expect else e._pixel(fridge.object_id, depth, seg))
            assert env.world.held == cup.object_id and cup.parent is None   # every try is taken back
    finally:
        env.world.set_open(fridge, False)
    assert not fridge.is_open
