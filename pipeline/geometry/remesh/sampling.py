"""Uniform samples of a disk map's image, and their Delaunay triangulation (paper §8, remeshing).

The image of a SEM map is the polygon ``P = uv[boundary]``, inscribed in the unit circle. Because
the map is equiareal, points spread evenly over ``P`` are spread evenly over the surface.

:func:`sample_disk` returns ``DiskSamples``: the *rim* samples first (indices ``0 … n_rim−1``,
counter-clockwise, exactly on the image's boundary edges), then the *interior* samples. The
map keeps areas, not boundary lengths: the surface's rim can be several times longer or
shorter than the polygon. The rim samples are spaced evenly by arc length on the polygon,
unless the surface's rim (``rim_points``) is at least ``RIM_STRETCH_MIN`` × longer and
nowhere folds back on itself at the spacing (``RIM_FOLD_BACK_COS``): then they
are spaced evenly along the surface's rim, measured by chords at the spacing ``h`` (a ragged
rim's teeth between two samples do not count) and never sparser on the polygon than ``h``
(:func:`rim_lengths_on_surface`); the rim count is that length over ``h``. Patterns:

* ``hexagonal`` — an equilateral lattice of spacing ``h`` (the densest even
  pattern: every interior triangle equilateral, valence 6), clipped to the points at least
  ``margin·h`` (0.6) inside the polygon so that no sliver forms between the lattice and the rim.
* ``jittered`` (the remesh's default) — the hexagonal lattice with every point moved by a
  seeded uniform offset of at most ``JITTER/2 · h`` (h/4) along each axis. A regular lattice
  is a fixed point of the improvement's smoothing however the map shears it on the surface
  (every 1-ring is the same parallelogram-symmetric hexagon), so the lifted lattice keeps the
  map's anisotropy; the offsets break that symmetry and let the isotropic rounds and flips
  reorganise the triangles in the surface's own metric (larger smallest angles, see the
  README's remesh table), at the price of slightly less even areas than the exact lattice.
* ``blue_noise`` — a Poisson-disk set (every pair ≥ r apart, r = h / 1.33 so that the density
  matches the lattice's), by parallel dart throwing on a grid (Wei 2008); random but even,
  with no lattice direction. Seeded, so reproducible.
* ``concentric`` — rings of evenly spaced points, ``√3/2·h`` apart, each ring rotated by half a
  step against the previous one (a lattice bent around the centre: rings match the rim).

Spacing. With a requested vertex count the spacing is solved for numerically: a closed-form
first guess, then secant steps on ``log count`` against ``log h`` on the *actual* count, and
finally the rim count absorbs the remaining difference when that changes the rim spacing by
less than 15 % (usually the count is then exact; the contract is 2 %).

Relaxation. The seam between the lattice and the rim is irregular (the distance of the first
lattice row to the rim varies between 0.6 h and 1.5 h). ``relax`` ODT sweeps (Chen & Xu 2004:
each point moves to the area-weighted mean of the circumcentres of its Delaunay triangles) act
on the interior points within 3 h of the rim, the rim fixed, evening out the triangles of the
seam.

:func:`triangulate_samples` runs ``scipy.spatial.Delaunay`` on the samples with the rim samples
pushed slightly outwards (by at most 0.05 h, towards the circumscribed circle), which puts every
rim sample in strictly convex position: no three rim samples are collinear (no zero-area hull
face, no dropped sample), and — since a triangle with three corners on the (near-)circle has a
circumcircle that contains the interior samples next to it — no face gets three rim corners
(a leaf face, paper Def. 4); a flip fixes one should it ever happen. For the hexagonal pattern
only the band along the rim goes through ``Delaunay``; the untouched lattice is triangulated by
construction (the same triangles, without a Delaunay run over the lattice). Faces are
counter-clockwise; a degenerate or clockwise face at the samples' own positions would be a bug
and raises.
:func:`snap_rim` moves rim samples onto given polygon points (the input boundary's corners).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import Delaunay

from ..libm import cos, sin
from ..locate import Segments
from .halfedge import double_areas

__all__ = ["DiskSamples", "PATTERNS", "sample_disk", "triangulate_samples", "rim_polygon",
           "snap_rim", "hexagonal_points", "blue_noise_points", "concentric_points"]

PATTERNS = ("hexagonal", "jittered", "blue_noise", "concentric")
JITTER = 0.5          # jittered: offsets uniform in [−JITTER/2, JITTER/2] × h along each axis
MARGIN = 0.6          # interior samples at least MARGIN·h inside the rim polygon
BAND = 3.0            # relax interior points within BAND·h of the rim
MIN_RIM = 8
RIM_STRETCH_MIN = 1.5   # the rim samples follow the surface's rim when it is this × longer
RIM_FOLD_BACK_COS = -0.9   # ... and no two consecutive chords h apart turn back further


@dataclass
class DiskSamples:
    """The sample points of a remesh on its disk (or sphere) domain: ``points`` (k, 2) (k, 3
    on the sphere), the ``n_rim`` on the rim polygon first; ``spacing`` their lattice
    spacing ``h`` in domain units, ``pattern`` the lattice, ``iterations`` the evaluations
    that solved for the count, ``polygon`` (p, 2) the rim polygon they were made for."""

    points: np.ndarray          # k×2; rim first (on the polygon), then interior
    n_rim: int
    spacing: float              # h, in disk units
    pattern: str
    iterations: int = 0         # count-solving evaluations
    polygon: np.ndarray | None = None   # the rim polygon the samples were made for
    rim_lengths: np.ndarray | None = None   # p: what its edges count for on the rim (None:
    #                                         their own lengths; rim_lengths_on_surface)

    @property
    def rim(self) -> np.ndarray:
        return self.points[:self.n_rim]


def rim_polygon(polygon: np.ndarray | None, resolution: int = 4096) -> np.ndarray:
    """The closed rim polygon (k×2, CCW). ``None`` means the unit circle (as a fine polygon)."""
    if polygon is None:
        t = 2 * np.pi * np.arange(resolution) / resolution
        return np.column_stack([cos(t), sin(t)])
    P = np.asarray(polygon, dtype=np.float64)[:, :2]
    return P[::-1] if _signed_double_area(P) < 0 else P        # make it CCW


def _signed_double_area(P: np.ndarray) -> float:
    """Twice the signed area of the closed polygon ``P`` (p, 2): positive counter-clockwise."""
    x, y = P[:, 0], P[:, 1]
    return float((x * np.roll(y, -1) - np.roll(x, -1) * y).sum())


class _Polygon:
    """Arc-length sampling, inside test and distance for a closed convex-ish polygon ``P``
    (p, 2); ``rim_lengths`` (p,), the length each edge ``P[i] → P[i+1]`` counts for in the
    spacing of the rim samples (default: its own)."""

    def __init__(self, P: np.ndarray, rim_lengths: np.ndarray | None = None):
        self.P = P
        self.A, self.B = P, np.roll(P, -1, axis=0)
        self.segments = Segments(self.A, self.B)     # closest-point queries, tree built once
        seg = np.linalg.norm(self.B - self.A, axis=1)
        self.cum = np.r_[0.0, np.cumsum(seg)]
        self.length = float(self.cum[-1])
        self._set_rim_lengths(rim_lengths)
        self.area = 0.5 * _signed_double_area(P)
        self.radius = float(np.linalg.norm(P, axis=1).max())
        # every point of the disk of this radius is inside (distance from the origin to the
        # nearest edge line), so only the ring outside it needs the exact distance
        e = self.B - self.A
        cr = np.abs(e[:, 0] * self.A[:, 1] - e[:, 1] * self.A[:, 0])
        self.apothem = float((cr / np.maximum(seg, 1e-300)).min())

    def _set_rim_lengths(self, rim_lengths: np.ndarray | None) -> None:
        # the rim samples are spaced evenly by this measure: each edge's own length unless
        # rim_lengths (p,) gives another
        self.rim_lengths = rim_lengths
        self.rim_cum = self.cum if rim_lengths is None else np.r_[0.0, np.cumsum(rim_lengths)]
        self.rim_length = float(self.rim_cum[-1])

    def spaced_by(self, rim_lengths: np.ndarray | None) -> _Polygon:
        """The same polygon (its closest-segment tree shared) with the rim measure
        ``rim_lengths`` (p,) (None: the edges' own lengths)."""
        other = copy.copy(self)
        other._set_rim_lengths(rim_lengths)
        return other

    def arc_position(self, points: np.ndarray) -> np.ndarray:
        """Arc length (k,) from the first vertex to each point's closest point on the polygon."""
        return self._measure_of(self.cum, points)

    def rim_position(self, points: np.ndarray) -> np.ndarray:
        """Rim length (k,) (:attr:`rim_cum`) from the first vertex to each point's closest
        point on the polygon."""
        return self._measure_of(self.rim_cum, points)

    def _measure_of(self, cum: np.ndarray, points: np.ndarray) -> np.ndarray:
        seg, t, _ = self.segments.closest(points)
        return cum[seg] + t * (cum[seg + 1] - cum[seg])

    def at_rim_length(self, s: np.ndarray) -> np.ndarray:
        """Points (k, 2) at rim lengths ``s`` (k,) (mod the rim's) from the first vertex:
        exactly on edges, each edge's rim length spread evenly along it."""
        i, t = _edge_fractions(self.rim_cum, np.mod(s, self.rim_length))
        return self.A[i] + t[:, None] * (self.B[i] - self.A[i])

    def rim(self, n: int) -> np.ndarray:
        """``n`` points (n, 2) evenly spaced by rim length, the first at the first vertex."""
        return self.at_rim_length(self.rim_length * np.arange(n) / n)

    def inner_distance(self, X: np.ndarray) -> np.ndarray:
        """Signed distance to the polygon, positive inside (the polygon is convex: a SEM image
        is inscribed in the circle with its vertices in angular order)."""
        seg, _, q = self.segments.closest(X)
        d = np.linalg.norm(X - q, axis=1)
        e = self.B[seg] - self.A[seg]
        w = X - self.A[seg]
        side = e[:, 0] * w[:, 1] - e[:, 1] * w[:, 0]              # > 0: left of a CCW edge
        return np.where(side >= 0, d, -d)


def _inner_points(poly: _Polygon, X: np.ndarray, h: float, margin: float) -> np.ndarray:
    """The candidates ``X`` that lie at least ``margin·h`` inside the polygon."""
    r = np.hypot(X[:, 0], X[:, 1])
    X = X[r < poly.radius - margin * h]                 # cheap pre-filter: inside the circle
    ring = np.flatnonzero(r[r < poly.radius - margin * h] > poly.apothem - margin * h)
    keep = np.ones(len(X), bool)
    keep[ring] = poly.inner_distance(X[ring]) >= margin * h
    return X[keep]


def hexagonal_points(poly: _Polygon, h: float, margin: float = MARGIN) -> np.ndarray:
    """Equilateral lattice of spacing ``h`` (a point at the origin, rows along x)."""
    return _inner_points(poly, _lattice(poly, h), h, margin)


def jittered_points(poly: _Polygon, h: float, margin: float = MARGIN, seed: int = 0
                    ) -> np.ndarray:
    """The lattice of :func:`hexagonal_points`, each point moved by a uniform offset in
    ``[−JITTER/2, JITTER/2] · h`` along each axis (seeded), then clipped like it."""
    X = _lattice(poly, h)
    X += JITTER * h * (np.random.default_rng(seed).random(X.shape) - 0.5)
    return _inner_points(poly, X, h, margin)


def _lattice(poly: _Polygon, h: float) -> np.ndarray:
    """The equilateral lattice of spacing ``h`` over the polygon's circumscribed square
    (k×2; a point at the origin, rows along x), not clipped."""
    dy = h * np.sqrt(3.0) / 2.0
    R = poly.radius
    rows = np.arange(-np.ceil(R / dy), np.ceil(R / dy) + 1)
    cols = np.arange(-np.ceil(R / h) - 1, np.ceil(R / h) + 2)
    cc, rr = np.meshgrid(cols, rows)
    return np.column_stack([((cc + 0.5 * (rr % 2)) * h).ravel(), (rr * dy).ravel()])


def concentric_points(poly: _Polygon, h: float, margin: float = MARGIN) -> np.ndarray:
    """Rings ``√3/2·h`` apart inside the rim, ``round(2πρ/h)`` points each, alternately offset
    by half a step; a point at the centre."""
    dy = h * np.sqrt(3.0) / 2.0
    out = [np.zeros((1, 2))]
    inner_r = poly.radius - dy
    j = 0
    while inner_r - j * dy > 0.5 * h:
        rho = inner_r - j * dy
        k = max(3, int(round(2 * np.pi * rho / h)))
        t = 2 * np.pi * (np.arange(k) + 0.5 * (j % 2)) / k
        out.append(rho * np.column_stack([cos(t), sin(t)]))
        j += 1
    return _inner_points(poly, np.vstack(out), h, margin)


def blue_noise_points(poly: _Polygon, r: float, margin: float = MARGIN, seed: int = 0,
                      rounds: int = 12) -> np.ndarray:
    """Poisson-disk samples (pairwise distance ≥ ``r``) at least ``margin·r`` inside the rim.

    Parallel dart throwing on a grid of cells of side ``r/√2`` (at most one sample per cell;
    Wei 2008): in every round the cells are visited in 9 phases by ``(i mod 3, j mod 3)``, so
    that the cells of one phase are more than ``r`` apart and their candidates cannot conflict
    with each other; each empty cell of the phase draws one uniform candidate, accepted when
    no sample lies within ``r`` in the 20 surrounding cells that can hold one. ``rounds``
    rounds leave the set close to maximal. Reproducible for a given ``seed``.
    """
    rng = np.random.default_rng(seed)
    R = poly.radius - margin * r
    c = r / np.sqrt(2.0)
    g = int(np.ceil(2 * R / c)) + 1
    pad = 2
    owner = np.full((g + 2 * pad, g + 2 * pad), -1, np.int64)
    pts = np.zeros((g * g, 2))
    count = 0
    ii, jj = np.meshgrid(np.arange(g), np.arange(g), indexing="ij")
    cell_i, cell_j = ii.ravel(), jj.ravel()
    lo = -R + np.column_stack([cell_i, cell_j]) * c                 # cell corners
    centre = lo + 0.5 * c
    useful = np.hypot(centre[:, 0], centre[:, 1]) < R + c            # cells meeting the disk
    offsets = np.array([(di, dj) for di in range(-2, 3) for dj in range(-2, 3)
                        if abs(di) + abs(dj) < 4 and (di, dj) != (0, 0)])
    phase = (cell_i % 3) * 3 + cell_j % 3
    groups = [np.flatnonzero(useful & (phase == ph)) for ph in range(9)]
    for _ in range(rounds):
        for ph in range(9):
            cand = groups[ph]
            cand = cand[owner[cell_i[cand] + pad, cell_j[cand] + pad] < 0]
            groups[ph] = cand
            if len(cand) == 0:
                continue
            X = lo[cand] + c * rng.random((len(cand), 2))
            ok = np.hypot(X[:, 0], X[:, 1]) < R
            nb = owner[cell_i[cand, None] + pad + offsets[:, 0],
                       cell_j[cand, None] + pad + offsets[:, 1]]          # (k, 20)
            has = nb >= 0
            Y = pts[np.where(has, nb, 0)]
            d2 = ((Y - X[:, None, :]) ** 2).sum(axis=2)
            ok &= ~np.any(has & (d2 < r * r), axis=1)
            cand, X = cand[ok], X[ok]
            k = len(cand)
            pts[count:count + k] = X
            owner[cell_i[cand] + pad, cell_j[cand] + pad] = np.arange(count, count + k)
            count += k
    return _inner_points(poly, pts[:count], r, margin)


def _interior(poly: _Polygon, pattern: str, h: float, seed: int) -> np.ndarray:
    if pattern == "hexagonal":
        return hexagonal_points(poly, h)
    if pattern == "jittered":
        return jittered_points(poly, h, seed=seed)
    if pattern == "concentric":
        return concentric_points(poly, h)
    if pattern == "blue_noise":
        return blue_noise_points(poly, h / _BLUE_SPACING, seed=seed)
    raise ValueError(f"unknown pattern {pattern!r}; use one of {PATTERNS}")


_BLUE_SPACING = 1.33      # Poisson-disk radius r: the density of a lattice of spacing 1.33 r


def _count(poly: _Polygon, pattern: str, h: float, seed: int) -> tuple[int, np.ndarray, int]:
    inner = _interior(poly, pattern, h, seed)
    n_rim = max(MIN_RIM, int(round(poly.rim_length / h)))
    return n_rim + len(inner), inner, n_rim


def sample_disk(n_vertices: int | None = None, spacing: float | None = None,
                pattern: str = "hexagonal", polygon: np.ndarray | None = None,
                relax: int = 3, seed: int = 0, rim_points: np.ndarray | None = None
                ) -> DiskSamples:
    """Even samples of the polygon (default: the unit circle); give ``n_vertices`` or ``spacing``.

    ``spacing`` is the target edge length ``h`` in disk units. With ``n_vertices`` the spacing
    is solved for (see the module docstring) and the count is within 2 % (usually exact).
    ``rim_points`` (p, 3), the surface points of the ``polygon``'s vertices (p, 2) in disk
    units (the map's area scale applied), spaces the rim samples by the surface's rim where
    it is longer than the polygon (:func:`rim_lengths_on_surface`).
    """
    if pattern not in PATTERNS:
        raise ValueError(f"unknown pattern {pattern!r}; use one of {PATTERNS}")
    if (n_vertices is None) == (spacing is None):
        raise ValueError("give exactly one of n_vertices or spacing")
    poly = _Polygon(rim_polygon(polygon))
    if rim_points is not None:
        if polygon is None:
            raise ValueError("rim_points are the surface points of a polygon's vertices")
        X = np.asarray(rim_points, dtype=np.float64)
        X = X[::-1] if _signed_double_area(np.asarray(polygon)[:, :2]) < 0 else X
        h = spacing if spacing is not None else _closed_form_spacing(poly, int(n_vertices))
        poly = poly.spaced_by(rim_lengths_on_surface(poly.P, X, h))
    evaluations = 0
    if spacing is not None:
        h = float(spacing)
        _, inner, n_rim = _count(poly, pattern, h, seed)
        evaluations = 1
    else:
        N = int(n_vertices)
        h = _closed_form_spacing(poly, N)
        logs = []
        best = None
        for _ in range(6):
            count, inner, n_rim = _count(poly, pattern, h, seed)
            evaluations += 1
            if best is None or abs(count - N) < abs(best[0] - N):
                best = (count, inner, n_rim, h)
            if abs(count - N) <= max(0.002 * N, 0.1 * n_rim) and abs(count - N) < 0.15 * n_rim:
                break
            logs.append((math.log(h), math.log(count)))
            if len(logs) >= 2 and logs[-1][1] != logs[-2][1]:
                slope = (logs[-1][1] - logs[-2][1]) / (logs[-1][0] - logs[-2][0])
                slope = float(np.clip(slope, -3.0, -1.0))
            else:
                slope = -2.0
            h = math.exp(math.log(h) + (math.log(N) - math.log(count)) / slope)
        count, inner, n_rim, h = best
        diff = N - count                                   # let the rim absorb the rest
        if abs(diff) < 0.15 * n_rim and n_rim + diff >= MIN_RIM:
            n_rim += diff
    rim = poly.rim(n_rim)
    points = np.vstack([rim, inner])
    if relax > 0 and len(inner):
        points = _relax_band(points, n_rim, poly, h, relax)
    return DiskSamples(points, n_rim, float(h), pattern, evaluations, poly.P, poly.rim_lengths)


def _closed_form_spacing(poly: _Polygon, n_vertices: int) -> float:
    """The spacing ``h`` for which ``(A − L·(MARGIN − 0.5)·h)/(√3/2·h²) + L_rim/h`` (the
    lattice in the area shrunk by the margin band, and the rim samples) is ``n_vertices``:
    a quadratic in ``1/h``."""
    a = np.sqrt(3.0) / 2.0
    L, A = poly.length, poly.area
    b = poly.rim_length - L * (MARGIN - 0.5) / a
    return float(2 * A / a / (b + np.sqrt(b * b + 4 * n_vertices * A / a)))


def rim_lengths_on_surface(P: np.ndarray, X: np.ndarray, h: float) -> np.ndarray | None:
    """The length (p,) each edge ``P[i] → P[i+1]`` of the rim polygon ``P`` (p, 2) counts for
    when the rim samples follow the surface's rim ``X`` (p, 3, the surface points of ``P``'s
    vertices, in disk units) at the spacing ``h``; None where that is the polygon's own.

    The polygon is cut into ``m = round(perimeter / h)`` equal arcs; each arc counts the chord
    between the surface points its ends lift to (linearly along the edges, as the lift does),
    or its own length if the chord is shorter, and its count is spread over the polygon's
    edges in proportion to arc length. Chords at the spacing skip what the rim does between
    two samples (a ragged rim's teeth), and an arc never counts less than its length: the rim
    samples are never sparser on the polygon than ``h`` (a rim shorter on the surface than
    on the disk keeps the polygon's spacing). None unless the arcs count ``RIM_STRETCH_MIN``
    × the perimeter at least (a rim about as long on the surface as on the disk keeps the
    polygon's even spacing), and None where the rim folds back on itself at the spacing
    (two consecutive chords at an angle whose cosine is below ``RIM_FOLD_BACK_COS``: a slit,
    a seam whose two sides meet, where rim samples crowded on both sides of a narrow strip
    leave folds)."""
    seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    cum = np.r_[0.0, np.cumsum(seg)]
    m = max(MIN_RIM, int(round(cum[-1] / h)))
    s = cum[-1] * np.arange(m + 1) / m
    i, t = _edge_fractions(cum, s)
    Xc = np.vstack([X, X[:1]])
    Y = Xc[i] + t[:, None] * (Xc[i + 1] - Xc[i])
    chord = np.linalg.norm(np.diff(Y, axis=0), axis=1)
    counted = np.maximum(chord, cum[-1] / m)
    if counted.sum() < RIM_STRETCH_MIN * cum[-1] or _folds_back(np.diff(Y, axis=0)):
        return None
    return np.diff(np.interp(cum, s, np.r_[0.0, np.cumsum(counted)]))


def _edge_fractions(cum: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the lengths ``s`` (k,) fall on a closed polygon whose edges end at the
    cumulative lengths ``cum`` (p + 1, from 0): each one's edge (k int, below p) and the
    fraction of that edge before it (k float)."""
    i = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(cum) - 2)
    return i, (s - cum[i]) / np.maximum(cum[i + 1] - cum[i], 1e-300)


def _folds_back(D: np.ndarray) -> bool:
    """Whether two consecutive chords ``D`` (m, 3) of a closed rim turn back on each other
    (the cosine of their angle below ``RIM_FOLD_BACK_COS``)."""
    u = D / np.maximum(np.linalg.norm(D, axis=1), 1e-300)[:, None]
    return bool(((u * np.roll(u, -1, axis=0)).sum(axis=1) < RIM_FOLD_BACK_COS).any())


def _relax_band(points: np.ndarray, n_rim: int, poly: _Polygon, h: float, sweeps: int
                ) -> np.ndarray:
    """ODT sweeps (optimal Delaunay triangulation smoothing, Chen & Xu 2004) on the interior
    points within ``BAND·h`` of the rim: each moves to the area-weighted mean of the
    circumcentres of its Delaunay triangles, then the band is re-triangulated.

    Only the points within ``(BAND + 2)·h`` of the rim take part (the lattice further in is
    unaffected); the rim is fixed."""
    X = points[n_rim:]
    ring = np.flatnonzero(np.hypot(X[:, 0], X[:, 1]) > poly.apothem - (BAND + 2.0) * h)
    d = poly.inner_distance(X[ring])
    near = n_rim + ring[d < (BAND + 2.0) * h]
    free = np.r_[np.zeros(n_rim, bool), d[d < (BAND + 2.0) * h] < BAND * h]
    P = points[np.r_[np.arange(n_rim), near]].copy()
    n = len(P)
    for _ in range(sweeps):
        F = _delaunay(P, n_rim, h)
        A, B, C = P.take(F[:, 0], axis=0), P.take(F[:, 1], axis=0), P.take(F[:, 2], axis=0)
        b, c = B - A, C - A
        d2 = 2.0 * (b[:, 0] * c[:, 1] - b[:, 1] * c[:, 0])
        ok = d2 > 1e-12 * h * h
        # drop the long triangles spanning the empty inner region of the band
        ok &= np.maximum(np.hypot(*b.T), np.hypot(*c.T)) < 2.0 * h
        b2, c2 = (b * b).sum(1), (c * c).sum(1)
        cc = A + np.column_stack([c[:, 1] * b2 - b[:, 1] * c2, b[:, 0] * c2 - c[:, 0] * b2]) \
            / np.where(ok, d2, 1.0)[:, None]
        w = np.where(ok, 0.5 * d2, 0.0)
        Fw = F.ravel()
        W = np.bincount(Fw, np.repeat(w, 3), n)
        Sx = np.bincount(Fw, np.repeat(w * cc[:, 0], 3), n)
        Sy = np.bincount(Fw, np.repeat(w * cc[:, 1], 3), n)
        move = free & (W > 0)
        P[move] = np.column_stack([Sx[move], Sy[move]]) / W[move, None]
    out = points.copy()
    out[near] = P[n_rim:]
    return out


def _delaunay(points: np.ndarray, n_rim: int, h: float) -> np.ndarray:
    """Delaunay faces (CCW) of the points, the rim samples pushed slightly outward.

    A rim sample at distance ``g`` inside the circumscribed circle (radius ``ρ``) is moved
    radially by ``α·g`` with ``α = min(1, 0.05 h / max g)``: the rim becomes a strictly convex
    curve (no three rim samples collinear, so no zero-area hull face and no dropped sample)
    while no sample moves more than 0.05 h, so the triangulation is the Delaunay triangulation
    of the samples' own positions up to that tolerance, even along long polygon edges.
    """
    Q = points.copy()
    r = np.hypot(Q[:n_rim, 0], Q[:n_rim, 1])
    rho = float(r.max())
    gap = rho - r
    alpha = min(1.0, 0.05 * h / max(float(gap.max()), 1e-300))
    Q[:n_rim] *= ((r + alpha * gap) / r)[:, None]
    F = Delaunay(Q).simplices.astype(np.int64)
    a2 = double_areas(Q, F)
    cw = a2 < 0
    F[cw] = F[cw][:, [0, 2, 1]]
    return F


def triangulate_samples(samples: DiskSamples) -> np.ndarray:
    """Delaunay triangulation (m×3, CCW) of the samples: a disk bounded by the rim samples in
    order, no leaf faces, no degenerate faces (see the module docstring).

    For the hexagonal pattern only the band along the rim goes through ``Delaunay``; the
    untouched lattice further in is triangulated by construction (its Delaunay triangles are
    known: two per lattice point). Every lattice triangle whose corners are at least
    ``(BAND + 1.5)·h`` inside the rim has an empty circumcircle among *all* samples (the moved
    band points are farther than its circumradius), and every band triangle with a corner
    nearer than that, of circumradius below ``h``, sees only samples that were passed to the
    band triangulation; so the union is the Delaunay triangulation of all samples. It is
    checked (face count ``2n − n_rim − 2``, all faces CCW, total area = polygon area) and the
    full ``Delaunay`` is used instead if the check fails.
    """
    P, nb, h = samples.points, samples.n_rim, samples.spacing
    F = None
    if samples.pattern == "hexagonal" and samples.polygon is not None and len(P) > 2000:
        F = _hexagonal_triangulation(samples)
    if F is None:
        F = _delaunay(P, nb, h)
    n = len(P)
    used = np.zeros(n, bool)
    used[F.ravel()] = True
    if not used.all():                                    # pragma: no cover - Qhull 'coplanar'
        raise RuntimeError(f"Delaunay dropped {int((~used).sum())} samples (coincident points)")
    F = _drop_folded_leaves(P, _flip_leaves(P, F, nb), nb, h)
    if (F < nb).all(axis=1).any():                      # pragma: no cover
        raise RuntimeError("could not remove faces with three rim corners")
    a2 = double_areas(P, F)
    if np.any(a2 <= 1e-9 * max(h, 1e-300) ** 2):          # pragma: no cover
        raise RuntimeError("degenerate or clockwise face in the sample triangulation")
    return F


def _hexagonal_triangulation(samples: DiskSamples) -> np.ndarray | None:
    """Band Delaunay + lattice by construction (see :func:`triangulate_samples`); ``None``
    when the check fails."""
    P, nb, h = samples.points, samples.n_rim, samples.spacing
    poly = _Polygon(samples.polygon)
    n = len(P)
    X = P[nb:]
    D0 = (BAND + 1.5) * h
    d = np.full(len(X), np.inf)
    ring = np.flatnonzero(np.hypot(X[:, 0], X[:, 1]) > poly.apothem - D0 - 3 * h)
    d[ring] = poly.inner_distance(X[ring])
    dist = np.r_[np.zeros(nb), d]
    core = dist >= D0
    # band: Delaunay of the rim and every sample within D0 + 2h
    S = np.flatnonzero(dist < D0 + 2 * h)
    Fb = S[_delaunay(P[S], nb, h)]                      # rim samples are S[:nb] (dist 0)
    Fb = Fb[(~core[Fb]).any(axis=1)]
    T = P[Fb]
    a, b = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    d2 = 2 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    A2, B2 = (a * a).sum(1), (b * b).sum(1)
    ux = (b[:, 1] * A2 - a[:, 1] * B2) / d2
    uy = (a[:, 0] * B2 - b[:, 0] * A2) / d2
    if not np.all(np.hypot(ux, uy) < h):                # circumradius
        return None
    # lattice: (row, col) of every core sample, exact lattice positions only
    dy = h * np.sqrt(3.0) / 2.0
    ci = np.flatnonzero(core)
    r = np.rint(P[ci, 1] / dy).astype(np.int64)
    c = np.rint(P[ci, 0] / h - 0.5 * (r % 2)).astype(np.int64)
    exact = (np.abs(P[ci, 1] - r * dy) < 1e-9 * h) & \
        (np.abs(P[ci, 0] - (c + 0.5 * (r % 2)) * h) < 1e-9 * h)
    if not exact.all():
        return None
    r0, c0 = r.min(), c.min() - 1
    grid = np.full((r.max() - r0 + 2, c.max() - c0 + 3), -1, np.int64)
    grid[r - r0, c - c0] = ci
    rr, cc = r - r0, c - c0
    right = grid[rr, cc + 1]
    odd = (r % 2).astype(np.int64)
    up_r = grid[rr + 1, cc + odd]
    up_l = grid[rr + 1, cc + odd - 1]
    up = np.column_stack([ci, right, up_r])
    down = np.column_stack([ci, up_r, up_l])
    Fl = np.vstack([up[(up >= 0).all(axis=1)], down[(down >= 0).all(axis=1)]])
    F = np.vstack([Fb, Fl])
    a2 = double_areas(P, F)
    if len(F) != 2 * n - nb - 2 or np.any(a2 <= 0):
        return None
    # area enclosed by the rim samples (the triangulation's boundary), not the polygon's
    rx, ry = P[:nb, 0], P[:nb, 1]
    rim_area = 0.5 * float((rx * np.roll(ry, -1) - np.roll(rx, -1) * ry).sum())
    if abs(0.5 * a2.sum() - rim_area) > 1e-9 * rim_area:
        return None
    return F


def _drop_folded_leaves(P: np.ndarray, F: np.ndarray, nb: int, h: float) -> np.ndarray:
    """Drop the faces of three rim samples that are flat in ``P`` and whose corners all have
    other faces. At a corner of the image polygon sharper than a right angle (a mesh with a
    handful of boundary vertices maps onto such a polygon) the rim push of :func:`_delaunay`
    can dent the rim inward, and the hull then closes three consecutive rim samples of one
    polygon edge into a face folded over the rim: zero area on the polygon, its two short edges
    shared with the faces inside. Without it the triangulation is the disk it should be."""
    a2 = double_areas(P, F)
    folded = (F < nb).all(axis=1) & (np.abs(a2) <= 1e-9 * max(h, 1e-300) ** 2)
    if not folded.any():
        return F
    rest = F[~folded]
    covered = np.zeros(len(P), bool)
    covered[rest.ravel()] = True
    drop = folded & covered[F].all(axis=1)
    return F[~drop]


def _flip_leaves(P: np.ndarray, F: np.ndarray, nb: int) -> np.ndarray:
    """Flip away faces with three rim corners (indices < nb) — none are expected (see the
    module docstring); a safety net run in Python over the few leaves."""
    leaf = np.flatnonzero((F < nb).all(axis=1))
    if len(leaf) == 0:
        return F
    F = F.copy()
    for _ in range(10):
        leaf = np.flatnonzero((F < nb).all(axis=1))
        if len(leaf) == 0:
            return F
        emap = {}
        for t, (a, b, c) in enumerate(F.tolist()):
            emap[(a, b)], emap[(b, c)], emap[(c, a)] = t, t, t
        for t in leaf.tolist():
            tri = F[t].tolist()
            for k in range(3):
                a, b, c = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
                g = emap.get((b, a))
                if g is None:
                    continue
                dd = [x for x in F[g].tolist() if x != a and x != b][0]
                if dd < nb:
                    continue
                new = np.array([[c, a, dd], [c, dd, b]])
                if (double_areas(P, new) > 0).all():
                    F[t], F[g] = new[0], new[1]
                    break
            else:
                continue
            break
    return F


def arc_parameters(polygon: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Arc length (k,) from the first vertex of the closed polygon (k'×2) to each point's
    closest point on it."""
    return arc_polygon(polygon).arc_position(points)


def arc_polygon(polygon: np.ndarray) -> _Polygon:
    """The closed polygon (k×2) made once for many :func:`arc_parameters` questions: its
    ``arc_position(points)`` is ``arc_parameters(polygon, points)`` (its closest-segment tree
    built at the first)."""
    return _Polygon(np.asarray(polygon, dtype=np.float64))


def snap_rim(samples: DiskSamples, targets: np.ndarray) -> np.ndarray:
    """Move the rim sample nearest (by arc length) to each target — points of the rim
    polygon, e.g. the images of the input boundary's sharp corners — exactly onto it, so that
    the corner is a vertex of the remesh instead of being cut off. Each rim sample takes at
    most one target (the first given wins), and the rim order is kept (a sample moves by at
    most half a rim spacing, staying between its neighbours). Returns the indices moved."""
    if samples.polygon is None or len(targets) == 0:
        return np.zeros(0, np.int64)
    poly = _Polygon(samples.polygon, samples.rim_lengths)
    T = np.asarray(targets, dtype=np.float64).reshape(-1, 2)
    s = poly.rim_position(T)
    nb = samples.n_rim
    k = np.rint(s / (poly.rim_length / nb)).astype(np.int64) % nb
    _, first = np.unique(k, return_index=True)
    first = np.sort(first)
    samples.points = samples.points.copy()
    samples.points[k[first]] = T[first]
    return k[first]
