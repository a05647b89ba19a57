"""A flap: an interior vertex whose neighbours are all on the boundary (its star hangs on the
rest of the disk by one chord edge). Without the neck split the equiareal map wraps the flap
twice around its vertex, the boundary image runs backwards and the remesh fails."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay

from pipeline.cli import main
from pipeline.errors import UserError
from pipeline.geometry import topology as topo
from pipeline.geometry.laplacian import face_double_areas
from pipeline.geometry.repair import RepairedMesh, has_interior_neighbour, repair_mesh
from pipeline.geometry.sem import SEMOptions, stretch_energy_minimization
from pipeline.io.meshio import read_mesh
from pipeline.stages.parameterize import (ParameterizationFailed, parameterize_stage,
                                          write_parameterization)
from pipeline.stages.remesh import RemeshConfig, remesh_stage

NB = 200                        # boundary vertices of the disk; the flap is one edge wide


def flap_disk(seed: int = 0) -> tuple[np.ndarray, np.ndarray, int]:
    """A noisy unit disk (Delaunay of ``NB`` circle points and a hexagonal lattice of the same
    spacing) with a six-face fan glued onto its first boundary edge from outside: the fan's
    centre (returned last) has that edge's ends and four new boundary vertices as neighbours."""
    h = 2 * np.pi / NB
    t = h * np.arange(NB)
    g = np.arange(-1, 1 + h, h)
    X, Y = np.meshgrid(g, g)
    X = X + 0.5 * h * (np.arange(len(g))[:, None] % 2)
    inner = np.column_stack([X.ravel(), Y.ravel()])
    P = np.vstack([np.column_stack([np.cos(t), np.sin(t)]),
                   inner[np.hypot(*inner.T) < 1 - 0.6 * h]])
    F = Delaunay(P).simplices
    e1, e2 = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    F[cw] = F[cw][:, [0, 2, 1]]
    a = 0.5 * h
    c = (1 + 0.8 * h) * np.array([np.cos(a), np.sin(a)])
    s = a + np.linspace(-0.6 * np.pi, 0.6 * np.pi, 4)
    n = len(P)
    P = np.vstack([P, c, c + h * np.column_stack([np.cos(s), np.sin(s)])])
    ring = sorted([0, n + 1, n + 2, n + 3, n + 4, 1],
                  key=lambda v: np.arctan2(P[v, 1] - c[1], P[v, 0] - c[0]))
    fan = np.array([[n, ring[k], ring[(k + 1) % 6]] for k in range(6)])
    V = np.column_stack([P, 0.002 * np.random.default_rng(seed).standard_normal(len(P))])
    return V, np.vstack([F, fan]), n


def _angle_sums(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The sum (n,) of the face angles of ``uv`` (n×2) at each vertex."""
    out = np.zeros(len(uv))
    for k in range(3):
        a = uv[F[:, (k + 1) % 3]] - uv[F[:, k]]
        b = uv[F[:, (k + 2) % 3]] - uv[F[:, k]]
        np.add.at(out, F[:, k], np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
                                           (a * b).sum(1)))
    return out


def test_flap_neck_is_split_and_the_map_is_injective():
    V, F, centre = flap_disk()
    is_b = topo.boundary_vertices_mask(F, len(V))
    assert not is_b[centre] and not has_interior_neighbour(F, is_b)[centre]
    m = repair_mesh(V, F)
    assert m.report["flap_necks_split"] == 1 and m.report["leaf_split_vertices_added"] == 0
    assert any("flap" in s for s in m.messages)
    is_b = topo.boundary_vertices_mask(m.F, len(m.V))
    assert has_interior_neighbour(m.F, is_b)[~is_b].all()
    assert len(m.boundary) == NB + 4                        # the boundary is unchanged
    assert np.isclose(face_double_areas(m.V, m.F).sum(), face_double_areas(V, F).sum())
    uv = stretch_energy_minimization(m.V, m.F, m.boundary).uv[:, :2]
    interior = np.setdiff1d(np.arange(len(uv)), m.boundary)
    assert np.allclose(_angle_sums(uv, m.F)[interior], 2 * np.pi)   # no vertex wound twice
    th = np.unwrap(np.arctan2(uv[m.boundary, 1], uv[m.boundary, 0]))
    assert np.all(np.diff(th) > 0)                          # the boundary image runs forwards


def test_disk_without_flap_is_left_as_it_is():
    V, F, centre = flap_disk()
    F = F[~(F == centre).any(axis=1)]
    m = repair_mesh(V[:centre], F)
    assert m.report["flap_necks_split"] == 0 and len(m.V) == centre


def test_run_remeshes_a_disk_with_a_flap(tmp_path):
    V, F, _ = flap_disk()
    mesh = tmp_path / "flap.obj"
    with open(mesh, "w") as f:
        f.writelines(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in V)
        f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F)
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"run: {{name: flap, out_dir: {tmp_path / 'out'}}}\n"
                   f"input: {{mesh: {mesh}}}\nremesh: {{vertices: 6000}}\n")
    assert main(["run", str(cfg)]) == 0
    out = read_mesh(tmp_path / "out" / "flap" / "remesh" / "remeshed.obj")
    Fo = np.asarray(out.faces)
    assert len(topo.boundary_loops(Fo, out.V)) == 1
    assert topo.euler_characteristic(Fo, len(out.V)) == 1


def _unrepaired(V, F) -> RepairedMesh:
    """The flap disk as the map stage would get it without the repair's neck split."""
    boundary = topo.boundary_loops(F, V)[0]
    return RepairedMesh(V, F, None, np.arange(len(V)), boundary, np.zeros(0, dtype=np.int64))


def test_a_map_that_wraps_the_flap_twice_is_a_failure_not_a_map(tmp_path):
    """Every face of the unrepaired flap's map is positive, yet the map is not one-to-one: the
    boundary image crosses itself, and the stage says so instead of passing the map on."""
    V, F, _ = flap_disk()
    p = parameterize_stage(_unrepaired(V, F), SEMOptions())
    assert p.flipped_faces == 0
    assert p.boundary_self_crossings == p.metrics["distortion"]["boundary_self_crossings"] > 0
    assert not p.ok and p.metrics["status"] == "failed"
    assert "boundary image crosses itself" in p.problem
    with pytest.raises(ParameterizationFailed, match="crosses itself"):
        write_parameterization(p, tmp_path / "map", figures=False)
    assert (tmp_path / "map" / "metrics.json").exists()            # written for diagnosis
    assert not (tmp_path / "map" / "parameterization.npz").exists()     # the map is not
    with pytest.raises(UserError, match="boundary image crosses itself"):
        remesh_stage(p.mesh, p.uv, RemeshConfig(vertices=2000))
