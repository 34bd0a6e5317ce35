"""World._free_spots (numpy) gives the same resting spots, to the last bit and in the same order, as the
point-by-point loop it replaced; and rooms scattered with it are the rooms the splits were made in."""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'benchmarks'))

from free_spots import reference_free_spots  # noqa: E402  (the loop before session 12)


@pytest.mark.parametrize('split,count', [('valid_seen', 6), ('valid_unseen', 6)])
def test_free_spots_equal_the_reference_loop_on_every_surface(env, split, count):
    from dialfred_sim.tasks import load_split
    compared = nonempty = crowded = 0
    for task in load_split(split)[:count]:
        env.reset(options={'task_id': task.task_id})
        w = env.world
        small = [o for o in w.objects.values() if not o.fixture][:12]
        for r in (o for o in w.objects.values() if o.otype.receptacle and o.spec.surfaces):
            for k in range(len(r.spec.surfaces)):
                for obj in small:
                    new, ref = w._free_spots(r, obj, k), reference_free_spots(w, r, obj, k)
                    assert new == ref, (task.task_id, r.object_id, k, obj.object_id)
                    assert all(type(x) is float and type(y) is float for x, y in new)
                    compared += 1
                    nonempty += bool(ref)
                    crowded += bool(ref) and any(w.objects[c].surface == k for c in r.contents)
    assert compared > 500 and nonempty > 100 and crowded > 20, (compared, nonempty, crowded)


def test_scattered_rooms_match_the_demonstrations_they_were_rendered_from(env):
    """The objects' poses after reset are what they were before the change: a digest of the first
    tasks' scattered objects, measured with the loop (session 12)."""
    from dialfred_sim.tasks import load_split
    h = hashlib.sha256()
    for task in load_split('valid_seen')[:5]:
        env.reset(options={'task_id': task.task_id})
        for oid, o in sorted(env.world.objects.items()):
            h.update(repr((oid, o.parent, o.surface, o.local, tuple(map(float, o.position)))).encode())
    assert h.hexdigest() == SCATTER_DIGEST


SCATTER_DIGEST = '1660a09729fcfb84a6ede00c207c920801eb92d877f89fe3f81f1272775df6fa'
