"""Shared test helpers.

``require_data(*parts)`` locates the third-party test meshes (never copied into the repo):
``$SEM_DATA`` or ``<repo>/../shared/data``. Missing data skips the test locally and fails it on
CI (``CI=true``). Import it with ``from conftest import require_data`` (``tests`` must be on the
python path: ``pythonpath = [".", "tests"]`` in the pytest config).

Shared fixtures and builders, defined here once:

* synthetic faces (``pipeline.sample``): ``synthetic_face`` (a cached ``make_face``), ``face`` and
  ``smile`` (the 6000-vertex neutral/smiling pair), ``small_face`` (an 800-vertex face written as
  OBJ), ``sample_files`` (``write_sample`` of a 900-vertex pair and its landmarks);
* planar disk meshes with exact facts (``delaunay_disk``, ``polar_disk``, fixtures ``ddisk`` and
  ``pdisk``), a curved surface over them (``height_field``), flip-free maps of them
  (``random_flip_free_maps``), and independent formulas of the paper (``independent_areas``,
  ``stretch_L``) for the SEM kernel tests;
* ``load_mesh(name)``: ``meshes/<name>.obj`` of the shared data (v/f only).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.spatial import Delaunay

from pipeline.geometry import metrics
from pipeline.geometry.laplacian import (corner_dot_over_area, edge_weights, face_double_areas,
                                         laplacian_matrix)
from pipeline.geometry.topology import boundary_loops

REPO = Path(__file__).resolve().parents[1]
DATA_DIR = Path(
    os.environ.get("SEM_DATA", Path(__file__).resolve().parents[1].parent / "shared" / "data")
)


def require_data(*parts) -> Path:
    """Path of ``DATA_DIR / parts``; skip (fail on CI) when it does not exist."""
    path = DATA_DIR.joinpath(*parts)
    if not path.exists():
        msg = f"shared data not found at {path}; set SEM_DATA"
        if os.environ.get("CI") == "true":
            pytest.fail(msg)
        pytest.skip(msg)
    return path


def run_cli(*args, cwd=None):
    """Run ``python -m pipeline`` in a subprocess (what a user sees: stdout, stderr, code)."""
    proc = subprocess.run([sys.executable, "-m", "pipeline", *map(str, args)], cwd=cwd or REPO,
                          capture_output=True, text=True, timeout=600,
                          env=dict(os.environ, PYTHONPATH=str(REPO)))
    return proc.returncode, proc.stdout, proc.stderr


# ------------------------------------------------------------------------- synthetic faces


@pytest.fixture(scope="session")
def synthetic_face():
    """``make_face(n_vertices, expression, identity)``, each built once per session.

    The samples are shared between tests: a test that modifies ``V`` or ``F`` copies them first.
    """
    from pipeline.sample import make_face

    cache = {}

    def get(n_vertices: int = 6000, expression: str = "neutral", identity: int = 0):
        key = (n_vertices, expression, identity)
        if key not in cache:
            cache[key] = make_face(n_vertices, expression, identity)
        return cache[key]

    return get


@pytest.fixture(scope="session")
def face(synthetic_face):
    """The default synthetic face (6000 vertices, neutral)."""
    return synthetic_face(6000)


@pytest.fixture(scope="session")
def smile(synthetic_face):
    """The default synthetic face smiling (same connectivity and landmarks as ``face``)."""
    return synthetic_face(6000, "smile")


@pytest.fixture(scope="session")
def small_face(tmp_path_factory, synthetic_face):
    """``(path, sample)``: the 800-vertex neutral synthetic face written as ``face.obj``."""
    from pipeline.io.meshio import write_obj

    s = synthetic_face(800)
    path = write_obj(tmp_path_factory.mktemp("face") / "face.obj", s.V, s.F)
    return path, s


@pytest.fixture(scope="session")
def sample_files(tmp_path_factory):
    """``write_sample`` of the 900-vertex neutral/smiling pair: paths under ``"neutral"``,
    ``"smile"``, ``"landmarks"``."""
    from pipeline.sample import write_sample

    return write_sample(tmp_path_factory.mktemp("sample"), n_vertices=900)


# ---------------------------------------------------------- planar disks and SEM formulas


def boundary_loop(F: np.ndarray, V: np.ndarray | None = None) -> np.ndarray:
    """The first boundary loop of ``(V, F)`` as an int64 index array."""
    return np.asarray(boundary_loops(F, V)[0], dtype=np.int64)


def load_mesh(name: str) -> tuple[np.ndarray, np.ndarray]:
    """``meshes/<name>.obj`` (v/f only); skip when the data folder is missing (fail in CI)."""
    path = require_data("meshes", f"{name}.obj")
    V, F = [], []
    with open(path) as fh:
        for line in fh:
            if line.startswith("v "):
                V.append(line.split()[1:4])
            elif line.startswith("f "):
                F.append([s.split("/")[0] for s in line.split()[1:4]])
    return np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64) - 1


def orient_ccw(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """``F`` with every clockwise face of the planar mesh ``P`` (n, 2) reversed."""
    s = metrics.signed_double_areas(P, F)
    F = F.copy()
    F[s < 0] = F[s < 0][:, [0, 2, 1]]
    return F


def delaunay_disk(n_boundary=48, n_interior=200, seed=0):
    """Planar unit-disk mesh: ``n_boundary`` equally spaced vertices on the circle (vertex 0 at
    angle 0, listed first, counter-clockwise), well spaced random interior points, Delaunay
    faces oriented counter-clockwise. Not symmetric."""
    rng = np.random.default_rng(seed)
    th = 2 * np.pi * np.arange(n_boundary) / n_boundary
    pts = [np.array([np.cos(t), np.sin(t)]) for t in th]
    spacing = 0.6 / np.sqrt(n_interior)
    while len(pts) < n_boundary + n_interior:
        p = rng.uniform(-1, 1, 2)
        if np.hypot(*p) < 0.93 and min(np.hypot(*(p - q)) for q in pts) > spacing:
            pts.append(p)
    P = np.asarray(pts)
    F = orient_ccw(P, Delaunay(P).simplices.astype(np.int64))
    return P, F


def polar_disk(n_rings=6, n_per_ring=32):
    """Planar unit-disk mesh with exact ``n_per_ring``-fold rotational symmetry: a centre vertex
    and concentric rings of equally many vertices, each ring rotated half a step against the next.
    The boundary is the last ring (equally spaced, its vertex 0 at angle 0)."""
    P = [np.zeros((1, 2))]
    for k in range(1, n_rings + 1):
        th = 2 * np.pi * (np.arange(n_per_ring) + 0.5 * (n_rings - k)) / n_per_ring
        P.append(k / n_rings * np.column_stack([np.cos(th), np.sin(th)]))
    P = np.vstack(P)
    N = n_per_ring

    def ring(k, j):
        return 1 + (k - 1) * N + j % N

    F = [[0, ring(1, j), ring(1, j + 1)] for j in range(N)]
    for k in range(1, n_rings):
        for j in range(N):
            F.append([ring(k, j), ring(k + 1, j), ring(k + 1, j + 1)])
            F.append([ring(k, j), ring(k + 1, j + 1), ring(k, j + 1)])
    return P, orient_ccw(P, np.asarray(F, dtype=np.int64))


def loop_from_angle_zero(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Boundary loop (counter-clockwise) rolled to start at the boundary vertex at angle 0."""
    b = boundary_loop(F, P)
    k = int(np.flatnonzero(np.abs(P[b, 0] - 1) + np.abs(P[b, 1]) < 1e-12)[0])
    return np.roll(b, -k)


