"""Feature lines: remesh vertices on the input's creases, the edges between them kept
(pipeline.geometry.remesh.features)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.geometry.metrics import signed_double_areas
from pipeline.geometry.remesh import uniform_remesh
from pipeline.geometry.remesh.features import (chain_points, consecutive_pairs, feature_chains,
                                               feature_edges, join_edges, release_features)
from pipeline.geometry.remesh.flips import flip_edges
from pipeline.geometry.remesh.halfedge import edge_table
from pipeline.geometry.remesh_quality import (MeshDistance, is_disk, mesh_facts,
                                              triangle_quality)
from remesh_helpers import coarse_state, creased_disk, remesh_map

X0 = 0.1          # creased_disk folds the unit disk along u = X0


def on_crease(uv: np.ndarray) -> np.ndarray:
    """The points (indices) exactly on the crease line, in order along it."""
    on = np.flatnonzero(np.abs(uv[:, 0] - X0) < 1e-12)
    return on[np.argsort(uv[on, 1])]


def edge_set(F: np.ndarray) -> set:
    """Every edge of ``F`` as a sorted vertex pair."""
    _, a, b, _ = edge_table(F)
    return set(zip(np.minimum(a, b).tolist(), np.maximum(a, b).tolist()))


def test_the_crease_of_a_folded_disk_is_one_chain_in_order():
    """The disk folded at slope 2 (a 126.87° dihedral) with 155 input vertices on the crease:
    the feature edges at 30° are the 154 crease edges and 3 edges of one face cut off at the
    crease's lower end (82.6–86.6°); the crease is one chain through its 155 vertices in order,
    and its points lie on the crease, the first and last at its ends."""
    uv, F, V, _, _ = creased_disk(2.0)
    crease = on_crease(uv)
    E, angle = feature_edges(V, F, 30.0)
    assert len(E) == 157 and len(crease) == 155
    along = np.all(np.abs(uv[E, 0] - X0) < 1e-12, axis=1)
    assert along.sum() == 154
    np.testing.assert_allclose(np.degrees(angle[along]), 2 * np.degrees(np.arctan(2.0)))
    chains = feature_chains(V, E)
    c = int(np.argmax([len(ch) for ch in chains]))
    longest = chains[c]
    assert sorted(map(len, chains)) == [2, 2, 2, 155]
    assert longest.tolist() in (crease.tolist(), crease[::-1].tolist())
    L = 0.1
    P, chain, rank = chain_points(V, uv, chains, L, min_length=0.8)
    mine = chain == c
    assert np.all(np.abs(P[mine, 0] - X0) < 1e-12)
    ends = P[mine][[0, -1], 1]
    assert set(np.round(ends, 12)) == set(np.round(uv[crease[[0, -1]], 1], 12))
    steps = np.abs(np.diff(P[mine, 1]))                     # the crease is straight along v
    assert steps.max() <= 1.25 * L and steps.min() >= 0.75 * L
    assert rank[mine][0] == 0 and rank[mine][-1] == 0
    assert len(P) == mine.sum()                             # the cut-off edges are too short


@pytest.mark.timeout(60)
def test_remesh_puts_vertices_on_the_crease_and_keeps_the_edges_between_them():
    """The folded disk (slope 2) remeshed at 1000 vertices, ``follow_input`` off: without
    feature lines two remesh vertices lie on the crease and an input vertex of it is 0.35 L
    from the remesh; with them (30°) 22 do, every two consecutive ones are joined by an edge,
    and every input vertex of the crease lies on the remesh (to rounding; not fitted to the
    surface, every vertex on it), with the count, one disk and the smallest angle still at
    least 20°."""
    uv, F, V, loop, _ = creased_disk(2.0)
    crease = on_crease(uv)
    facts = {}
    for angle in (0.0, 30.0):
        r = uniform_remesh(V, F, uv, loop, vertices=1000, follow_input=0.0,
                           feature_angle_deg=angle, fit_surface=False)
        L = r.info["spacing_mesh_units"]
        on = on_crease(r.uv)
        joined = [tuple(sorted(p)) for p in zip(on[:-1].tolist(), on[1:].tolist())]
        facts[angle] = (len(on), sum(p in edge_set(r.F) for p in joined),
                        MeshDistance(r.V, r.F)(V[crease])[0].max() / L)
        assert len(r.V) == 1000 and is_disk(mesh_facts(r.V, r.F))
        assert triangle_quality(r.V, r.F)["min_angle_deg"] >= 20.0
    assert facts[0.0][0] == 2 and facts[0.0][2] > 0.35
    assert facts[30.0][:2] == (22, 21) and facts[30.0][2] < 1e-12


def test_joined_edges_survive_flips_and_are_released():
    """On a coarse remesh (4 rings) of the folded disk: the far corners of an interior quad
    are joined by one flip (:func:`join_edges`); the Delaunay flips take that edge back out
    unless it is kept (``fixed``: :meth:`.state.RemeshState.is_joined`, either way round), and
    freeing one end (:func:`release_features`) drops it and unlocks both ends, on no other
    kept edge."""
    S, _ = coarse_state(*creased_disk(2.0), 4)
    h, a, b, twin = edge_table(S.F)
    for k in np.flatnonzero((twin >= 0) & ~S.is_rim[a] & ~S.is_rim[b]):
        p = S.F[h[k] // 3, (h[k] % 3 + 2) % 3]
        q = S.F[twin[k] // 3, (twin[k] % 3 + 2) % 3]
        pair = join_edges(S, np.array([[p, q]]))
        if len(pair):
            break
    assert pair.tolist() == [[p, q]] and (min(p, q), max(p, q)) in edge_set(S.F)
    assert (min(a[k], b[k]), max(a[k], b[k])) not in edge_set(S.F)
    assert (signed_double_areas(S.uv, S.F) > 0).all()
    S.joined = pair
    S.locked[[p, q]] = True
    F_free, _, _ = flip_edges(S.X, S.F, S.uv, 90.0)
    F_kept, _, _ = flip_edges(S.X, S.F, S.uv, 90.0, fixed=S.is_joined)
    assert (min(p, q), max(p, q)) not in edge_set(F_free)
    assert (min(p, q), max(p, q)) in edge_set(F_kept)
    assert S.is_joined(np.array([q, p, a[k]]), np.array([p, q, b[k]])).tolist() == [True, True,
                                                                                    False]
    at = np.zeros(S.n, bool)
    at[p] = True
    assert len(release_features(S, at)) == 2
    assert len(S.joined) == 0 and not S.locked[[p, q]].any()


def test_placed_feature_points_are_joined_with_no_flat_face():
    """On a coarse remesh (6 rings) of the folded disk with 155 input vertices on the straight
    crease: every feature point gets a locked vertex exactly on the crease, consecutive ones
    are joined by edges, and no face is left thinner than ``DISK_SHAPE_MIN`` on the disk (three
    snapped points on one straight crease would make one)."""
    from pipeline.geometry.remesh.features import place_features
    from pipeline.geometry.remesh.halfedge import DISK_SHAPE_MIN, disk_shape

    S, _ = coarse_state(*creased_disk(2.0), 6)
    L = 0.3
    pairs = place_features(S, L)
    on = on_crease(S.uv)
    assert len(on) == S.log["feature_points"] - S.log["features_too_close"]
    assert S.locked[on].all()
    assert len(pairs) == len(on) - 1 == S.log["features_joined"]
    kept = edge_set(S.F)
    assert all((min(p, q), max(p, q)) in kept for p, q in zip(on[:-1], on[1:]))
    assert disk_shape(S.uv, S.F).min() >= DISK_SHAPE_MIN


def test_join_flip_refuses_a_face_turned_over_on_the_surface():
    """A quad convex on the disk but not on the surface (its corner ``p`` pushed towards the
    opposite diagonal end in 3D): the flip of ``p–q`` would turn the new face ``(x, p, y)``
    over (normal −z against the input's +z at its corners) and is refused, ``F`` unchanged;
    the same quad flat as on the disk flips."""
    from pipeline.geometry.remesh.features import _flip
    from pipeline.geometry.remesh.state import turned_against

    x, p, q, y = 0, 1, 2, 3
    uv = np.array([[-1.0, 0.0], [0.0, -1.0], [0.0, 1.0], [1.0, 0.0]])
    F = np.array([[x, p, q], [y, q, p]])

    def vf(F):
        out = {}
        for t, f in enumerate(F.tolist()):
            for v in f:
                out.setdefault(v, set()).add(t)
        return out

    up = np.tile([0.0, 0.0, 1.0], (4, 1))
    X = np.array([[-1.0, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    F1 = F.copy()
    assert _flip(F1, vf(F1), uv, 0, p, q, lambda T: turned_against(X, T, up[T])) is None
    assert np.array_equal(F1, F)
    flat = np.column_stack([uv, np.zeros(4)])
    F2 = F.copy()
    assert _flip(F2, vf(F2), uv, 0, p, q, lambda T: turned_against(flat, T, up[T])) == 1
    assert edge_set(F2) == {(0, 1), (0, 2), (1, 3), (2, 3), (0, 3)}


def test_no_feature_line_where_the_map_stretches_the_input_too_much():
    """The folded disk's map is the plane projection: every input face has the dilatation
    ``√(1 + slope²)`` (2.24 at slope 2, 10.05 at slope 10). Below ``MAX_DILATATION`` (8) its
    crease gets feature points; above it none (flips and joins on a disk that squeezes the
    surface that much fold it); :func:`feature_edges` keeps only the edges between the faces
    it is given."""
    from pipeline.geometry.remesh.features import MAX_DILATATION, place_features

    assert 2.3 < MAX_DILATATION < 10.0
    uv, F, V, loop, _ = creased_disk(2.0)
    E, _ = feature_edges(V, F, 30.0)
    upper = uv[F].mean(axis=1)[:, 1] > 0
    E_up, _ = feature_edges(V, F, 30.0, faces=upper)
    assert 0 < len(E_up) < len(E) and (uv[E_up, 1] >= 0).all()
    counts = {}
    for slope in (2.0, 10.0):
        S, _ = coarse_state(*creased_disk(slope), 6)
        place_features(S, 0.3)
        counts[slope] = S.log.get("feature_points", 0)
    assert counts[2.0] > 0 and counts[10.0] == 0


def test_freed_feature_vertices_are_not_locked_again():
    """A snapshot of the locks taken while a kept edge's ends are locked, applied again after
    a repair freed them (``_Operations.lock_at``), locks the other vertex of the snapshot but
    not the freed ends (no later release could free them: they are on no kept edge)."""
    from pipeline.geometry.remesh.improve import _Operations

    S, _ = coarse_state(*creased_disk(2.0), 4)
    inner = np.flatnonzero(~S.is_rim)
    p, q, r = inner[:3]
    S.joined = np.array([[p, q]])
    S.locked[[p, q, r]] = True
    snapshot = S.X[S.locked].copy()
    ops = _Operations(S, 0.3, True, 20.0, 0.5, 0.2)
    ops.release(np.flatnonzero((S.F == p).any(axis=1)))
    assert len(S.joined) == 0 and not S.locked[[p, q]].any() and S.locked[r]
    ops.lock_at(snapshot)
    assert np.flatnonzero(S.locked).tolist() == [r]


def test_even_out_moves_feature_neighbours_and_frees_feature_vertices_at_skinny_faces():
    """The last smoothing steps on the folded disk with feature lines placed (12 rings,
    ``L`` = 0.15, two smoothing steps and flips): the feature vertices at a face with an angle
    below ``FEATURE_RELEASE_DEG`` lose their kept edges; those still on a kept edge stay where
    they are, while interior vertices next to them move (the ring around the followed vertices
    that stays put does not include theirs)."""
    from pipeline.geometry.remesh.features import place_features
    from pipeline.geometry.remesh.improve import FEATURE_RELEASE_DEG, _Operations, skinny_faces

    S, _ = coarse_state(*creased_disk(2.0), 12)
    L = 0.15
    ops = _Operations(S, L, True, 20.0, 0.5, 0.2)
    joined = place_features(S, L)
    ops.features = S.X[np.unique(joined)]
    for _ in range(2):
        ops.relax()
        ops.flip()
    ends = np.unique(S.joined)
    at_skinny = np.intersect1d(ends, S.F[skinny_faces(S.X, S.F, FEATURE_RELEASE_DEG)])
    uv0 = S.uv.copy()
    ops.even_out(4, 20.0, S.X[S.locked])
    still = np.unique(S.joined)
    assert len(at_skinny) > 0 and not np.isin(at_skinny, still).any()
    assert len(still) > 0 and np.array_equal(S.uv[still], uv0[still])
    beside = np.unique(S.F[np.isin(S.F, still).any(axis=1)])
    beside = beside[~np.isin(beside, ends) & ~S.is_rim[beside]]
    assert (S.uv[beside] != uv0[beside]).any(axis=1).any()


def test_only_consecutive_feature_points_with_vertices_are_joined():
    """Points 0–4 on chain 0 (point 2 without a vertex), 5–6 on chain 1, 7 on chain 2 at the
    same vertex as 6: the pairs are 0–1, 3–4 and 5–6 (not 1–3 across the missing point, not
    4–5 across chains, not 6–7, one vertex)."""
    v = np.array([10, 11, -1, 13, 14, 15, 16, 16])
    chain = np.array([0, 0, 0, 0, 0, 1, 1, 2])
    assert consecutive_pairs(v, chain).tolist() == [[10, 11], [13, 14], [15, 16]]


def grooved_square(n: int = 121, half_width: float = 0.017, depth: float = 0.4,
                   end: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """The square [-1, 1]² (an n × n grid) with a V groove along v = 0, ``depth`` deep and
    ``half_width`` wide on either side, full depth from the rim at u = -1 to u = 0, then
    tapering to nothing at u = ``end``: a fold of 175° along its bottom (one grid line),
    ending inside the surface as a closed mouth's slit does at its corner."""
    t = np.linspace(-1.0, 1.0, n)
    u, v = np.meshgrid(t, t, indexing="ij")
    taper = np.clip((end - u) / end, 0.0, 1.0)
    z = -depth * np.clip(1.0 - np.abs(v) / half_width, 0.0, None) * taper
    i = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    F = np.vstack([np.column_stack([i, i + n, i + n + 1]), np.column_stack([i, i + n + 1, i + 1])])
    return np.column_stack([u.ravel(), v.ravel(), z.ravel()]), F


@pytest.mark.timeout(120)
def test_remesh_command_follows_a_fold_that_turns_back():
    """The grooved square through the remesh stage's defaults at 5000 vertices (its SEM map,
    as the command makes it): the groove's bottom folds by 175°, and the default feature
    lines (``FOLD_BACK_DEG``) keep vertices and edges along it, so no input point is farther
    than 0.3 L from the remesh (0.25 L; with ``feature_angle_deg`` 0, 0.42 L), with the
    smallest angle at least 20°, no face turned over, one disk and the count within 2 %."""
    from pipeline.geometry.remesh.features import FOLD_BACK_DEG
    from pipeline.geometry.remesh_quality import remesh_quality
    from pipeline.geometry.repair import repair_mesh
    from pipeline.stages.remesh import ImproveConfig, RemeshConfig, remesh_stage

    V, F = grooved_square()
    _, angle = feature_edges(V, F, FOLD_BACK_DEG)
    assert np.degrees(angle.max()) > 170.0
    mesh = repair_mesh(V, F, name="grooved")
    uv = remesh_map(mesh)
    assert ImproveConfig().feature_angle_deg == FOLD_BACK_DEG
    r = remesh_stage(mesh, uv, RemeshConfig(vertices=5000))
    L = r.info["improve"]["target_edge_length"]
    q = remesh_quality(mesh.V, mesh.F, r.V, r.F)
    assert r.info["improve"]["features_joined"] > 0
    assert q["distance"]["input_to_output"]["max"] < 0.3 * L
    assert q["triangles"]["min_angle_deg"] >= 20.0
    assert q["distance"]["turned_over_faces"] == 0
    assert q["is_disk"] and abs(len(r.V) - 5000) <= 100


def test_face_sets_are_the_loops_sets_and_iterate_alike():
    """:func:`face_sets` gives every vertex of the faces the set of its faces, laid out as a
    loop adding the faces in order lays them out: the sets, their unions and intersections
    iterate in the same order, also after the faces of a flip are moved between sets asked
    for before or made at the move (a Delaunay disk; an unused vertex, or one out of range,
    is no key)."""
    from pipeline.geometry.remesh.features import face_sets

    from remesh_helpers import ccw_delaunay, disk_points

    uv = disk_points(8, 6)
    F = ccw_delaunay(uv)
    n = len(uv)
    loop = {}
    for t, f in enumerate(F.tolist()):
        for v in f:
            loop.setdefault(v, set()).add(t)
    got = face_sets(F, n + 1)
    for v in (n, n + 1, -1):
        with pytest.raises(KeyError):
            got[v]
    rng = np.random.default_rng(3)
    for p, q in rng.integers(0, n, (200, 2)).tolist():
        assert list(got[p] | got[q]) == list(loop[p] | loop[q])
        assert list(got[p] & got[q]) == list(loop[p] & loop[q])
    # a flip's two faces moved between the sets as features._flip moves them, in sets asked
    # for before (got) and in sets made at the move (fresh): still laid out as the loop's
    fresh = face_sets(F, n + 1)
    for sets in (got, fresh, loop):
        t = 0
        g = min((sets[F[t, 1]] & sets[F[t, 2]]) - {t})
        for v in sorted(set(F[t].tolist()) | set(F[g].tolist())):
            sets[v].discard(t)
            sets[v].discard(g)
        for v in range(n):
            sets[v].add(t if v % 2 else g)
    for sets in (got, fresh):
        assert sets.keys() == loop.keys() and n not in sets
        assert all(list(sets[v]) == list(loop[v]) for v in loop)
    assert max(len(s) for s in got.values()) >= 6
