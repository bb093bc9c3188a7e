"""History rows of an explicit run: the table's columns, the rows completed with the derived (macroscopic)
columns, and the running aggregates of the table that the summary reports."""

from __future__ import annotations

import numpy as np

from ..analysis import macro as _macro
from ..engine import kernels as K
from ..engine.families import used_families


def history_columns(system) -> list:
    """(name, unit, description) of every history-table column of a system's runs."""
    cols = list(K.HISTORY_BASE_COLUMNS)
    for f in used_families(system):
        cols += list(f.columns_of(system))
    for name in system.monitored:
        cols.extend((f"{c}:{name}", u, d) for c, u, d in K.SET_COLUMNS)
    if system.macro is not None:
        cols += list(_macro.COLUMNS)
    return cols


class RowMaker:
    """Complete the engine's history rows with the columns derived in Python (macroscopic measures).

    ``file_columns``: the column names of the table a resumed run appends to, if another version of polydem
    wrote it with other columns or in another order: rows are then written in the file's order, a column of
    the file this version does not compute as NaN; columns the file lacks are left out (``dropped``)."""

    def __init__(self, system, columns, file_columns=None):
        self.macro = system.macro
        names = [c[0] for c in columns]
        self.kernel_cols = names[: len(columns) - (len(_macro.COLUMNS) if self.macro else 0)]
        self.take, self.dropped = None, []
        if file_columns is not None and list(file_columns) != names:
            where = {n: i for i, n in enumerate(names)}
            self.take = np.array([where.get(n, -1) for n in file_columns])
            self.dropped = [n for n in names if n not in set(file_columns)]

    def __call__(self, rows):
        if self.macro is not None:
            rows = np.hstack([rows, _macro.derive(self.macro, self.kernel_cols, rows)])
        if self.take is None:
            return rows
        out = rows[:, np.maximum(self.take, 0)]
        out[:, self.take < 0] = np.nan
        return out


class HistoryStats:
    """Running aggregates of the history table for the summary."""

    def __init__(self, columns):
        self.cols = [c[0] for c in columns]
        self.peak = {}
        self.last = None
        self.first = None
        self.e_dev = 0.0
        self.e_scale = 0.0
        self.macro_rows = []  # (sigma22, eps22, eps11) chunks, when the history has them
        self.has_macro = "sigma22" in self.cols

    def update(self, rows):
        if len(rows) == 0:
            return
        if self.first is None:
            self.first = rows[0].copy()
        self.last = rows[-1].copy()
        c = self.cols
        d, sc = self.energy_terms(rows)
        self.e_dev, self.e_scale = max(self.e_dev, d), max(self.e_scale, sc)
        if self.has_macro:
            self.macro_rows.append(rows[:, [c.index("sigma22"), c.index("eps22"), c.index("eps11")]].copy())
        for j, name in enumerate(c):
            if name.startswith(("f1:", "f2:", "c:")):
                k = int(np.argmax(np.abs(rows[:, j])))
                v = float(rows[k, j])
                if abs(v) >= abs(self.peak.get(name, (0.0, 0.0, 0.0))[0]):
                    u = name.split(":", 1)
                    ucol = "u2:" + u[1] if "u2:" + u[1] in c else None
                    self.peak[name] = (
                        v,
                        float(rows[k, c.index("time")]),
                        float(rows[k, c.index(ucol)]) if ucol else 0.0,
                    )

    @property
    def last_step(self):
        """The step of the last row seen (None before any)."""
        return None if self.last is None else int(self.last[self.cols.index("step")])

    def energy_terms(self, rows):
        """(largest |E_total - E_0|, largest energy scale) over ``rows`` (relative to the first row seen)."""
        c = self.cols
        rows = np.atleast_2d(rows)
        et = rows[:, c.index("energy_total")]
        dev = float(np.max(np.abs(et - self.first[c.index("energy_total")])))
        scale = (
            np.abs(rows[:, c.index("kinetic")])
            + np.abs(rows[:, c.index("elastic")])
            + np.abs(rows[:, c.index("dissipated")])
            + np.abs(rows[:, c.index("external_work")])
            + np.abs(rows[:, c.index("potential")] - self.first[c.index("potential")])
        )
        return dev, float(scale.max())

    def summary(self):
        out = {}
        if self.last is not None:
            for key in ("kinetic", "elastic", "potential", "dissipated", "external_work"):
                out[f"final_{key}"] = float(self.last[self.cols.index(key)])
            out["energy_balance_error"] = self.e_dev / self.e_scale if self.e_scale > 0 else 0.0
        out["peaks"] = {k: {"value": v[0], "time": v[1], "u2": v[2]} for k, v in self.peak.items()}
        return out

    def macro_summary(self, spec):
        if not self.has_macro or spec is None or not self.macro_rows:
            return None
        m = np.vstack(self.macro_rows)
        res = _macro.summarize(m[:, 0], m[:, 1], m[:, 2], spec.fit_range, spec.L1, spec.T, spec.L2)
        res["definition"] = spec.as_dict()
        return res
