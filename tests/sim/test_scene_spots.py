"""Rooms are scattered exactly as when the splits and demonstrations were made: a digest of the first
tasks' object poses after reset."""

from __future__ import annotations

import hashlib



def test_scattered_rooms_match_the_demonstrations_they_were_rendered_from(env):
    """The objects' poses after reset are what they were before the change: a digest of the first
    tasks' scattered objects. SCATTER_DIGEST is this test's own digest, taken when valid_seen was last
    regenerated (with the world that made it); a deliberate change of the world's scattering and a
    regenerated valid_seen renew it, nothing else should."""
    from dialfred_sim.tasks import load_split
    h = hashlib.sha256()
    for task in load_split('valid_seen')[:5]:
        env.reset(options={'task_id': task.task_id})
        for oid, o in sorted(env.world.objects.items()):
            h.update(repr((oid, o.parent, o.surface, o.local, tuple(map(float, o.position)))).encode())
    assert h.hexdigest() == SCATTER_DIGEST


SCATTER_DIGEST = '940092205c691eb030b29785641418e2d220a4f25d72bbf36d83b2daf7c24c53'
