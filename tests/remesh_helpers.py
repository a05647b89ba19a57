"""Helpers shared by the remeshing tests (not a test module): small disk meshes, the synthetic
face with its map (the module-scoped fixture ``face_map``; import it into a test module to use
it) and the distance of points from a mesh."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.geometry import topology as topo
from pipeline.geometry.locate import PointLocator
from pipeline.geometry.metrics import signed_double_areas
from pipeline.geometry.remesh_quality import (MeshDistance, bounding_box_diagonal,
                                              point_mesh_distance)
from pipeline.geometry.repair import repair_mesh
from pipeline.geometry.sem import SEMOptions
from pipeline.sample import make_face
from pipeline.stages.parameterize import parameterize_stage


def disk_points(rings, per):
    """The centre and ``rings`` concentric rings of ``per × i`` points in the unit disk."""
    pts = [np.zeros((1, 2))]
    for i in range(1, rings + 1):
        t = np.linspace(0, 2 * np.pi, per * i, endpoint=False) + 0.3 * i
        pts.append(i / rings * np.column_stack([np.cos(t), np.sin(t)]))
    return np.vstack(pts)


def ccw_delaunay(uv):
    """The Delaunay triangulation of ``uv``, every face counter-clockwise."""
    from scipy.spatial import Delaunay

    F = Delaunay(uv).simplices
    return np.where((signed_double_areas(uv, F) > 0)[:, None], F, F[:, ::-1])


@pytest.fixture(scope="module")
def face_map():
    """The synthetic face (with a colour per vertex), repaired and parameterized."""
    face = make_face(2500)
    mesh = repair_mesh(face.V, face.F)
    mesh.colors = (face.V - face.V.min(0)) / np.ptp(face.V, axis=0)        # a colour per vertex
    p = parameterize_stage(mesh, SEMOptions(mode="converged", max_iter=60))
    return face, mesh, p


def remesh_map(mesh):
    """The ``remesh`` command's disk map of the repaired ``mesh`` (``mode: auto``, on a disk
    :data:`pipeline.geometry.sem.REMESH_DISK_STEPS` steps of Algorithm 1): ``(n, 2)``."""
    return parameterize_stage(mesh, SEMOptions(mode="auto")).image


def on_surface(X, mesh):
    """The largest distance of the points ``X`` from ``mesh``, over its bounding box diagonal."""
    d, _ = point_mesh_distance(X, mesh.V, mesh.F)
    return d.max() / bounding_box_diagonal(mesh.V)


def off_surface_limit(r, mesh) -> float:
    """The farthest the vertices of the remesh ``r`` may lie from ``mesh``, over its bounding
    box diagonal (:func:`on_surface`): rounding where it was not fitted to the surface (every
    vertex lifted by eq. 1), else the fit's cap, ``OFFSET_CAP`` × the target edge length
    (:mod:`pipeline.geometry.remesh.fit`)."""
    from pipeline.geometry.remesh.fit import OFFSET_CAP

    improve = r.info.get("improve", {})
    if "fit" not in improve:
        return 1e-9
    return OFFSET_CAP * improve["target_edge_length"] / bounding_box_diagonal(mesh.V) + 1e-9


def disk_map(tent: float = 0.0):
    """A unit disk mesh parameterized by its xy coordinates, with a tent of height ``tent``
    (radius 0.25) at its centre: ``(uv_in, F_in, V_in, loop, locator)``."""
    uv_in = disk_points(40, 6)
    F_in = ccw_delaunay(uv_in)
    V_in = np.column_stack([uv_in, tent * np.maximum(0, 1 - np.linalg.norm(uv_in, axis=1) / 0.25)])
    loop = topo.boundary_loops(F_in)[0]
    return uv_in, F_in, V_in, loop, PointLocator(uv_in, F_in, loop)


def coarse_state(uv_in, F_in, V_in, loop, locator, rings: int):
    """A coarse remesh of the disk map ``(uv_in, F_in)`` of ``V_in`` as a
    :class:`pipeline.geometry.remesh.state.RemeshState`: the points of :func:`disk_points`
    (``rings`` rings of 6·i) and every 10th map point on the unit circle (its rim),
    triangulated by :func:`ccw_delaunay`, located and lifted; also those rim points' map
    indices."""
    from pipeline.geometry.locate import lift
    from pipeline.geometry.remesh.state import RemeshState

    ring = np.flatnonzero(np.isclose(np.linalg.norm(uv_in, axis=1), 1.0))[::10]
    uv = np.vstack([disk_points(rings, 6), uv_in[ring]])
    F = ccw_delaunay(uv)
    face, bary = locator.locate(uv)
    S = RemeshState(lift(V_in, F_in, face, bary), F, uv, topo.boundary_vertices_mask(F, len(uv)),
                    face, bary, V_in, F_in, uv_in, locator, uv_in[loop])
    return S, ring


def creased_disk(slope: float, x0: float = 0.1, rings: int = 40, on_crease: int = 159,
                 clear: float = 0.01):
    """The unit disk folded along the line ``u = x0``: ``z = slope·|u − x0|``, its map the
    ``uv`` coordinates. The ring points of :func:`disk_points` (``rings``
    rings) farther than ``clear`` from the line and up to ``on_crease`` evenly spaced points on
    it (158 by default), so that input edges run along the crease. Returns
    ``(uv_in, F_in, V_in, loop, locator)``."""
    uv = disk_points(rings, 6)
    uv = uv[np.abs(uv[:, 0] - x0) > clear]
    y = np.linspace(-1, 1, on_crease + 2)[1:-1]
    y = y[np.abs(y) < np.sqrt(1 - x0 ** 2) - 0.02]
    uv = np.vstack([uv, np.column_stack([np.full(len(y), x0), y])])
    F = ccw_delaunay(uv)
    V = np.column_stack([uv, slope * np.abs(uv[:, 0] - x0)])
    loop = topo.boundary_loops(F)[0]
    return uv, F, V, loop, PointLocator(uv, F, loop)


def count_measured(monkeypatch) -> list:
    """A list to which every :class:`MeshDistance` query from now on (within the test) adds
    its number of points."""
    measured = []
    call = MeshDistance.__call__

    def counting(self, P):
        measured.append(len(P))
        return call(self, P)

    monkeypatch.setattr(MeshDistance, "__call__", counting)
    return measured
