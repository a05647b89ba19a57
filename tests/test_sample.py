"""The embedded synthetic face sample (pipeline/sample.py): topology, landmarks, variants, files."""

import json

import numpy as np
import pytest

from pipeline import sample
from pipeline.errors import UserError
from pipeline.sample import EXPRESSIONS, LANDMARK_NAMES, FaceSample, layout, make_face, write_sample

ICT_NAMES = {
    "right_eye_outer", "right_eye_inner", "left_eye_inner", "left_eye_outer", "nose_bridge",
    "nose_tip", "subnasale", "mouth_right", "mouth_left", "upper_lip_top", "lower_lip_bottom",
    "chin", "right_brow_outer", "right_brow_inner", "left_brow_inner", "left_brow_outer",
}  # fmt: skip


# ---------------------------------------------------------------------------------- helpers


def _undirected_edges(F):
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    return np.unique(np.sort(E, axis=1), axis=0, return_counts=True)


def _boundary_loops(F):
    """Boundary loops as vertex lists, following the directed boundary half-edges."""
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    directed = set(map(tuple, E.tolist()))
    nxt = {}
    for a, b in directed:
        if (b, a) not in directed:
            assert a not in nxt, "boundary vertex with two outgoing boundary edges (not manifold)"
            nxt[a] = b
    loops, seen = [], set()
    for s in nxt:
        if s in seen:
            continue
        loop, x = [], s
        while x not in seen:
            seen.add(x)
            loop.append(x)
            x = nxt[x]
        assert x == s, "boundary edges do not close into loops"
        loops.append(loop)
    return loops


def _angles(X, F):
    out = []
    for k in range(3):
        a = X[F[:, (k + 1) % 3]] - X[F[:, k]]
        b = X[F[:, (k + 2) % 3]] - X[F[:, k]]
        c = (a * b).sum(1) / np.linalg.norm(a, axis=1) / np.linalg.norm(b, axis=1)
        out.append(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))
    return np.stack(out, axis=1)


def _signed_area_xy(V, F):
    a, b, c = V[F[:, 0], :2], V[F[:, 1], :2], V[F[:, 2], :2]
    ab, ac = b - a, c - a
    return 0.5 * (ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0])


def _segments_cross(P):
    """True if the closed polygon P (k, 2) has two non-adjacent edges that intersect."""
    A, B = P, np.roll(P, -1, axis=0)
    k = len(P)

    def orient(p, q, r):
        return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
                       - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))  # fmt: skip

    a, b = A[:, None], B[:, None]
    c, d = A[None, :], B[None, :]
    cross = (orient(a, b, c) * orient(a, b, d) < 0) & (orient(c, d, a) * orient(c, d, b) < 0)
    i, j = np.nonzero(cross)
    adjacent = (np.abs(i - j) <= 1) | (np.abs(i - j) == k - 1)
    return bool((~adjacent).any())


# ---------------------------------------------------------------------------------- topology


@pytest.mark.parametrize("n", [500, 2000, 6000])
def test_disk_topology(n):
    f = make_face(n)
    V, F = f.V, f.F
    assert V.dtype == np.float64 and V.shape[1] == 3
    assert F.dtype == np.int64 and F.shape[1] == 3
    assert F.min() == 0 and F.max() == len(V) - 1
    assert len(np.unique(F)) == len(V), "unreferenced vertex"
    edges, counts = _undirected_edges(F)
    assert set(np.unique(counts)) <= {1, 2}, "edge in more than two faces"
    assert len(V) - len(edges) + len(F) == 1, "Euler characteristic must be 1"
    loops = _boundary_loops(F)
    assert len(loops) == 1
    bnd = np.zeros(len(V), bool)
    bnd[loops[0]] = True
    assert bnd.sum() == (counts == 1).sum()
    # manifold at the vertices too: one fan per boundary vertex (V-E+F=1 and one loop imply it
    # for a connected surface) -- check connectivity explicitly
    import scipy.sparse as sp
    import scipy.sparse.csgraph as csg

    A = sp.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(len(V),) * 2)
    assert csg.connected_components(A, directed=False)[0] == 1
    # consistent orientation: every interior edge once in each direction, no directed duplicate
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    assert len(np.unique(E, axis=0)) == len(E)
    # no leaf faces, every boundary vertex adjacent to an interior vertex
    assert not bnd[F].all(axis=1).any()
    touches_interior = np.zeros(len(V), bool)
    for a, b in ((0, 1), (1, 0)):
        m = bnd[edges[:, a]] & ~bnd[edges[:, b]]
        touches_interior[edges[m, a]] = True
    assert touches_interior[bnd].all()


def test_boundary_is_the_first_block_ccw(face):
    loop = _boundary_loops(face.F)[0]
    assert sorted(loop) == list(range(len(loop)))
    # counter-clockwise seen from the front
    P = face.V[loop, :2]
    assert 0.5 * np.sum(P[:, 0] * np.roll(P[:, 1], -1) - np.roll(P[:, 0], -1) * P[:, 1]) > 0


