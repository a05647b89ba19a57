"""Uniform remeshing of closed genus-0 meshes through the sphere map
(pipeline.geometry.remesh.sphere, pipeline.geometry.locate_sphere, the remesh stage on the sphere):
exact facts on an icosphere mapped by itself, then the bunny through its spherical SEM map."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import require_data
from pipeline.errors import UserError
from pipeline.geometry.locate import lift
from pipeline.geometry.locate_sphere import SphereLocator, sphere_barycentrics
from pipeline.geometry.remesh.domain import project
from pipeline.geometry.remesh.halfedge import disk_shape, double_areas
from pipeline.geometry.remesh.sphere import (SPHERE_JITTER, fibonacci_sphere, hull_triangulation,
                                             jittered_sphere, sphere_remesh, sphere_spacing)
from pipeline.geometry.remesh_quality import is_sphere, mesh_facts, remesh_quality
from pipeline.geometry.repair import RepairedMesh
from pipeline.geometry.sphere import triple_products
from pipeline.stages.remesh import RemeshConfig, remesh_outputs, remesh_stage


def icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """A subdivided icosahedron on the unit sphere, faces outward."""
    t = (1 + 5 ** 0.5) / 2
    V = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]],
                 float)
    V /= np.linalg.norm(V, axis=1)[:, None]
    F = hull_triangulation(V)
    for _ in range(subdivisions):
        E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        E, inv = np.unique(E, axis=0, return_inverse=True)
        mid = project(V[E[:, 0]] + V[E[:, 1]])
        m = len(F)
        a, b, c = F.T
        ab, bc, ca = len(V) + inv[:m], len(V) + inv[m:2 * m], len(V) + inv[2 * m:]
        V = np.vstack([V, mid])
        F = np.vstack([np.column_stack(x) for x in ((a, ab, ca), (ab, b, bc), (ca, bc, c),
                                                    (ab, bc, ca))])
    return V, F


def closed_mesh(V, F) -> RepairedMesh:
    n = len(V)
    return RepairedMesh(V=V, F=F, colors=None, source_index=np.arange(n),
                        boundary=np.empty(0, np.int64), added_vertices=np.empty(0, np.int64))


# ----------------------------------------------------------------------- samples and hull


@pytest.mark.parametrize("n", [12, 1000, 5001])
def test_fibonacci_hull_is_a_closed_outward_sphere(n):
    P = fibonacci_sphere(n)
    assert P.shape == (n, 3) and np.allclose(np.linalg.norm(P, axis=1), 1.0, atol=1e-15)
    F = hull_triangulation(P)
    assert len(F) == 2 * n - 4
    assert np.all(triple_products(P, F) > 0)                     # every face outward
    assert is_sphere(mesh_facts(P, F))                           # closed, manifold, χ = 2


def test_fibonacci_samples_are_even():
    P = fibonacci_sphere(4000)
    F = hull_triangulation(P)
    A = np.linalg.norm(np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]), axis=1)
    assert A.std() / A.mean() < 0.15


def test_jittered_samples_stay_in_their_lattice_cells():
    n = 3000
    P, Q = fibonacci_sphere(n), jittered_sphere(n, seed=3)
    assert np.allclose(np.linalg.norm(Q, axis=1), 1.0, atol=1e-12)
    moved = np.linalg.norm(Q - P, axis=1)        # tangent offset ≤ √2 · h/2, then normalised
    h = sphere_spacing(n)
    assert moved.max() <= SPHERE_JITTER * h / np.sqrt(2) and moved.mean() > 0.2 * h
    assert np.array_equal(Q, jittered_sphere(n, seed=3))
    assert not np.array_equal(Q, jittered_sphere(n, seed=4))
    assert is_sphere(mesh_facts(Q, hull_triangulation(Q)))


def bumpy_sphere(seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An icosphere (2562 vertices) with 12 seeded Gaussian bumps of height 0.15 pushed out
    radially, its faces and its radial map onto the unit sphere (bijective, not equiareal)."""
    S, F = icosphere(4)
    C = np.random.default_rng(seed).normal(size=(12, 3))
    C /= np.linalg.norm(C, axis=1)[:, None]
    bumps = np.exp(-((S[:, None, :] - C[None]) ** 2).sum(-1) / 0.08).sum(1)
    return S * (1 + 0.15 * bumps)[:, None], F, S


