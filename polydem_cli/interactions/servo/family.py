"""Stress-controlled walls (Luding & Herrmann LH 1.2) as a family of the compiled loop.

A servo wall is a free wall particle (type ``wall``, interactions/disks/family.py) whose one free DOF obeys

    m_x ẍ = F_x(t) − p_x h z(t) − γ_x ẋ        (LH 1.2, written along the wall's inward normal n)

``F_x`` is the force of the material on the wall (the contacts, computed by the other families), ``p_x`` the
prescribed pressure, ``h`` the depth (the wall group's thickness), ``z(t)`` the current distance between the
faces of two other walls (the wall's height: bottom and top for the right wall), ``γ_x`` its damping, ``m_x``
its mass (the wall's ``mass``).  The family adds ``p h z n − γ v`` to the wall's force; the loop integrates
it like any free DOF.  Its power ``p h z n·v`` is external work (the ``work`` hook: part of 'external_work'),
``γ v²`` is dissipated; both by the trapezoidal rule.

For small deviations the wall is a damped oscillator ``m ξ̈ + γ ξ̇ + K ξ = 0`` (LH 1.3): its frequency is
``sqrt(K/m − (γ/2m)²)``; the paper prints a plus sign under the root, a misprint (damping lowers the
frequency of a damped oscillator), tests/test_servo.py checks the minus.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from ...jit import loop_njit
from ...params import ArrayOf, Param, Table
from ..protocol import Family, register_hooks
from ..ranks import Entries, Held

#: per servo q: wall particle, its DOF (0/1), the inward normal's sign along it, pressure, depth, damping,
#: the two walls whose faces give z: particles a, b, the axis of z and the faces' offsets from the centres
ServoParams = namedtuple("ServoParams", ["wall", "dof", "sign", "p", "h", "gamma", "za", "zb", "axis", "offa", "offb"])
#: stats (nq, 4): pressure force along n, z, external power, dissipation rate (last final pass);
#: acc: [work so far, dissipated so far, external power at the last step, dissipation rate at the last step,
#: initialised, dt]
#: cnt: [1 where the servos' power is counted: a serial run, rank 0 of a decomposed one (every rank computes the
#: same servo forces from the walls' positions, the forces acting where a wall is owned)]
ServoWall = namedtuple("ServoWall", ["p", "stats", "acc", "cnt"])
S_FORCE, S_Z, S_POW, S_DRATE = range(4)
A_WORK, A_DISS, A_POW_PREV, A_DRATE_PREV, A_INIT, A_DT = range(6)
#: accumulators counted on rank 0 of a decomposed run (summed over the ranks)
A_SUMS = (A_WORK, A_DISS, A_POW_PREV, A_DRATE_PREV)


@loop_njit
def _pass(fam, final, x, v, dt, F):
    p = fam.p
    for q in range(p.wall.shape[0]):
        w = p.wall[q]
        d = p.dof[q]
        ax = p.axis[q]
        z = abs((x[p.zb[q], ax] + p.offb[q]) - (x[p.za[q], ax] + p.offa[q]))
        fp = p.sign[q] * p.p[q] * p.h[q] * z  # the external pressure pushes the wall into the packing
        F[w, d] += fp - p.gamma[q] * v[w, d]
        if final:
            fam.stats[q, S_FORCE] = fp
            fam.stats[q, S_Z] = z
            fam.stats[q, S_POW] = fp * v[w, d]
            fam.stats[q, S_DRATE] = p.gamma[q] * v[w, d] * v[w, d]
    if final:
        fam.acc[A_DT] = dt
    return 0


@loop_njit
def _accept(fam):
    if fam.acc[A_INIT] == 0.0:
        fam.acc[A_POW_PREV] = fam.stats[:, S_POW].sum() * fam.cnt[0]
        fam.acc[A_DRATE_PREV] = fam.stats[:, S_DRATE].sum() * fam.cnt[0]
        fam.acc[A_INIT] = 1.0


@loop_njit
def _trapezoid(fam, col, prev, total):
    """The step's integral of the rate summed over the walls in stats column ``col`` (trapezoidal rule, the
    last step's rate kept in acc[prev]), added to acc[total] and returned."""
    r = fam.stats[:, col].sum() * fam.cnt[0]
    d = 0.5 * fam.acc[A_DT] * (fam.acc[prev] + r)
    fam.acc[prev] = r
    fam.acc[total] += d
    return d


@loop_njit
def _accumulate(fam):
    return _trapezoid(fam, S_DRATE, A_DRATE_PREV, A_DISS)


@loop_njit
def _work(fam):
    return _trapezoid(fam, S_POW, A_POW_PREV, A_WORK)


@loop_njit
def _row(fam, row, off):
    for q in range(fam.stats.shape[0]):
        row[off] = fam.stats[q, S_FORCE]
        row[off + 1] = fam.stats[q, S_Z]
        off += 2
    row[off] = fam.acc[A_WORK]
    row[off + 1] = fam.acc[A_DISS]
    return off + 2


register_hooks(ServoWall, pass_=_pass, accept=_accept, accumulate=_accumulate, work=_work, row=_row)