def height_field(P: np.ndarray) -> np.ndarray:
    """A curved 3D surface over the planar disk mesh (a real, non-developable disk surface)."""
    x, y = P[:, 0], P[:, 1]
    return np.column_stack([x, y, 0.4 * np.sin(2.0 * x) * np.cos(1.5 * y) + 0.3 * x * y])


def as_complex(uv: np.ndarray) -> np.ndarray:
    """(n, 2) planar points as n complex numbers."""
    return uv[:, 0] + 1j * uv[:, 1]


def independent_areas(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Unsigned triangle areas by numpy's cross product (independent of the package)."""
    if X.shape[1] == 2:
        X = np.column_stack([X, np.zeros(len(X))])
    return 0.5 * np.linalg.norm(np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]), axis=1)


def stretch_L(X: np.ndarray, F: np.ndarray, uv: np.ndarray, pattern) -> sp.csr_matrix:
    """The full stretch Laplacian L(f), eq. (12)–(14), as an n×n matrix."""
    w = edge_weights(pattern, corner_dot_over_area(uv, F, face_double_areas(X, F)))
    return laplacian_matrix(F, len(X), w, pattern.edges)


def random_flip_free_maps(P, F, rng, k=5, scale=0.05):
    """Non-affine flip-free maps of a planar mesh: a smooth random warp plus vertex noise of a
    tenth of the shortest incident edge."""
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    elen = np.linalg.norm(P[E[:, 0]] - P[E[:, 1]], axis=1)
    hmin = np.full(len(P), np.inf)
    np.minimum.at(hmin, E.ravel(), np.repeat(elen, 2))
    out = []
    for _ in range(200):
        K = rng.uniform(-3, 3, size=(2, 2))
        phase = rng.uniform(0, 2 * np.pi, size=2)
        warp = np.sin(P @ K.T + phase)
        uv = P + scale * warp + 0.1 * hmin[:, None] * rng.uniform(-1, 1, size=P.shape)
        if len(metrics.flipped_faces(uv, F)) == 0:
            out.append(uv)
            if len(out) == k:
                return out
    raise AssertionError("could not draw flip-free maps")


@pytest.fixture(scope="module")
def ddisk():
    """``(P, F, b)`` of :func:`delaunay_disk`, ``b`` the boundary loop from angle 0."""
    P, F = delaunay_disk()
    return P, F, loop_from_angle_zero(P, F)


@pytest.fixture(scope="module")
def pdisk():
    """``(P, F, b)`` of :func:`polar_disk`, ``b`` the boundary loop from angle 0."""
    P, F = polar_disk()
    return P, F, loop_from_angle_zero(P, F)