@pytest.mark.parametrize("n", [1200, 2000])
def test_jittered_samples_let_the_improvement_unshear_the_lattice(n):
    """The Fibonacci lattice is locally a sheared hexagonal one, and a topologically regular
    patch is a fixed point of the improvement's smoothing: from the exact lattice the remesh of
    a bumpy sphere keeps its shear (mean smallest angle 49.4°, 49.5°), from the jittered one
    (the default) it does not (50.7°, 50.6°)."""
    V, F, S = bumpy_sphere()

    def mean_smallest(pattern=None):
        kw = {} if pattern is None else {"pattern": pattern}
        r = sphere_remesh(V, F, S, vertices=n, **kw)
        assert len(r.V) == n
        return remesh_quality(V, F, r.V, r.F, 5000)["triangles"]["mean_min_angle_deg"]

    assert mean_smallest() > 50.2
    assert mean_smallest("hexagonal") < 50.0


def test_domain_determinant_is_the_disks_with_points_read_as_u_v_1():
    """The kernels' and double_areas' orientation on the sphere is det[a, b, c]; a plane point
    (u, v) read as (u, v, 1) gives back the disk's signed double area."""
    rng = np.random.default_rng(1)
    uv = rng.random((30, 2))
    F = rng.integers(0, 30, (40, 3))
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])]
    h = np.column_stack([uv, np.ones(30)])
    assert np.allclose(double_areas(h, F), double_areas(uv, F), rtol=1e-12, atol=1e-14)
    S = project(rng.normal(size=(30, 3)))
    det = np.einsum("ij,ij->i", S[F[:, 0]], np.cross(S[F[:, 1]], S[F[:, 2]]))
    assert np.allclose(double_areas(S, F), det, atol=1e-14)
    longest = np.max([((S[F[:, (c + 1) % 3]] - S[F[:, c]]) ** 2).sum(axis=1)
                      for c in range(3)], axis=0)
    assert np.allclose(disk_shape(S, F), det / longest, atol=1e-14)
    assert project(uv) is uv                                     # nothing to do on the disk


# ------------------------------------------------------------------------ point location


def test_located_points_reproduce_themselves_on_an_icosphere():
    S, F = icosphere(3)
    loc = SphereLocator(S, F)
    # the map's own vertices: exactly that corner
    face, bary = loc.locate(S)
    assert np.array_equal(lift(S, F, face, bary), S)
    # edge midpoints (on an edge) and random directions: central projection, coordinates ≥ 0
    E = np.sort(F[:, [0, 1]], axis=1)
    rng = np.random.default_rng(0)
    P = np.vstack([project(S[E[:, 0]] + S[E[:, 1]]), project(rng.normal(size=(20000, 3)))])
    face, bary = loc.locate(P)
    assert np.all(bary >= 0) and np.allclose(bary.sum(axis=1), 1.0, atol=1e-15)
    assert np.allclose(project(lift(S, F, face, bary)), P, atol=1e-14)
    # from a far hint (the antipode's face), walk and fallback still find every point
    far, _ = loc.locate(-P)
    f2, b2, inside = loc.relocate(P, far, walk=2)
    assert inside.all() and np.allclose(project(lift(S, F, f2, b2)), P, atol=1e-14)


