"""The interaction-family protocol of the compiled time loop (issue 13, first step).

A *family* is one interaction model with its own data: a namedtuple type (its *bundle*: parameters,
history, work arrays, statistics, accumulators) plus compiled hooks registered for that type, and a
Python :class:`Family` object for everything outside the loop (history-table columns, checkpoint
fields, summary figures).  The driver builds the tuple of the bundles a scene uses once, before the
loop; the loop runs over it with ``numba.literal_unroll``, so every hook is specialised and inlined
for the families present and a family a scene does not use costs nothing per step.  Adding a family
adds a module and a line in ``engine/families.py`` (the registry); the loop does not change.

Compiled hooks, called for every bundle in the tuple, in its order (all optional):

``pass_(fam, final, x, v, dt, F) -> int``
    add the family's generalised forces to F at state (x, v); ``final`` is False in the provisional
    pass at the predicted state and True in the final pass at the corrected one (thesis Fig. A.2),
    which also writes the new history and the statistics; 0, or −(capacity needed) to make the driver
    enlarge a buffer and repeat the step.
``accept(fam)``
    the step (or the initial state) is accepted: the new history becomes the old one.
``accumulate(fam) -> float``
    after an accepted step: update the family's own accumulators, return the energy it dissipated
    in the step (added to the total 'dissipated').
``elastic(fam) -> float``
    energy stored in the family's interactions at the last final pass (part of 'elastic').
``work(fam) -> float``
    after an accepted step (after ``accumulate``): the work external agents did through the family in the
    step (added to 'external_work'; a stress-controlled wall's pressure).
``row(fam, row, off) -> int``
    write the family's history-table columns from ``row[off]`` on; return the next offset.
``begin(fam, step, t)``
    a step ``step`` (to time ``t``) begins: before its passes (a family that records when something
    happened keeps the step; a controller arms itself).
``settle(fam, value, F) -> int``
    only the first element of the tuple is asked, at the end of every force evaluation: in a run decomposed over
    MPI ranks the one time the ranks meet besides the ghost exchange (engine/halo.py), so that every rank takes
    the same branch and none waits in an exchange the others left.  One reduction holds: the room (``value`` < 0:
    a family asked for some), whether some rank's forces are not finite, whether some rank's ghosts may no
    longer hold every partner (the halo then pauses the loop after the step), and the sums over the ranks the
    families asked for (:meth:`Family.rank_sums`: a wall's force from the disks of every rank, the load-drop
    stop's load), which it adds to F where a family named an entry.  Returns the ranks' summed room if any asked
    (negative), else 1 + the first row of F with a non-finite force on this rank (``F.shape[0]`` if only other
    ranks had one) if any rank had one, else 0.  Absent (a serial run): ``value`` itself.
``halt(fam) -> int``
    after the final pass of a step, before it is committed: :data:`GO_ON`, :data:`HALT_END` (the run has
    reached its end criterion: the step is committed and recorded, then the loop ends) or
    :data:`HALT_ABORT` (the step is not committed; the loop ends with an error the family explains in
    ``Family.halt_message``).  A controller (the load-drop stop) reads the forces of the step here from
    what its final pass saw: families pass in registry order, so the last one sees every force — except, in a
    decomposed run, the sums ``settle`` adds to F after the passes (a wall's force from the disks of every rank),
    which it finds in the ledger (:class:`RankSums`).  In a decomposed run the ranks do not meet on the halt: a
    halt hook must decide from what every rank knows alike — the totals of its :meth:`Family.rank_sums` (a
    reason of its own rank's, such as a count, is declared as a rank sum and read back summed).

A scene's tuple always starts with the halo exchange of a decomposed run (engine/halo.py; an inert one in a serial run,
so that the loop has one type) and holds every
registered family (engine/families.py ``compose``): those the scene does not use as *inert* bundles, whose
``acc`` has length 0; the dispatchers here then skip the family's hooks (``pass_`` gives 0, ``row`` its
offset unchanged), so a hook never tests for it.

The loop is cached on disk per family combination, and Numba's cache index names every bundle type
of every cached combination: a family must live in an importable module (in the package, or with its
own ``NUMBA_CACHE_DIR`` as tests/plugin_family.py does), and its hooks must be cached.

Families (engine/families.py, in the order they pass): beam bonds, polygon contact, particle–base friction,
cohesive disks, servo walls, platen friction, the applied loads' record, the load-drop stop.  The loop itself knows only the particles, the integrator
and the prescribed motion.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba.extending import overload

# ---------------------------------------------------------------- compiled hooks (dispatch by bundle type)

_HOOKS: dict = {}


def fam_pass(fam, final, x, v, dt, F):  # pragma: no cover - compiled only
    """Compiled dispatch of a family's ``pass_`` hook (see the module docstring); Python never calls it."""
    raise NotImplementedError


