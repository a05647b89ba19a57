"""The remesh command on shapes made here, of kinds the shared meshes are not: how they compare
with pymeshlab's isotropic remeshing where the disk map is strained.

    python benchmarks/bench_shapes.py [--vertices 5000 20000] [--shapes NAME ...] [--compare]

Acceptance runs on meshes we do not have; these stand in for some (all seeded or exact, so every
run makes the same files, written to a temporary folder):

* ``head_neck``: a sphere's cap of 155° on a neck 3.5 radii long, cut at the neck (surface of
  revolution; the map squeezes the head);
* ``bust``: a head on a neck on shoulders and a torso of superelliptic sections, cut at the
  waist;
* ``deep_bowl``: a sphere's cap of 170°;
* ``strip20`` / ``strip100``: a 1 × 20 / 1 × 100 strip waved along its length (the equiareal
  disk map is anisotropic by about its aspect);
* ``spiral``: a strip 90 times as long as wide, wound in a rising spiral;
* ``cone``: a grid with a cone of half-angle 11.3° rising from it (an input corner of about 81°
  at its tip, a little wider than 3 × 20°);
* ``density``: a random Delaunay height field with a patch 100 times as dense;
* ``slivers``: the Delaunay of clustered random points on a saddle (many obtuse slivers).

Per shape and vertex count the rows of :mod:`bench_scans`: ``sem-pipeline remesh SHAPE
--vertices N --no-compare --no-report`` end to end and its measures, and with ``--compare``
pymeshlab's call under it.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_scans import print_rows  # noqa: E402  (puts REPO first on the path)

from pipeline.io.meshio import write_obj  # noqa: E402


def revolution(r: np.ndarray, z: np.ndarray, n_around: int) -> tuple:
    """``(V, F)`` of the surface of revolution of the profile ``(r, z)`` (k,) about the z axis:
    ``r[0] = 0`` the pole (one vertex), the last ring the rim, ``n_around`` vertices a ring."""
    t = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    rings = np.stack([np.outer(r[1:], np.cos(t)), np.outer(r[1:], np.sin(t)),
                      np.repeat(z[1:, None], n_around, axis=1)], axis=-1).reshape(-1, 3)
    V = np.vstack([[0.0, 0.0, z[0]], rings])
    j = np.arange(n_around)
    F = [np.column_stack([np.zeros(n_around, int), 1 + j, 1 + (j + 1) % n_around])]
    for i in range(len(r) - 2):
        a, b = 1 + i * n_around + j, 1 + i * n_around + (j + 1) % n_around
        c, d = a + n_around, b + n_around
        F += [np.column_stack([a, c, d]), np.column_stack([a, d, b])]
    return V, np.vstack(F)


def by_arc_length(points: np.ndarray, n: int) -> tuple:
    """The polyline ``points`` (k×2, ``(r, z)``) resampled at ``n`` points even in arc length:
    ``(r, z)``."""
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    at = np.linspace(0.0, s[-1], n)
    return np.interp(at, s, points[:, 0]), np.interp(at, s, points[:, 1])


def height_field(P: np.ndarray, z) -> tuple:
    """``(V, F)``: the Delaunay triangulation of the points ``P`` (n×2) lifted by ``z(x, y)``."""
    from scipy.spatial import Delaunay

    return np.column_stack([P, z(P[:, 0], P[:, 1])]), Delaunay(P).simplices


def grid(nx: int, ny: int, width: float = 1.0, height: float = 1.0) -> np.ndarray:
    """The points of an ``(nx + 1) × (ny + 1)`` grid over ``[0, width] × [0, height]``."""
    x, y = np.meshgrid(np.linspace(0, width, nx + 1), np.linspace(0, height, ny + 1))
    return np.column_stack([x.ravel(), y.ravel()])


def head_neck() -> tuple:
    th = np.linspace(0, np.radians(155), 80)
    head = np.column_stack([np.sin(th), np.cos(th)])
    z0 = head[-1, 1]
    neck = np.array([[0.42, z0 - 0.4], [0.42, z0 - 3.5]])
    return revolution(*by_arc_length(np.vstack([head, neck]), 161), 96)


def bust() -> tuple:
    def half_axes(z):          # the section's half-axes and superellipse exponent at height z
        if z > 1.0:                                              # head: radius 0.8 at 1.8
            a = np.sqrt(max(0.64 - (z - 1.8) ** 2, 0.0))
            return a, 1.1 * a, 2.0
        if z > 0.6:                                              # neck
            return 0.35, 0.35, 2.0
        if z > 0.2:                                              # shoulders
            w = (0.6 - z) / 0.4
            return 0.35 + 1.25 * np.sin(w * np.pi / 2), 0.35 + 0.25 * w, 4.0
        return 1.6 - 0.15 * (0.2 - z), 0.6 - 0.05 * (0.2 - z), 4.0   # torso
    n_around = 120
    t = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    z = 2.6 - 4.6 * np.linspace(0, 1, 151)
    V, F = revolution(np.r_[0.0, np.ones(150)], z, n_around)
    for i, zi in enumerate(z[1:]):
        a, b, p = half_axes(zi)
        ring = slice(1 + i * n_around, 1 + (i + 1) * n_around)
        V[ring, 0] = a * np.sign(np.cos(t)) * np.abs(np.cos(t)) ** (2 / p)
        V[ring, 1] = b * np.sign(np.sin(t)) * np.abs(np.sin(t)) ** (2 / p)
    return V, F


def deep_bowl() -> tuple:
    th = np.linspace(0, np.radians(170), 91)
    return revolution(np.sin(th), -np.cos(th), 128)


def strip(aspect: int) -> tuple:
    return height_field(grid(20 * aspect, 20, float(aspect)), lambda x, y: 0.3 * np.sin(x / 2))


def spiral() -> tuple:
    t = np.linspace(0, 6 * np.pi, 600)
    across = np.linspace(-0.2, 0.2, 9)
    radius = (0.5 + 0.15 * t)[:, None] + across[None, :]
    V = np.stack([radius * np.cos(t)[:, None], radius * np.sin(t)[:, None],
                  np.repeat(0.05 * t[:, None], len(across), axis=1)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(len(t) - 1), np.arange(len(across) - 1), indexing="ij")
    a = (i * len(across) + j).ravel()
    b, c = a + 1, a + len(across)
    return V, np.vstack([np.column_stack([a, c, c + 1]), np.column_stack([a, c + 1, b])])


def cone() -> tuple:
    return height_field(grid(80, 80, 2.0, 2.0) - 1.0,
                        lambda x, y: 5.0 * np.maximum(0.0, 0.3 - np.hypot(x, y)))


def density(rng) -> tuple:
    P = np.vstack([[[0, 0], [1, 0], [1, 1], [0, 1]], rng.random((3000, 2)),
                   0.45 + 0.1 * rng.random((30000, 2))])
    return height_field(P, lambda x, y: 0.2 * np.sin(3 * x) * np.cos(2 * y))


def slivers(rng) -> tuple:
    centres = rng.random((40, 1, 2))
    P = np.vstack([(centres + 0.01 * rng.standard_normal((40, 150, 2))).reshape(-1, 2),
                   rng.random((300, 2))])
    return height_field(P, lambda x, y: 0.5 * (x - 0.5) ** 2 - 0.3 * (y - 0.5) ** 2)


SHAPES = {"head_neck": head_neck, "bust": bust, "deep_bowl": deep_bowl,
          "strip20": lambda: strip(20), "strip100": lambda: strip(100), "spiral": spiral,
          "cone": cone, "density": lambda: density(np.random.default_rng(22)),
          "slivers": lambda: slivers(np.random.default_rng(23))}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, nargs="+", default=[5000, 20000])
    ap.add_argument("--shapes", nargs="+", choices=list(SHAPES), default=list(SHAPES))
    ap.add_argument("--compare", action="store_true",
                    help="under each row, pymeshlab's isotropic remeshing of the same shape")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        paths = {}
        for name in args.shapes:
            V, F = SHAPES[name]()
            paths[name] = write_obj(folder / f"{name}.obj", V, F)
            print(f"{name}: {len(V)} vertices, {len(F)} faces")
        print_rows(paths, args.vertices, args.compare)
    return 0


if __name__ == "__main__":
    sys.exit(main())