# ---------------------------------------------------------------------------------- geometry


@pytest.mark.parametrize("expression", EXPRESSIONS)
@pytest.mark.parametrize("identity", [0, 1, 7])
def test_every_variant_is_an_embedding_facing_front(expression, identity):
    """All triangles CCW in the (x, y) projection and a simple projected rim: a graph z=f(x,y)."""
    f = make_face(2000, expression, identity)
    assert (_signed_area_xy(f.V, f.F) > 1e-6).all()
    loop = _boundary_loops(f.F)[0]
    assert not _segments_cross(f.V[loop, :2])
    assert np.isfinite(f.V).all()


def test_dimensions_in_centimetres(face):
    w, h, d = np.ptp(face.V, axis=0)
    assert 13.0 < w < 15.5
    assert 18.5 < h < 21.0
    assert 8.0 < d < 10.5


def test_min_angle(face):
    P, F = layout(6000)
    assert np.array_equal(F, face.F)
    assert _angles(P, F).min() > 20.0  # the 2-D layout
    assert _angles(face.V, face.F).min() > 12.0  # the 3-D face
    assert np.percentile(_angles(face.V, face.F).min(axis=1), 5) > 25.0


def test_uniform_edge_lengths(face):
    edges, _ = _undirected_edges(face.F)
    L = np.linalg.norm(face.V[edges[:, 0]] - face.V[edges[:, 1]], axis=1)
    assert L.max() / np.median(L) < 3.5
    assert L.min() / np.median(L) > 0.3


def test_nose_tip_is_the_most_forward_point(face):
    i = int(np.argmax(face.V[:, 2]))
    tip = face.V[face.landmarks["nose_tip"]]
    assert abs(face.V[i, 0]) < 0.5
    assert np.linalg.norm(face.V[i] - tip) < 0.6
    # near the centre of the face, well in front of everything far from it
    assert abs(face.V[i, 1] - np.median(face.V[:, 1])) < 4.0
    far = np.linalg.norm(face.V[:, :2] - face.V[i, :2], axis=1) > 3.0
    assert face.V[far, 2].max() < face.V[i, 2] - 1.0


def test_anatomy_is_where_it_belongs(face):
    V, L = face.V, face.landmarks
    p = {k: V[i] for k, i in L.items()}
    # subject's right is -x
    for part in ("eye_outer", "eye_inner", "brow_outer", "brow_inner"):
        assert p["right_" + part][0] < 0 < p["left_" + part][0]
    assert p["mouth_right"][0] < 0 < p["mouth_left"][0]
    # top to bottom
    order = ["left_brow_inner", "left_eye_inner", "nose_tip", "subnasale", "upper_lip_top",
             "mouth_left", "lower_lip_bottom", "chin"]  # fmt: skip
    ys = [p[k][1] for k in order]
    assert all(a > b for a, b in zip(ys, ys[1:]))
    # eyes sit in sockets: behind the brows and the nose bridge
    assert p["left_eye_inner"][2] < p["nose_bridge"][2]
    assert p["left_eye_inner"][2] < p["left_brow_inner"][2]
    assert p["right_eye_inner"][2] < p["right_brow_inner"][2]
    # symmetric default face
    for a, b in (("right_eye_outer", "left_eye_outer"), ("mouth_right", "mouth_left")):
        assert p[a][0] == pytest.approx(-p[b][0], abs=0.3)
        assert p[a][1] == pytest.approx(p[b][1], abs=0.3)
    # lips protrude beyond the subnasale-chin line a little; the chin is forward of the neck
    assert p["upper_lip_top"][2] > p["chin"][2]


# ---------------------------------------------------------------------------------- landmarks


@pytest.mark.parametrize("n", [300, 500, 6000])
def test_landmarks_interior_and_distinct(n):
    f = make_face(n)
    assert set(f.landmarks) == ICT_NAMES == set(LANDMARK_NAMES)
    idx = list(f.landmarks.values())
    assert all(isinstance(i, int) for i in idx)
    assert len(set(idx)) == len(idx)
    bnd = set(_boundary_loops(f.F)[0])
    assert not bnd & set(idx)
    assert all(0 <= i < len(f.V) for i in idx)


# ---------------------------------------------------------------------------------- variants


def test_expression_shares_connectivity(face, smile):
    assert np.array_equal(face.F, smile.F)
    assert face.V.shape == smile.V.shape
    assert not np.allclose(face.V, smile.V)
    assert smile.landmarks == face.landmarks
    moved = np.linalg.norm(smile.V - face.V, axis=1)
    assert moved.max() < 2.0  # a smooth, local displacement
    assert np.median(moved) < 0.05  # most of the face does not move


