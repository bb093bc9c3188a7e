"""Export a polydem result to ParaView: one VTKHDF file (VTK's HDF5 format, ``UnstructuredGrid``, temporal,
version 2) holding every frame of the run — written with h5py in the layout VTK's own ``vtkHDFWriter``
produces (https://docs.vtk.org/en/latest/vtk_file_formats/vtkhdf_file_format/), read by ParaView ≥ 5.12 and
VTK's ``vtkHDFReader``.

Cells per frame (one time step per frame of the result, ``Steps/Values`` = its simulated time in s):

* every particle as a polygon (VTK_POLYGON) through its vertices ``x + R(φ) · body_vertices`` (disks: their
  24-gon outline);
* with bonds, every beam as a line (VTK_LINE) between the centroids of its two particles (failed beams too).

Cell data (one value per cell; fields that do not apply to a cell kind are NaN, or −1 for integers):

==================  =======  =================================================================
``kind``            —        0 particle, 1 beam
``particle``        —        particle index (beams: −1)
``group``           —        particle group index (names: attribute ``group_names`` of ``/polydem``)
``velocity``        cm/s     (v1, v2, 0) of the particle
``angular_velocity`` rad/s   ω of the particle
``rotation``        rad      φ − φ0 of the particle
``displacement``    cm       (u1, u2, 0) of the centroid from its initial position
``damage``          —        beam damage d (0 intact, 1 failed); only with bonds
``kappa``           —        beam history variable κ (the largest equivalent strain reached); only with bonds
==================  =======  =================================================================

A scene without bonds has no beam cells and no ``damage`` or ``kappa`` arrays (they would be NaN throughout).

Units: cm, s (the result's).  Points carry z = 0.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

VTK_LINE, VTK_POLYGON = 3, 7


def export(result, out=None) -> dict:
    """Write ``out`` (default: the result's path with the suffix ``.vtkhdf``); returns counts for the caller."""
    import h5py

    from .hdf5 import ResultError, read_bonds, read_frames, read_static

    result = Path(result)
    out = Path(out) if out else result.with_suffix(".vtkhdf")
    st = read_static(result)
    steps, times, X, V = read_frames(result)
    if len(steps) == 0:
        raise ResultError(f"{result}: no frames to export")
    bonds = read_bonds(result)
    n = len(st["mass"])
    vs = np.asarray(st["vertex_start"], np.int64)
    body = np.asarray(st["body_vertices"], float)
    nv = np.diff(vs if len(vs) == n + 1 else np.append(vs, len(body)))  # vertices per particle
    body = body[vs[0] : vs[0] + int(nv.sum())]
    owner = np.repeat(np.arange(n), nv)  # particle of every vertex
    npv = len(body)
    pairs = np.asarray(bonds["pairs"], np.int64) if bonds is not None else np.zeros((0, 2), np.int64)
    nb = len(pairs)
    npts = npv + (n if nb else 0)  # vertices, then the centroids (beam ends)
    ncells = n + nb
    # topology (the same in every frame)
    conn = np.concatenate([np.arange(npv, dtype=np.int64), (npv + pairs).ravel()])
    offsets = np.concatenate([[0], np.cumsum(np.concatenate([nv, np.full(nb, 2)]))]).astype(np.int64)
    types = np.concatenate([np.full(n, VTK_POLYGON, np.uint8), np.full(nb, VTK_LINE, np.uint8)])
    nan_b = np.full(nb, np.nan)
    F = len(steps)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".part")  # complete or absent: renamed when written, removed if not
    try:
        with h5py.File(tmp, "w") as f:
            g = f.create_group("VTKHDF")
            g.attrs["Version"] = np.array([2, 2], np.int64)
            g.attrs.create("Type", np.bytes_("UnstructuredGrid"))
            g["NumberOfPoints"] = np.full(F, npts, np.int64)
            g["NumberOfCells"] = np.full(F, ncells, np.int64)
            g["NumberOfConnectivityIds"] = np.full(F, len(conn), np.int64)
            g["Connectivity"] = np.tile(conn, F)
            g["Offsets"] = np.tile(offsets, F)
            g["Types"] = np.tile(types, F)
            pts = g.create_dataset("Points", (F * npts, 3), float)
            cd = g.create_group("CellData")
            g.create_group("PointData")
            g.create_group("FieldData")
            meta = f.create_group("polydem")  # outside /VTKHDF: ignored by VTK, kept for the reader of the file
            meta.attrs["result"] = str(result)
            meta.attrs["group_names"] = [str(q) for q in st["group_names"]]
            meta["step"] = np.asarray(steps, np.int64)
            arrays = {
                "kind": np.concatenate([np.zeros(n, np.int32), np.ones(nb, np.int32)]),
                "particle": np.concatenate([np.arange(n, dtype=np.int32), np.full(nb, -1, np.int32)]),
                "group": np.concatenate([np.asarray(st["group"], np.int32), np.full(nb, -1, np.int32)]),
            }
            for name, a in arrays.items():
                cd[name] = np.tile(a, F)
            vel = cd.create_dataset("velocity", (F * ncells, 3), float)
            om = cd.create_dataset("angular_velocity", (F * ncells,), float)
            rot = cd.create_dataset("rotation", (F * ncells,), float)
            disp = cd.create_dataset("displacement", (F * ncells, 3), float)
            if nb:  # beam fields: none without bonds
                dmg = cd.create_dataset("damage", (F * ncells,), float)
                kap = cd.create_dataset("kappa", (F * ncells,), float)
            x0 = np.asarray(X[0], float)
            for k in range(F):
                x = np.asarray(X[k], float)
                c, s = np.cos(x[owner, 2]), np.sin(x[owner, 2])
                P = np.zeros((npts, 3))
                P[:npv, 0] = x[owner, 0] + c * body[:, 0] - s * body[:, 1]
                P[:npv, 1] = x[owner, 1] + s * body[:, 0] + c * body[:, 1]
                if nb:
                    P[npv:, :2] = x[:, :2]
                pts[k * npts : (k + 1) * npts] = P
                sl = slice(k * ncells, (k + 1) * ncells)
                v = np.zeros((n, 3)) if V is None else np.asarray(V[k], float)
                vel[sl] = np.concatenate([np.column_stack([v[:, 0], v[:, 1], np.zeros(n)]), np.full((nb, 3), np.nan)])
                om[sl] = np.concatenate([v[:, 2], nan_b])
                rot[sl] = np.concatenate([x[:, 2] - x0[:, 2], nan_b])
                u = np.column_stack([x[:, 0] - x0[:, 0], x[:, 1] - x0[:, 1], np.zeros(n)])
                disp[sl] = np.concatenate([u, np.full((nb, 3), np.nan)])
                if nb:
                    dmg[sl] = np.concatenate([np.full(n, np.nan), bonds["frame_d"][k]])
                    kap[sl] = np.concatenate([np.full(n, np.nan), bonds["frame_kappa"][k]])
            s_ = g.create_group("Steps")
            s_.attrs["NSteps"] = np.int64(F)
            s_["Values"] = np.asarray(times, float)
            s_["PartOffsets"] = np.arange(F, dtype=np.int64)
            s_["NumberOfParts"] = np.ones(F, np.int64)
            s_["PointOffsets"] = np.arange(F, dtype=np.int64) * npts
            s_["CellOffsets"] = np.arange(F, dtype=np.int64) * ncells
            s_["ConnectivityIdOffsets"] = np.arange(F, dtype=np.int64) * len(conn)
            cdo = s_.create_group("CellDataOffsets")
            for name in cd:
                cdo[name] = np.arange(F, dtype=np.int64) * ncells
            s_.create_group("PointDataOffsets")
            s_.create_group("FieldDataOffsets")
            s_.create_group("FieldDataSizes")
        tmp.replace(out)
    finally:  # a failed or interrupted export leaves nothing
        tmp.unlink(missing_ok=True)
    return {"file": str(out), "frames": F, "particles": n, "beams": nb, "points": npts, "cells": ncells}