SERVO = Table(
    {
        "set": Param("str", doc="the wall: a particle set of one particle of a group of type 'wall'"),
        "pressure": Param(
            "float",
            unit="g/(cm s^2)",
            min=0.0,
            doc="pressure p_x on the wall (force per wall length and depth); 1 N/m^2 = 10",
            thesis="p_x, (LH 1.2)",
        ),
        "gamma": Param(
            "float", unit="g/s", default=0.0, min=0.0, doc="wall damping; 1 kg/s = 1e3", thesis="γ_x, (LH 1.2)"
        ),
        "length_between": Param(
            "strs",
            doc="the two walls (sets) whose face distance is the loaded length z(t), e.g. [\"bottom\", \"top\"]",
            check=lambda v: None if len(v) == 2 else "must name exactly two wall sets",
        ),
    },
    doc="Stress-controlled walls (Luding & Herrmann LH 1.2): the wall's free DOF along its normal is "
    "driven by the material, the pressure p h z(t) and its damping; its mass is the wall group's 'mass', "
    "the depth h its thickness.  The wall's other DOFs must be fixed by [[boundary]].",
)


class ServoFamily(Family):
    name = "servo"
    tables = {"servo": ArrayOf(SERVO, doc=SERVO.doc, required=False)}

    def build(self, sc, ctx):
        from ...errors import ScenarioError

        entries = sc.get("servo") or []
        if not entries:
            return None
        file, specs = ctx["file"], ctx["specimens"]
        cols = {k: [] for k in ServoParams._fields}

        def wall_of(name, key):
            if name not in ctx["groups"] or "wall_normal" not in specs[name].info:
                walls = [g for g in ctx["groups"] if "wall_normal" in specs[g].info]
                raise ScenarioError(
                    file, key, name, f"is not a group of type 'wall' (walls: {', '.join(walls) or 'none'})"
                )
            return ctx["groups"][name][0], specs[name].info

        for qi, e in enumerate(entries):
            key = f"servo[{qi}]"
            w, info = wall_of(e["set"], f"{key}.set")
            nx, ny = info["wall_normal"]
            d = 0 if nx else 1
            if ctx["bc_kind"][w, d] != 0:
                raise ScenarioError(
                    file,
                    f"{key}.set",
                    e["set"],
                    f"its {'x1' if d == 0 else 'x2'} is prescribed by [[boundary]]: a servo DOF must be free",
                )
            (a, ia), (b, ib) = (wall_of(s, f"{key}.length_between") for s in e["length_between"])
            na, nb = np.asarray(ia["wall_normal"]), np.asarray(ib["wall_normal"])
            ax = 0 if na[0] else 1
            if not nb[ax] or na[ax] == nb[ax]:
                raise ScenarioError(
                    file,
                    f"{key}.length_between",
                    e["length_between"],
                    "must be two opposite walls (e.g. bottom and top)",
                )
            if ax == d:
                raise ScenarioError(
                    file, f"{key}.length_between", e["length_between"], "must be the walls across the servo's motion"
                )
            cols["wall"].append(w)
            cols["dof"].append(d)
            cols["sign"].append(nx if d == 0 else ny)
            cols["p"].append(e["pressure"])
            cols["h"].append(ctx["thickness"][w])
            cols["gamma"].append(e["gamma"])
            cols["za"].append(a)
            cols["zb"].append(b)
            cols["axis"].append(ax)
            cols["offa"].append(na[ax] * ia["wall_offset"])  # face = centre + offset along the inward normal
            cols["offb"].append(nb[ax] * ib["wall_offset"])
        ints = ("wall", "dof", "za", "zb", "axis")
        return ServoParams(**{k: np.asarray(v, np.int64 if k in ints else float) for k, v in cols.items()}), [
            e["set"] for e in entries
        ]

    def uses(self, system):
        return system.family_data.get(self.name) is not None

    def columns_of(self, system):
        _, names = system.family_data[self.name]
        cols = []
        for s in names:
            cols += [
                (f"servo_force:{s}", "dyn", f"external pressure force p h z on wall {s} along its inward normal"),
                (f"servo_length:{s}", "cm", f"loaded length z of wall {s} (distance of the faces of its two walls)"),
            ]
        return tuple(cols) + (
            ("servo_work", "erg", "work of the servo pressures so far (included in 'external_work')"),
            (
                "servo_dissipated",
                "erg",
                "energy dissipated by the servo walls' damping so far (included in 'dissipated')",
            ),
        )

    def bundle(self, system, built=None):
        p, names = system.family_data[self.name]
        return ServoWall(p, np.zeros((len(names), 4)), np.zeros(6), np.ones(1))

    def inert_bundle(self, system, built=None):
        z, zi = np.zeros(0), np.zeros(0, np.int64)
        return ServoWall(ServoParams(zi, zi, z, z, z, z, zi, zi, zi, z, z), np.zeros((0, 4)), z, np.ones(1))

    # ------------------------------------------------------------ a decomposed run (engine/distributed.py)

    def data_layout(self, data):
        """The walls renumbered (every rank holds every wall: the disks family replicates them)."""
        return ((("0.wall", "0.za", "0.zb"), Held()),)

    def attach(self, bundle, mpi, sums):
        """The servos' power counted on rank 0 only (its forces and lengths are the same on every rank)."""
        return bundle._replace(cnt=np.array([1.0 if mpi.rank[0] == 0 else 0.0]))

    def column_reductions(self, system):
        _, names = system.family_data[self.name]
        return ("same", "same") * len(names) + ("sum", "sum")

    def state_layout(self, system):
        """Work and dissipation (counted on rank 0) summed, the rest rank 0's."""
        return ((("servo_acc",), Entries(sums=A_SUMS)),)

    def state(self, b):
        return {"servo_acc": b.acc.copy()}

    def restore(self, b, st, system=None):
        b.acc[:] = st["servo_acc"]


SERVO_WALL = ServoFamily()