def fam_accept(fam):  # pragma: no cover
    """Compiled dispatch of a family's ``accept`` hook; Python never calls it."""
    raise NotImplementedError


def fam_accumulate(fam):  # pragma: no cover
    """Compiled dispatch of a family's ``accumulate`` hook; Python never calls it."""
    raise NotImplementedError


def fam_elastic(fam):  # pragma: no cover
    """Compiled dispatch of a family's ``elastic`` hook; Python never calls it."""
    raise NotImplementedError


def fam_row(fam, row, off):  # pragma: no cover
    """Compiled dispatch of a family's ``row`` hook; Python never calls it."""
    raise NotImplementedError


def fam_work(fam):  # pragma: no cover
    """Compiled dispatch of a family's ``work`` hook; Python never calls it."""
    raise NotImplementedError


def fam_begin(fam, step, t):  # pragma: no cover
    """Compiled dispatch of a family's ``begin`` hook; Python never calls it."""
    raise NotImplementedError


def fam_settle(fam, value, F):  # pragma: no cover
    """Compiled dispatch of the ``settle`` hook of the tuple's first element; Python never calls it."""
    raise NotImplementedError


def fam_halt(fam):  # pragma: no cover
    """Compiled dispatch of a family's ``halt`` hook; Python never calls it."""
    raise NotImplementedError


#: entries of a decomposed run's reduction (the ``settle`` hook; :class:`RankSums` ``ledger``) before the families'
#: sums: the room, the count of ranks with a non-finite force, the count of ranks whose ghosts may be outrun
LEDGER_HEAD = 3

#: results of the ``halt`` hook, in the order in which they prevail (the largest over the families wins; the ranks of
#: a decomposed run reach the same one, each hook deciding from agreed totals): HALT_PAUSE commits the step and leaves the loop to continue after the Python
#: side has acted (a decomposed run redistributes its particles, engine/distributed.py)
GO_ON = 0
HALT_PAUSE = 1
HALT_END = 2
HALT_ABORT = 3


def _hook(fam, name):
    cls = getattr(fam, "instance_class", None)
    if cls not in _HOOKS:
        raise TypeError(f"{fam}: not a registered interaction family bundle")
    return _HOOKS[cls].get(name)


def _inert_guard(fam):
    """True if bundles of this type carry an ``acc`` array: a zero-length one marks an inert bundle (a family
    the scene does not use, engine/families.py ``compose``), for which the dispatchers below return at once,
    so the hooks themselves never test for it.  A bundle type without ``acc`` is never inert."""
    return "acc" in getattr(fam, "fields", ())


@overload(fam_pass, inline="always")
def _ov_pass(fam, final, x, v, dt, F):
    # always an int64, never the literal 0: inside the loop's literal_unroll one variable takes every family's
    # result, and a literal type there made numba drop a family's −(capacity needed) (2026-12-02)
    f = _hook(fam, "pass_")
    if f is None:
        return lambda fam, final, x, v, dt, F: np.int64(0)
    if _inert_guard(fam):
        return lambda fam, final, x, v, dt, F: (
            np.int64(0) if fam.acc.shape[0] == 0 else np.int64(f(fam, final, x, v, dt, F))
        )
    return lambda fam, final, x, v, dt, F: np.int64(f(fam, final, x, v, dt, F))


@overload(fam_accept, inline="always")
def _ov_accept(fam):
    f = _hook(fam, "accept")
    if f is None:
        return lambda fam: None
    if _inert_guard(fam):

        def _guarded(fam):
            if fam.acc.shape[0] != 0:
                f(fam)

        return _guarded
    return lambda fam: f(fam)


def _scalar_hook(name):
    """Dispatcher of a hook returning a float (0.0 when absent or inert)."""

    def ov(fam):
        f = _hook(fam, name)
        if f is None:
            return lambda fam: 0.0
        if _inert_guard(fam):
            return lambda fam: 0.0 if fam.acc.shape[0] == 0 else f(fam)
        return lambda fam: f(fam)

    return ov


@overload(fam_begin, inline="always")
def _ov_begin(fam, step, t):
    f = _hook(fam, "begin")
    if f is None:
        return lambda fam, step, t: None
    if _inert_guard(fam):

        def _guarded(fam, step, t):
            if fam.acc.shape[0] != 0:
                f(fam, step, t)

        return _guarded
    return lambda fam, step, t: f(fam, step, t)