def test_compiled_walk_gives_the_numpy_barycentrics_and_needs_no_face_search(monkeypatch):
    """The walk computes :func:`sphere_barycentrics` operation for operation (bit for bit, then
    clamped and renormalised), and a query whose hint is on the far side of a crowded, uneven
    map is still found by walking from its nearest map vertex: the search among the faces near
    it (``_near``) is never reached."""
    S, F = icosphere(3)
    rng = np.random.default_rng(7)
    S = project(project(S + [0.8, 0.0, 0.0]) + [0.0, 0.5, 0.0])     # crowded at −x, −y
    loc = SphereLocator(S, F)
    assert np.all(triple_products(S, F) > 0)                     # still a tiling of the sphere
    P = project(rng.normal(size=(5000, 3)))
    far, _ = loc.locate(-P)

    def no_search(*_):
        raise AssertionError("face search reached")

    # the search itself (the last resort of a walk that circles) finds the same faces
    f_near, b_near = loc._near(P, 1e-10)
    face, bary, _ = loc.relocate(P, far, walk=2)
    assert np.array_equal(f_near, face) and np.allclose(b_near, bary, rtol=0, atol=1e-15)
    monkeypatch.setattr(SphereLocator, "_near", no_search)
    face, bary, _ = loc.relocate(P, far, walk=2)
    bad_hint = np.where(np.arange(len(P)) % 2 == 0, -1, len(F))       # no face: not walked
    assert np.array_equal(loc.relocate(P, bad_hint)[0], face)
    lam = sphere_barycentrics(P, *(S[F[face, c]] for c in range(3)))
    assert lam.min() >= -1e-10
    clean = np.clip(lam, 0.0, None)
    assert np.array_equal(bary, clean / clean.sum(axis=1, keepdims=True))


def test_lifting_commutes_with_a_linear_surface():
    """Eq. (1) is linear in the vertices: a surface A·S mapped by S lifts every direction to
    A times its lift on the chordal icosphere."""
    S, F = icosphere(2)
    A = np.array([[2.0, 0.3, 0.0], [0.0, 1.0, 0.5], [0.1, 0.0, 0.7]])
    P = project(np.random.default_rng(3).normal(size=(500, 3)))
    face, bary = SphereLocator(S, F).locate(P)
    assert np.allclose(lift(S @ A.T, F, face, bary), lift(S, F, face, bary) @ A.T,
                       atol=1e-14)


# ---------------------------------------------------------------- remeshing the icosphere


def test_icosphere_mapped_by_itself_remeshes_to_a_closed_sphere():
    """Not fitted to the surface (``fit_surface`` off), every vertex is the lift of its
    sphere position."""
    S, F = icosphere(4)                                         # 2562 vertices
    r = sphere_remesh(S, F, S, vertices=1500, fit_surface=False)
    facts = mesh_facts(r.V, r.F)
    assert is_sphere(facts) and facts["degenerate_faces"] == 0
    assert r.facts == facts                                      # as its check found them
    assert len(r.V) == 1500
    assert np.all(triple_products(r.uv, r.F) > 0)                # outward on the sphere
    assert np.allclose(np.linalg.norm(r.uv, axis=1), 1.0, atol=1e-12)
    assert np.array_equal(lift(S, F, r.face, r.bary), r.V)       # every vertex lifted, eq. (1)
    # on the surface: each vertex in the chordal triangle of its face
    assert np.allclose(project(r.V), r.uv, atol=1e-12)
    # even areas (the final smoothing's area term: 0.11 with the centroid steps alone) for a
    # little of the mean smallest angle (50.0° then)
    t = remesh_quality(S, F, r.V, r.F, 5000)["triangles"]
    assert t["mean_min_angle_deg"] > 48.5 and t["area_cv"] < 0.08 and t["min_angle_deg"] > 35


