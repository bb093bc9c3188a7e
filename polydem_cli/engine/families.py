"""The registry of interaction families the compiled loop can compose (protocol: interactions/protocol.py).

Adding a family: write its module (bundle, compiled hooks, a :class:`~..interactions.protocol.Family`)
and add it to :data:`FAMILIES`; the time loop (engine/kernels.py) does not change.
"""

from __future__ import annotations

from ..interactions.base.family import BASE_FRICTION
from ..interactions.disks.family import DISK_CONTACT
from ..interactions.protocol import NO_FAMILY

#: the families the loop can compose, in the order their passes run (after bonds and contact)
FAMILIES = (BASE_FRICTION, DISK_CONTACT)


def used_families(system) -> tuple:
    """The registered families a scene uses, in loop order."""
    return tuple(f for f in FAMILIES if f.uses(system))


def compose(system):
    """(families used by the scene, the tuple of their bundles for the compiled loop, led by NO_FAMILY)."""
    used = used_families(system)
    return used, (NO_FAMILY,) + tuple(f.bundle(system) for f in used)
