"""The registry of interaction families the compiled loop can compose (protocol: interactions/protocol.py).

Adding a family: write its module (bundle, compiled hooks, a :class:`~..interactions.protocol.Family`)
and add it to :data:`FAMILIES`; the time loop (engine/kernels.py) does not change.
"""

from __future__ import annotations

from ..interactions.base.family import BASE_FRICTION
from ..interactions.bonds.family import BEAM_BONDS
from ..interactions.contact.family import POLYGON_CONTACT
from ..interactions.controllers.applied_loads import APPLIED_LOADS
from ..interactions.controllers.load_drop import LOAD_DROP
from ..interactions.controllers.platen import PLATEN_FRICTION
from ..interactions.controllers.proportional import PROPORTIONAL_PRESSURE
from ..interactions.disks.family import DISK_CONTACT
from ..interactions.servo.family import SERVO_WALL
from .halo import inert_halo

#: the families the loop can compose, in the order their passes run (thesis Fig. A.2: bonds before contact,
#: so that the contact search sees which pairs are still bonded); their history-table columns come in this
#: order too.  Platen friction reads the e2 force of those before it (a particle's push on its platen), the
#: proportional pressure the reaction of its reference face; the load-drop stop reads the forces of all the others:
#: it passes last.
FAMILIES = (
    BEAM_BONDS,
    POLYGON_CONTACT,
    BASE_FRICTION,
    DISK_CONTACT,
    SERVO_WALL,
    PLATEN_FRICTION,
    PROPORTIONAL_PRESSURE,
    APPLIED_LOADS,
    LOAD_DROP,
)


def used_families(system) -> tuple:
    """The registered families a scene uses, in loop order."""
    return tuple(f for f in FAMILIES if f.uses(system))


def compose(system):
    """(families used by the scene, the tuple for the compiled loop).

    The tuple holds a bundle of *every* registered family, led by an inert halo exchange (engine/halo.py: a
    decomposed run puts its own there, with the same type): the scene's own bundles for the
    families it uses, an inert bundle (``Family.inert_bundle``: zero-length arrays, every hook returns at
    once) for the others.  So the loop has one type signature whatever the scene, one compiled and cached
    specialisation: with one specialisation per family combination, two cached combinations sharing a
    family (disks alone, disks with servo walls) made a later process segfault when it loaded the loop
    from Numba's cache (2026-12-02; tests/test_families.py).  An unused family costs one branch per hook."""
    used = used_families(system)
    built = {}
    for f in FAMILIES:  # in registry order: a family may share arrays of one composed before it
        built[f.name] = f.bundle(system, built) if f in used else f.inert_bundle(system, built)
    return used, (inert_halo(),) + tuple(built[f.name] for f in FAMILIES)


def family(name):
    """The registered family called ``name``."""
    for f in FAMILIES:
        if f.name == name:
            return f
    raise KeyError(f"no interaction family {name!r}; registered: {', '.join(f.name for f in FAMILIES)}")


def slot(family) -> int:
    """Position of a registered family's bundle in the loop's tuple."""
    return 1 + FAMILIES.index(family)