def test_surface_middles_balance_the_split_on_the_surface():
    """Through the identity map of a sphere the lift of the domain midpoint is the middle of
    the edge on the surface: the split stays there, a quarter … half the edge from each end."""
    from pipeline.geometry.remesh.sag import surface_middles
    from pipeline.geometry.remesh.state import RemeshState

    S, F = icosphere(4)
    r = sphere_remesh(S, F, S, vertices=500, improve=False, pattern="hexagonal")
    st = RemeshState(r.V, r.F, r.uv, np.zeros(len(r.V), bool), r.face, r.bary, S, F, S,
                     SphereLocator(S, F), np.zeros((0, 3)))
    a, b = r.F[:50, 0], r.F[:50, 1]
    t, balance = surface_middles(st, a, b, np.arange(1, 8) / 8)
    assert np.all(t == 0.5) and np.allclose(balance, 0.5, atol=1e-3)


def test_stage_refuses_a_folded_sphere_map():
    S, F = icosphere(1)
    bad = S.copy()
    bad[0] = -bad[0]
    with pytest.raises(UserError, match="sphere map has .* flipped faces"):
        remesh_stage(closed_mesh(S, F), bad, RemeshConfig(vertices=200))


def test_stage_refuses_a_disk_only_pattern_on_a_sphere():
    S, F = icosphere(1)
    with pytest.raises(UserError, match="pattern 'blue_noise' has no sphere version"):
        remesh_stage(closed_mesh(S, F), S, RemeshConfig(vertices=200, pattern="blue_noise"))


# ------------------------------------------------------------------------ a real mesh


@pytest.fixture(scope="module")
def bunny_remesh(tmp_path_factory):
    from pipeline.geometry.sphere import folded_faces, spherical_sem
    from pipeline.io.meshio import read_mesh
    from pipeline.stages.parameterize import Parameterization, SEMOptions

    raw = read_mesh(require_data("closed", "igl_bunny.obj"))
    V, F = np.asarray(raw.V, float), np.asarray(raw.faces, np.int64)
    res = spherical_sem(V, F, max_iter=10, gradient_iter=200)
    assert folded_faces(res.S, res.F) == 0
    mesh = closed_mesh(V, res.F)
    p = Parameterization(mesh, uv=None, sem=res, options=SEMOptions(), sphere=res.S,
                         metrics={"parameterization": {"mode": "paper", "iterations": 10,
                                                       "status": "max_iter"}})
    r = remesh_stage(mesh, p.sphere, RemeshConfig(vertices=5000))
    out = tmp_path_factory.mktemp("bunny") / "remesh"
    files, metrics = remesh_outputs(mesh, p, r, out, {"source": "igl_bunny.obj"},
                                    compare=True, n_random=20000)
    return mesh, r, files, metrics


def test_bunny_remesh_is_a_closed_genus0_manifold_near_the_surface(bunny_remesh):
    mesh, r, _, metrics = bunny_remesh
    sem = metrics["methods"]["sem"]
    assert sem["is_sphere"] and sem["facts"]["euler_characteristic"] == 2
    assert sem["facts"]["degenerate_faces"] == 0 and sem["facts"]["boundary_vertices"] == 0
    assert abs(len(r.V) - 5000) <= 100
    assert sem["distance"]["hausdorff_rel"] <= 0.005
    assert np.all(triple_products(r.uv, r.F) > 0)


def test_bunny_report_sits_beside_pymeshlab(bunny_remesh):
    _, r, files, metrics = bunny_remesh
    assert {"obj", "metrics", "report", "remesh_sphere"} <= set(files)
    assert "remesh_disk" not in files
    text = files["obj"].read_text()
    assert "\nvt " not in text and "Euler characteristic 2" in text
    topo = next(row for row in metrics["table"] if row["measure"].startswith("one disk"))
    assert topo["values"]["sem"] == "yes, closed genus 0"
    if metrics["methods"]["pymeshlab_isotropic"]["available"]:
        angles = next(row for row in metrics["table"]
                      if row["measure"] == "mean of the faces' smallest angles")
        assert angles["values"]["pymeshlab_isotropic"] is not None
    assert "SEM sphere map" in files["report"].read_text()