@overload(fam_halt, inline="always")
def _ov_halt(fam):
    f = _hook(fam, "halt")
    if f is None:
        return lambda fam: np.int64(GO_ON)
    if _inert_guard(fam):
        return lambda fam: np.int64(GO_ON) if fam.acc.shape[0] == 0 else np.int64(f(fam))
    return lambda fam: np.int64(f(fam))


@overload(fam_settle, inline="always")
def _ov_settle(fam, value, F):
    f = _hook(fam, "settle")
    if f is None:
        return lambda fam, value, F: np.int64(value)
    if _inert_guard(fam):

        def _guarded(fam, value, F):
            if fam.acc.shape[0] == 0:
                return np.int64(value)
            return np.int64(f(fam, value, F))

        return _guarded
    return lambda fam, value, F: np.int64(f(fam, value, F))


overload(fam_accumulate, inline="always")(_scalar_hook("accumulate"))
overload(fam_elastic, inline="always")(_scalar_hook("elastic"))
overload(fam_work, inline="always")(_scalar_hook("work"))


@overload(fam_row, inline="always")
def _ov_row(fam, row, off):
    f = _hook(fam, "row")
    if f is None:
        return lambda fam, row, off: off
    if _inert_guard(fam):
        return lambda fam, row, off: off if fam.acc.shape[0] == 0 else f(fam, row, off)
    return lambda fam, row, off: f(fam, row, off)


def register_hooks(
    bundle_cls,
    *,
    pass_=None,
    accept=None,
    accumulate=None,
    elastic=None,
    row=None,
    work=None,
    begin=None,
    halt=None,
    settle=None,
):
    """Register the compiled hooks of a family's bundle type (see the module docstring).

    Every hook must be compiled with ``njit(cache=True)``: the loop is cached on disk with the hooks
    inlined, and a cached loop that called an uncached hook of an earlier process would crash."""
    hooks = {
        "pass_": pass_,
        "accept": accept,
        "accumulate": accumulate,
        "elastic": elastic,
        "row": row,
        "work": work,
        "begin": begin,
        "halt": halt,
        "settle": settle,
    }
    for name, f in hooks.items():
        if f is not None and type(getattr(f, "_cache", None)).__name__ in ("NullCache", "NoneType"):
            raise TypeError(f"{bundle_cls.__name__}: hook {name} must be compiled with numba.njit(cache=True)")
    _HOOKS[bundle_cls] = hooks


# ---------------------------------------------------------------- the Python side


class RankSums(NamedTuple):
    """A decomposed run's sums over the ranks at the end of every force evaluation (the halo's ``settle``), as
    :meth:`Family.attach` hands them to a family: ``local`` / ``total`` its own (:meth:`Family.rank_sums`; it
    writes ``local`` in its pass and reads ``total`` after the evaluation); ``ledger`` every family's totals (the
    :data:`LEDGER_HEAD` entries of the evaluation's own decisions, then one per row of ``targets``); ``targets`` (k, 2) the (particle, DOF) each total is added to in
    F, particles in global numbering (the same rows on every rank), −1 for none; ``system`` the rank's part (engine/distributed.py: its own particles and ghosts, its sets
    cut to the members it owns); ``held_sets`` each set's members the rank holds, owned or ghost (global numbers:
    the particles ``targets`` names are held by every rank)."""

    local: np.ndarray
    total: np.ndarray
    ledger: np.ndarray
    targets: np.ndarray
    system: object
    held_sets: dict

    def slots(self, particles, dof: int) -> np.ndarray:
        """Entries of ``ledger`` added to F[p, dof] for the (global) ``particles`` p."""
        t = self.targets
        hit = (t[:, 1] == dof) & np.isin(t[:, 0], np.asarray(particles, np.int64))
        return (LEDGER_HEAD + np.flatnonzero(hit)).astype(np.int64)


