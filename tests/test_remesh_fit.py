"""The remesh as a least-squares approximation of its input (pipeline.geometry.remesh.fit)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from pipeline.geometry.remesh.fit import (OFFSET_CAP, Equations, Guards, fit_to_input,
                                          guarded_offsets, vertex_normals)
from pipeline.geometry.remesh.state import face_normals
from pipeline.geometry.remesh_quality import MeshDistance, surface_distance
from remesh_helpers import ccw_delaunay, disk_points


def spherical_cap(rings: int, per: int, half_angle: float = np.pi / 3):
    """A cap of the unit sphere around +z over :func:`disk_points` (the disk's radius going to
    the polar angle, up to ``half_angle``): ``(V, F)``, every vertex on the sphere, the faces
    counter-clockwise seen from outside."""
    uv = disk_points(rings, per)
    F = ccw_delaunay(uv)
    phi = np.linalg.norm(uv, axis=1) * half_angle
    theta = np.arctan2(uv[:, 1], uv[:, 0])
    V = np.column_stack([np.sin(phi) * np.cos(theta), np.sin(phi) * np.sin(theta),
                         np.cos(phi)])
    return V, F


def flat_disk(rings: int, per: int, z: float = 0.0):
    """The unit disk of :func:`disk_points` at height ``z``: ``(V, F)``, normals +z."""
    uv = disk_points(rings, per)
    return np.column_stack([uv, np.full(len(uv), z)]), ccw_delaunay(uv)


def state(X, F, V_in, F_in, locked=None):
    """What :func:`fit_to_input` reads of a remesh state."""
    return SimpleNamespace(X=X.copy(), F=F, V_in=V_in, F_in=F_in,
                           locked=np.zeros(len(X), bool) if locked is None else locked)


def mean_edge(X, F):
    return float(np.linalg.norm(X[F[:, 0]] - X[F[:, 1]], axis=1).mean())


def test_a_remesh_of_a_plane_is_not_moved():
    """Every sample of a plane lies in the remesh's plane: no signed distance, no offset — the
    vertices stay bit for bit."""
    V_in, F_in = flat_disk(30, 6)
    X, F = flat_disk(6, 6)
    S = state(X, F, V_in, F_in)
    info = fit_to_input(S, mean_edge(X, F), 20.0, F_in, MeshDistance(V_in, F_in))
    assert info["vertices_moved"] == 0 and np.array_equal(S.X, X)


def test_a_chord_mesh_of_a_sphere_moves_out_and_its_rms_distance_falls_below_0_4():
    """A coarse mesh with its vertices on a sphere lies inside it (every face a chord): the
    fit moves the vertices outwards (all but a few at the rim, whose input points beyond the
    chords would get farther), at most ``OFFSET_CAP`` × L, and the two-sided RMS
    distance (the measure's definition) falls below 0.4 × (a chord of a parabola: √(1/6) ≈
    0.41 ×), the Hausdorff distance does not grow, no face turns over."""
    V_in, F_in = spherical_cap(60, 6)
    X, F = spherical_cap(8, 6)
    S = state(X, F, V_in, F_in)
    L = mean_edge(X, F)
    info = fit_to_input(S, L, 20.0, F_in, MeshDistance(V_in, F_in))
    offset = np.einsum("ij,ij->i", S.X - X, vertex_normals(X, F))
    assert info["vertices_moved"] >= 0.95 * len(X) and np.all(offset >= 0)
    assert offset.max() <= OFFSET_CAP * L * (1 + 1e-12)
    before = surface_distance(V_in, F_in, X, F, n_random=50_000)
    after = surface_distance(V_in, F_in, S.X, F, n_random=50_000)
    assert after["rms"] < 0.4 * before["rms"]
    assert after["hausdorff"] <= before["hausdorff"]
    assert after["turned_over_faces"] == 0


def test_locked_vertices_stay_and_the_rest_still_fit():
    """Every fifth vertex locked: those stay bit for bit; the others still bring the RMS
    distance down (below 0.8 ×: around a locked vertex the faces keep their sag, and the
    samples there may not get farther) without raising the Hausdorff distance."""
    V_in, F_in = spherical_cap(60, 6)
    X, F = spherical_cap(8, 6)
    locked = np.arange(len(X)) % 5 == 0
    S = state(X, F, V_in, F_in, locked)
    fit_to_input(S, mean_edge(X, F), 20.0, F_in, MeshDistance(V_in, F_in))
    assert np.array_equal(S.X[locked], X[locked]) and not np.array_equal(S.X, X)
    before = surface_distance(V_in, F_in, X, F, n_random=50_000)
    after = surface_distance(V_in, F_in, S.X, F, n_random=50_000)
    assert after["rms"] < 0.8 * before["rms"]
    assert after["hausdorff"] <= before["hausdorff"]


def hexagon_fan(z: float = 0.0):
    """A regular hexagon around a centre vertex 0 at height ``z``: ``(X, F)``, normals +z."""
    t = np.arange(6) * np.pi / 3
    X = np.vstack([[0.0, 0.0, z], np.column_stack([np.cos(t), np.sin(t), np.full(6, z)])])
    F = np.array([[0, 1 + i, 1 + (i + 1) % 6] for i in range(6)])
    return X, F


def no_samples(F):
    return Equations(F, np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0),
                     np.zeros(0), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))


def guards(X, F, eq, V_in=None, F_in=None, min_angle_deg=20.0):
    V_in, F_in = (X, F) if V_in is None else (V_in, F_in)
    return Guards(X, F, vertex_normals(X, F), eq, MeshDistance(V_in, F_in),
                  face_normals(V_in, F_in), min_angle_deg)


@pytest.mark.parametrize("lift, kept", [(2.0, False), (0.3, True)])
def test_an_offset_that_turns_a_face_more_than_20_degrees_is_undone(lift, kept):
    """Lifting the hexagon's centre by ``lift`` turns its faces by atan(lift / cos 30°):
    66.6° is undone (all six faces fail), 19.1° kept."""
    X, F = hexagon_fan()
    offsets = np.r_[lift, np.zeros(6)]
    out, stopped = guarded_offsets(offsets, guards(X, F, no_samples(F)))
    assert np.array_equal(out, offsets if kept else np.zeros(7))
    assert stopped.get("turned", 0) == (0 if kept else 1)


def test_an_offset_that_takes_a_sample_beyond_the_farthest_is_undone():
    """The input: the hexagon 0.01 above the remesh's; one sample, face 0's centroid, 0.01
    from it (the farthest). Lifting the centre by 0.045 takes the centroid to 0.005 from it;
    by 0.09 to 0.02, farther than any sample was: undone."""
    X, F = hexagon_fan()
    V_in, F_in = hexagon_fan(0.01)
    third = np.full((1, 3), 1 / 3)
    above = X[F[0]].mean(axis=0) + [0.0, 0.0, 0.01]        # the input's point nearest it
    eq = Equations(F, np.array([0]), third, third, np.array([0.01]), np.zeros(1), np.ones(1),
                   np.zeros((0, 3)), above[None])
    g = guards(X, F, eq, V_in, F_in)
    kept = np.r_[0.045, np.zeros(6)]
    assert np.array_equal(guarded_offsets(kept, g)[0], kept)
    out, stopped = guarded_offsets(np.r_[0.09, np.zeros(6)], g)
    assert np.array_equal(out, np.zeros(7)) and stopped["reach"] == 1


def test_an_offset_that_takes_a_vertex_to_the_other_sheet_is_undone():
    """The input: the hexagon at z = 0 facing up and another at z = 0.1 facing down (two lips).
    Lifting the centre by 0.04 leaves it nearest the lower sheet; by 0.08 it is nearest the
    upper one, which faces the other way: undone."""
    X, F = hexagon_fan()
    top, F_top = hexagon_fan(0.1)
    V_in = np.vstack([X, top])
    F_in = np.vstack([F, F_top[:, ::-1] + 7])
    g = guards(X, F, no_samples(F), V_in, F_in)
    assert np.array_equal(guarded_offsets(np.r_[0.04, np.zeros(6)], g)[0], np.r_[0.04, [0] * 6])
    out, stopped = guarded_offsets(np.r_[0.08, np.zeros(6)], g)
    assert np.array_equal(out, np.zeros(7)) and stopped["sheet"] == 1


def test_a_sphere_remesh_is_fitted_too():
    """The icosphere remeshed through its own sphere map at 1500 vertices (coarser than its
    2562): fitted, the two-sided RMS distance to it falls below 0.8 × the lifted remesh's,
    the Hausdorff distance does not grow; still a closed sphere with no fold."""
    from pipeline.geometry.remesh.sphere import sphere_remesh
    from pipeline.geometry.remesh_quality import is_sphere, mesh_facts
    from test_remesh_sphere import icosphere

    S, F = icosphere(4)
    lifted = sphere_remesh(S, F, S, vertices=1500, fit_surface=False)
    fitted = sphere_remesh(S, F, S, vertices=1500)
    assert np.array_equal(fitted.F, lifted.F) and is_sphere(mesh_facts(fitted.V, fitted.F))
    before = surface_distance(S, F, lifted.V, lifted.F, n_random=50_000)
    after = surface_distance(S, F, fitted.V, fitted.F, n_random=50_000)
    assert after["rms"] < 0.8 * before["rms"] and after["hausdorff"] <= before["hausdorff"]
    assert after["turned_over_faces"] == 0


def test_a_real_remesh_is_fitted_without_new_folds_or_thin_faces():
    """gpp_bunny (1,355 vertices) remeshed at 5000 with its ``remesh`` map: the fit changes
    no face (the same connectivity), lowers the two-sided RMS distance by more than 15 %, and
    leaves no fold and no face below 20° that no input corner forces (the remesh without the
    fit has none either)."""
    from conftest import require_data
    from pipeline.stages.load import load_stage
    from pipeline.stages.remesh import RemeshConfig, remesh_stage
    from remesh_helpers import remesh_map

    mesh = load_stage(require_data("meshes", "gpp_bunny.obj")).mesh
    uv = remesh_map(mesh)
    runs = {fit: remesh_stage(mesh, uv, RemeshConfig(vertices=5000,
                                                     improve={"fit_surface": fit}))
            for fit in (False, True)}
    assert np.array_equal(runs[True].F, runs[False].F)
    d = {fit: surface_distance(mesh.V, mesh.F, r.V, r.F, n_random=50_000)
         for fit, r in runs.items()}
    assert d[True]["rms"] < 0.85 * d[False]["rms"]
    for fit, r in runs.items():
        assert d[fit]["turned_over_faces"] == 0
        assert r.info["improve"]["below_min_angle"]["unforced_faces"] == 0