def test_smile_raises_and_widens_the_mouth_corners(face, smile):
    for name, side in (("mouth_left", 1.0), ("mouth_right", -1.0)):
        i = face.landmarks[name]
        assert smile.V[i, 1] > face.V[i, 1] + 0.3
        assert side * smile.V[i, 0] > side * face.V[i, 0] + 0.2
    # the cheeks bulge forward
    lm = face.landmarks
    mid = (face.V[lm["left_eye_outer"]] + face.V[lm["mouth_left"]]) / 2
    near = np.linalg.norm(face.V[:, :2] - mid[:2], axis=1) < 1.0
    assert (smile.V[near, 2] - face.V[near, 2]).mean() > 0.1


def test_jawopen_drops_the_chin():
    a, b = make_face(2000), make_face(2000, "jawopen")
    assert np.array_equal(a.F, b.F)
    i = a.landmarks["chin"]
    assert b.V[i, 1] < a.V[i, 1] - 1.0
    j = a.landmarks["lower_lip_bottom"]
    assert b.V[j, 1] < a.V[j, 1] - 1.0
    k = a.landmarks["nose_tip"]
    assert np.allclose(a.V[k], b.V[k], atol=0.05)


def test_identity_changes_shape_not_connectivity():
    a, b = make_face(2000, identity=0), make_face(2000, identity=3)
    assert np.array_equal(a.F, b.F)
    assert not np.allclose(a.V, b.V)
    assert a.name != b.name
    assert set(b.landmarks) == ICT_NAMES
    # vertex i is the same material point: corresponding landmarks stay close
    for name in ("nose_tip", "chin", "left_eye_outer"):
        assert np.linalg.norm(a.V[a.landmarks[name]] - b.V[a.landmarks[name]]) < 2.5


def test_vertex_count_close_to_request():
    for n in (2000, 6000):
        got = len(make_face(n).V)
        assert abs(got - n) <= 0.05 * n


def test_deterministic():
    a = make_face(2000, "smile", 5)
    sample._layout_cached.cache_clear()
    b = make_face(2000, "smile", 5)
    assert np.array_equal(a.V, b.V)
    assert np.array_equal(a.F, b.F)
    assert a.landmarks == b.landmarks
    assert isinstance(a, FaceSample)


def test_returned_arrays_are_the_callers():
    a = make_face(500)
    a.F[:] = 0
    a.V[:] = 0
    b = make_face(500)
    assert b.F.max() > 0 and np.abs(b.V).max() > 0


@pytest.mark.parametrize(
    "kwargs",
    [dict(expression="frown"), dict(n_vertices=10), dict(n_vertices=10**9),
     dict(n_vertices=1500.5), dict(identity="bob")],  # fmt: skip
)
def test_bad_arguments_are_user_errors(kwargs):
    with pytest.raises(UserError):
        make_face(**kwargs)


# ---------------------------------------------------------------------------------- files


def _read_obj(path):
    V, F = [], []
    for line in path.read_text().splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            V.append([float(x) for x in parts[1:4]])
        elif parts[0] == "f":
            F.append([int(x.split("/")[0]) - 1 for x in parts[1:4]])
    return np.array(V), np.array(F)


def test_write_sample(tmp_path):
    paths = write_sample(tmp_path / "out", n_vertices=1000)
    assert set(paths) == {"neutral", "smile", "landmarks"}
    assert paths["neutral"].name == "sample_face_neutral.obj"
    assert paths["smile"].name == "sample_face_smile.obj"
    assert paths["landmarks"].name == "sample_face_landmarks.json"
    Vn, Fn = _read_obj(paths["neutral"])
    Vs, Fs = _read_obj(paths["smile"])
    ref = make_face(1000)
    assert np.array_equal(Fn, ref.F) and np.array_equal(Fs, ref.F)
    assert np.allclose(Vn, ref.V, atol=1e-5)
    assert np.allclose(Vs, make_face(1000, "smile").V, atol=1e-5)
    data = json.loads(paths["landmarks"].read_text())
    assert data["source"] == "synthetic (sem-pipeline sample.py)"
    assert data["landmarks"] == ref.landmarks


def test_default_size_is_fast():
    import time

    sample._layout_cached.cache_clear()
    t = time.perf_counter()
    make_face()
    assert time.perf_counter() - t < 5.0  # < 0.2 s on an idle machine; generous for busy CI


def test_rim_faces_are_flipped_away():
    """A flat convex rim makes Delaunay put three-rim-vertex faces at its ends; they get flipped."""
    t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    rim = np.column_stack([4 * np.cos(t), 0.8 * np.sin(t)])
    inner = np.array([[-1.5, 0.0], [0.0, 0.0], [1.5, 0.0]])
    P = np.vstack([rim, inner])
    F = sample._delaunay(P)
    assert (F < 12).all(axis=1).any()  # the case exists before the fix
    G = sample._fix_rim_faces(P, F, 12)
    assert not (G < 12).all(axis=1).any()
    assert len(G) == len(F)
    assert (sample._ccw(P, G) > 0).all()
    loop = _boundary_loops(G)[0]
    k = loop.index(0)
    assert loop[k:] + loop[:k] == list(range(12))