class Family:
    """What the driver needs of a family outside the compiled loop.  Subclasses set ``name`` and
    ``columns`` ((name, unit, description) of its history-table columns) and implement the methods."""

    name = ""
    columns: tuple = ()
    #: scenario tables the family adds to the schema (top-level name -> polydem_cli.params.Table)
    tables: dict = {}
    #: particle generators the family adds ([[particles]] type -> its fields); generated by ``generate``
    particle_variants: dict = {}

    def generate(self, p: dict, seed: int):
        """The Specimen of a [[particles]] group of one of the family's own types (raise GeometryError)."""
        raise NotImplementedError

    def mass_properties(self, spec, rho, thickness, mass, inertia):
        """(mass, inertia) per particle of one of the family's specimens, given its polygons' values."""
        return mass, inertia

    def build(self, sc: dict, ctx: dict):
        """The family's static data from the validated scenario (stored in ``System.family_data[name]``), or
        None; raise ScenarioError for input it refuses.  ``ctx``: what scenario/build.py has resolved before the
        families (its ``_family_context`` lists the keys: file, n, particles, groups, specimens, materials,
        shapes, x0, thickness, bc_kind, sets, select, dt, drive, contact, initial_state)."""
        return None

    def data(self, system):
        """What :meth:`build` made for this scene (None if it made nothing)."""
        return system.family_data.get(self.name)

    def data_layout(self, data):
        """How what :meth:`build` made (``data``, not None) is cut to one rank's part of a decomposed scene: a tuple
        of (field paths, kind) with the kinds of interactions/ranks.py (``PerParticle``, ``Held``, ``Owned``,
        ``PairRows``, ``Groups``, ``HeldMembers``, ``PairList``; an empty tuple: nothing to cut), which the communication layer there applies (``localize``, called by
        engine/distributed.py for each rank's part); raise DecompositionError for data the family cannot decompose
        (naming why).  None (the default): the family does not run decomposed."""
        return None

    def unused(self, sc: dict) -> list:
        """Keys the scenario sets that this family will not use in the scene, each with the reason, e.g.
        ``"materials.steel.k_t (contact.tangential = 'none')"`` (reported by ``polydem check`` and stored)."""
        return []

    #: top-level keys the family adds to the run summary (None when the scene does not use it), so that every
    #: summary has the same keys
    summary_keys: tuple = ()

    def columns_of(self, system) -> tuple:
        """The family's history-table columns in this scene (default: ``columns``)."""
        return tuple(self.columns)

    def replicated(self, system) -> np.ndarray:
        """Global indices of particles every rank of a decomposed run must hold, whatever its subdomain (walls a
        family's pairs find by a plane, not by distance); engine/decompose.py copies them, with its large
        particles, to every rank.  Default: none."""
        return np.zeros(0, np.int64)

    def rank_sums(self, system) -> np.ndarray:
        """A decomposed run: the numbers this family sums over the ranks at the end of every force evaluation, as
        one row each (particle, DOF) of the rank's part ``system`` — the F entry the sum is added to, or (−1, −1)
        for a sum the family reads itself (from the ``total`` that :meth:`attach` gives it).  They travel in the
        evaluation's one reduction (the ``settle`` hook of engine/halo.py), not in a reduction of their own.
        Default none."""
        return np.zeros((0, 2), np.int64)

    def ghost_field(self, bundle):
        """A decomposed run: the per-particle array (n, k) of ``bundle`` that this family fills in its provisional
        pass for every particle of the rank's part and reads in its final pass, where a ghost's row must be its
        owner's (a sum over interactions another rank also holds).  The halo exchange (engine/halo.py) sends the
        owners' rows to the ghosts with the positions before the final pass, so it costs no meeting of its own.
        Default None (the family needs nothing on its ghosts)."""
        return None

    def attach(self, bundle, mpi, sums: RankSums):
        """The bundle of one rank of a decomposed run, given the MPI entry points (mpicall.py ``MpiApi``) and the
        evaluation's sums over the ranks (:class:`RankSums`: the family's own, :meth:`rank_sums`, and the ledger of
        all); default unchanged."""
        return bundle

    def state_layout(self, system):
        """How each of :meth:`state`'s checkpoint fields is held over the ranks of a decomposed run: a tuple of
        (field names, kind) with the kinds of interactions/ranks.py (``Same``, ``Summed``, ``Entries``, ``Rows``,
        ``Pairs``, ``Rebuilt``), from which the communication layer there gathers a checkpoint to rank 0, shares
        it out again on a resume or a re-cut, and joins the ranks' fields into the serial run's, so that a run
        resumes on any number of ranks; the family moves none of it itself.  None (the default): the family
        does not run decomposed."""
        return None

    def column_reductions(self, system) -> tuple:
        """How each of :meth:`columns_of`'s columns of a decomposed run combines the ranks' values: ``"sum"``
        (counts, energies: each interaction counted on one rank), ``"max"`` (largest values) or ``"same"`` (a value
        every rank computes alike, e.g. from a wall's position: rank 0's).  Default: all sum."""
        return ("sum",) * len(self.columns_of(system))

    def uses(self, system) -> bool:
        """Does the scene use this family?"""
        raise NotImplementedError

    #: does the family have a threaded kernel (engine/threads.py: ``--threads auto`` keeps one thread otherwise)
    threaded = False

    def bundle(self, system, built=None):
        """A fresh bundle (parameters from the built system, zero history).  ``built``: the bundles of the
        families composed before this one, by name (a family may share another's arrays: polygon contact
        reads which pairs the beam bonds still join)."""
        raise NotImplementedError

    def inert_bundle(self, system, built=None):
        """A bundle of the same type with zero-length arrays (``acc`` of length 0) for a scene that does not use
        the family; the dispatchers skip its hooks."""
        raise NotImplementedError

    def state(self, bundle) -> dict:
        """Checkpoint fields (name -> array) of the bundle's history and accumulators."""
        return {}

    def restore(self, bundle, st: dict, system=None):
        """Set the bundle's history from checkpoint fields (every field :meth:`state` writes: a checkpoint
        of an older form is refused before, solvers/explicit.py); return a replacement bundle if the stored
        history does not fit this one, else None."""

    def grow(self, system, bundle):
        """A larger bundle with the same state if the last pass returned −(capacity needed) for this family,
        else None (the driver then enlarges the polygon-contact buffers)."""
        return None

    def observables(self, bundle) -> dict:
        """Figures of the run summary's 'observables'."""
        return {}

    def omegas(self, system) -> list:
        """(ω, what) candidates for the critical time step estimate (engine/stability.py): the highest
        angular frequency of the family's stiffest interaction and a description of it."""
        return []

    def reach(self, system) -> float:
        """How far beyond touching bounding circles two particles can interact through this family [cm] (a
        pair-list buffer); engine/decompose.py sizes the ghost layer of a subdomain by the largest.  Pairs the
        family joins explicitly (bonds) are ghosts by their list, not by distance."""
        return 0.0

    def check_initial(self, system, bundle):
        """Refuse an impossible initial state (raise ScenarioError) after the evaluation at t0."""

    def check(self, system, bundle, limits: dict):
        """A reason the run has gone unstable (solvers/explicit.py stops it with that reason), or None.
        ``limits``: the scenario's [stability] table."""
        return None

    def warning(self, system, bundle):
        """A warning to print once (something the run survives but the user should know), or None."""
        return None

    def halt_message(self, system, bundle, step: int):
        """Why this family's ``halt`` hook aborted the run at ``step`` (None if it did not; in a decomposed run also on
        a rank that stopped because another found the cause).  ``system`` may be a rank's part: name particles
        through ``system.number(i)``, their number in the whole scene."""
        return None

    def end_reason(self, system, bundle):
        """Why this family's ``halt`` hook ended the run (None if it did not)."""
        return None

    def end_progress(self, system, bundle):
        """How near this family's end criterion (its ``halt`` hook) is, for the progress line and its ETA:
        ``(now, end, what)``, a measure that falls towards ``end`` as the run nears its end (the run ends
        once it is below ``end``) and what it is, e.g. ``(0.34, 0.1, "load / its peak")``; None if the family
        ends no run or cannot tell yet."""
        return None

    def frame(self, system, bundle, x) -> dict:
        """Extra fields of an output frame at positions ``x`` (per-interaction state to draw)."""
        return {}

    def records(self, bundle) -> dict:
        """Result-file records written with every checkpoint: {record name: fields} (io/hdf5.py)."""
        return {}

    def summary(self, system, bundle) -> dict:
        """Sections of the run summary (top-level keys, among :attr:`summary_keys`) the family adds."""
        return {}

    def summary_lines(self, summary: dict) -> list:
        """Lines of the printed end-of-run account about the family's sections of ``summary``."""
        return []

    def table_columns(self, summary: dict) -> dict:
        """Columns of a sweep or batch table (name with unit -> value) from the family's summary sections."""
        return {}

    def end_note(self, system, bundle):
        """What to add to the end reason when the run reached its end time or displacement before the family's
        own end criterion (its ``halt`` hook) was met; None if it has none."""
        return None

    def static(self, system):
        """The family's static records of the result file: ``(group name, {dataset: array})``, or None."""
        return None

    def frame_layout(self, system) -> dict:
        """Per-frame fields the family writes (:meth:`frame`): {name: (shape of one frame, column names or
        None)}; the writer makes their datasets when it creates the result."""
        return {}

    def frame_rows(self, system):
        """The numbering of the rows of the :meth:`frame` fields (an interactions/ranks.py ``Rows``: every field's
        first axis), so that on ranks each rank writes the rows it counts of its own part and none gathers the state
        for a frame (engine/distributed.py); None: the family writes no frame fields."""
        return None

    #: the figures ``polydem report`` draws from the family's records (report/make.py ``FIGURES`` knows how to
    #: draw each), for a result that holds the group ``result_group`` (the one :meth:`static` writes)
    figures: tuple = ()
    result_group: str | None = None
