"""Per-face measures kept between counts (pipeline.geometry.remesh.face_memo): recomputed only
for the faces that changed, equal to a count over all faces."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from pipeline.geometry.remesh.face_memo import FaceMemo, changed_faces, snapshot


def _state(X, F):
    X = np.asarray(X, float)
    return SimpleNamespace(X=X, uv=X[:, :2].copy(), face=np.zeros(len(X), np.int64),
                           F=np.asarray(F, np.int64), n=len(X))


def _memo():
    """A memo of each face's corner sum of ``X`` that records the faces it computes."""
    asked = []

    def measure(S, faces):
        asked.append(np.asarray(faces).tolist())
        return S.X[S.F[faces]].sum(axis=(1, 2))

    return FaceMemo(measure), asked


def test_face_memo_recomputes_only_changed_faces_and_matches_a_full_count():
    """A fan of four faces around vertex 0 and a face apart: moving vertex 5 recomputes only
    faces 3 and 4, its input face changed only face 4's, a rewritten row only that face, an
    appended face only itself, a shrunk vertex list (vertex 6 gone, face 4 rewritten) only
    face 4; nothing changed, nothing recomputed. The values are always those of a full
    count."""
    X = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [2, 2, 0], [3, 2, 0]]
    S = _state(X, [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1], [5, 6, 1]])
    memo, asked = _memo()
    full = lambda: S.X[S.F].sum(axis=(1, 2))    # noqa: E731
    assert np.array_equal(memo(S), full()) and asked == [[0, 1, 2, 3, 4]]
    memo(S)
    assert asked[-1] == [0, 1, 2, 3, 4] and len(asked) == 1
    S.X = S.X.copy()
    S.X[1, 2] = 0.5
    assert np.array_equal(memo(S), full()) and asked[-1] == [0, 3, 4]
    S.face = S.face.copy()
    S.face[6] = 7
    assert np.array_equal(memo(S), full()) and asked[-1] == [4]
    S.F = S.F.copy()
    S.F[1] = [0, 2, 4]
    assert np.array_equal(memo(S), full()) and asked[-1] == [1]
    S.F = np.vstack([S.F, [[1, 5, 2]]])
    assert np.array_equal(memo(S), full()) and asked[-1] == [5]
    S.X, S.uv, S.face, S.n = S.X[:6], S.uv[:6], S.face[:6], 6
    S.F = S.F.copy()
    S.F[4] = [5, 2, 1]
    assert np.array_equal(memo(S), full()) and asked[-1] == [4]
    n = len(asked)
    memo(S)
    assert len(asked) == n


def test_changed_faces_sees_a_moved_disk_position():
    S = _state([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 1, 2], [1, 3, 2]])
    seen = snapshot(S)
    S.uv = S.uv.copy()
    S.uv[3, 0] = 1.5
    assert changed_faces(S, seen).tolist() == [False, True]


def test_face_memo_restored_with_the_remesh_recomputes_nothing():
    S = _state([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 1, 2], [1, 3, 2]])
    memo, asked = _memo()
    before = memo(S)
    kept, X = memo.kept(), S.X
    S.X = X + 1.0
    assert memo(S).tolist() == (before + 9.0).tolist() and asked[-1] == [0, 1]
    S.X = X
    memo.restore(kept)
    assert memo(S).tolist() == before.tolist() and len(asked) == 2
