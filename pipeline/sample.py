"""The project's embedded sample: a SYNTHETIC face-like open surface (not a scan).

Nothing here comes from a real person. The face is made up of smooth analytic pieces so that the
README's first command runs offline on a fresh machine, with no download and no data file.

* **Layout.** An egg-shaped convex oval of the plane, in centimetres of arc length on the face
  (``u`` towards the subject's left, ``v`` up; about 18 cm across and 22.6 cm tall before bending),
  is sampled by evenly spaced rim points plus a hexagonal lattice clipped 0.6 spacing inside the
  rim, relaxed by Laplacian sweeps (rim fixed) and triangulated by Delaunay (:func:`layout`). The
  oval is convex, so the triangulation covers exactly the oval: a connected, consistently oriented
  disk with one boundary loop and ``V - E + F = 1``; faces with all three corners on the rim are
  flipped away. The lattice spacing is solved for the requested vertex count (within ~1 %).
* **Base mask.** The layout is bent sideways along a cross-section that is flat at the front and
  curls back at the sides (more at the jaw and the top of the forehead), and bent around a
  horizontal axis (forehead and under-chin fall back): about 14 cm wide, 20 cm tall.
* **Relief.** A height field along ``z``: gaussians, superquadric bumps and "tubes" (gaussian
  ridges or grooves along short curves) for forehead, temples, brow ridges, recessed eye sockets
  with closed eyelids (a lid line, no hole), nose (bridge, tip, wings, nostrils), cheekbones,
  cheeks, nasolabial folds, muzzle, upper and lower lips with a closed mouth line, philtrum, the
  groove under the lower lip, chin. About 8.5-9 cm deep from the nose tip.
* **Variants.** ``identity`` (0 = the default face; any other integer draws face width/height,
  relief depth, nose length/projection/width, eye spacing, lips, mouth width, chin, brows, cheeks,
  jaw from a fixed seed) and ``expression`` (``smile``: mouth corners up and out, cheeks up and
  forward, deeper nasolabial folds, narrower eyes; ``jawopen``: chin and lower lip drop, the mouth
  line becomes a recess) are smooth near-identity warps of the *same* layout points plus changes of
  the heights. So ``F`` is shared and vertex ``i`` is the same material point in every variant.
  Every variant is a graph ``z = f(x, y)`` with all triangles counter-clockwise in the (x, y)
  projection (checked on every call): a valid embedding, free of self-intersections.

Coordinates follow ICT-FaceKit: centimetres, ``+y`` up, ``+z`` towards the viewer (triangles are
counter-clockwise seen from the front), the subject's right at ``-x``. The landmark names are
ICT-FaceKit's named set, so the two can be mixed; each landmark is the interior vertex nearest to
the anatomical point of the neutral face (distinct vertices), shared by the expressions.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.spatial import Delaunay, cKDTree

from pipeline.errors import UserError

__all__ = [
    "EXPRESSIONS",
    "LANDMARK_NAMES",
    "FaceSample",
    "layout",
    "make_face",
    "write_sample",
]

EXPRESSIONS = ("neutral", "smile", "jawopen")

LANDMARK_NAMES = (
    "right_eye_outer",
    "right_eye_inner",
    "left_eye_inner",
    "left_eye_outer",
    "nose_bridge",
    "nose_tip",
    "subnasale",
    "mouth_right",
    "mouth_left",
    "upper_lip_top",
    "lower_lip_bottom",
    "chin",
    "right_brow_outer",
    "right_brow_inner",
    "left_brow_inner",
    "left_brow_outer",
)

MIN_VERTICES = 300
MAX_VERTICES = 1_000_000
_CHUNK = 100_000  # vertices evaluated at a time (bounds the temporaries)

# Cross-section of the base mask: tangent angle psi(s) = curl(v) (s / _FRONT_RADIUS + _CURL s^3 / 3)
# with curl = 1 + _JAW_CURL at the jaw, 1 + _TOP_CURL at the top of the forehead.
_FRONT_RADIUS = 9.0
_CURL = 0.0015
_JAW_CURL = 0.6
_TOP_CURL = 0.3
_PROFILE_RADIUS = 12.5  # bend around a horizontal axis (forehead and chin fall back)


@dataclass
class FaceSample:
    """One synthetic face: vertices (cm), CCW triangles, named landmark vertex indices."""

    V: np.ndarray  # (n, 3) float64
    F: np.ndarray  # (m, 3) int64
    landmarks: dict[str, int] = field(default_factory=dict)
    name: str = "sample_face"


# ----------------------------------------------------------------------------------------------
# The planar layout (shared connectivity)
# ----------------------------------------------------------------------------------------------

# Egg-shaped oval in layout coordinates (cm of arc on the face): u = A cos t (1 + K sin t),
# v = V_C + B sin t: widest at the cheekbones, narrower at the jaw.
_A = 9.2
_B = 11.3
_K = 0.1
_V_C = 0.1


def _oval_boundary(n: int) -> np.ndarray:
    """``n`` points on the oval, equally spaced in arc length, counter-clockwise."""
    m = max(4096, 8 * n)
    t = np.linspace(0.0, 2.0 * np.pi, m + 1)
    u = _A * np.cos(t) * (1.0 + _K * np.sin(t))
    v = _V_C + _B * np.sin(t)
    seg = np.hypot(np.diff(u), np.diff(v))
    s = np.concatenate([[0.0], np.cumsum(seg)])
    target = np.arange(n) * (s[-1] / n)
    tt = np.interp(target, s, t)
    return np.column_stack(
        [_A * np.cos(tt) * (1.0 + _K * np.sin(tt)), _V_C + _B * np.sin(tt)]
    )


def _oval_perimeter() -> float:
    t = np.linspace(0.0, 2.0 * np.pi, 20001)
    u = _A * np.cos(t) * (1.0 + _K * np.sin(t))
    v = _V_C + _B * np.sin(t)
    return float(np.hypot(np.diff(u), np.diff(v)).sum())


def _inside_oval(p: np.ndarray) -> np.ndarray:
    s = (p[:, 1] - _V_C) / _B
    half = _A * (1.0 + _K * s) * np.sqrt(np.clip(1.0 - s * s, 0.0, None))
    return (np.abs(s) < 1.0) & (np.abs(p[:, 0]) < half)


def _lattice_points(h: float, rim_tree: cKDTree, margin: float) -> np.ndarray:
    dy = h * np.sqrt(3.0) / 2.0
    rows = np.arange(np.floor((_V_C - _B) / dy) - 1, np.ceil((_V_C + _B) / dy) + 2)
    cols = np.arange(np.floor(-_A * 1.2 / h) - 1, np.ceil(_A * 1.2 / h) + 2)
    cc, rr = np.meshgrid(cols, rows)
    u = (cc + 0.5 * (rr % 2)) * h
    v = rr * dy
    p = np.column_stack([u.ravel(), v.ravel()])
    p = p[_inside_oval(p)]
    d, _ = rim_tree.query(p)
    return p[d > margin * h]


def _points_for_spacing(h: float) -> tuple[np.ndarray, int]:
    perimeter = _oval_perimeter()
    nb = max(12, int(round(perimeter / h)))
    rim = _oval_boundary(nb)
    dense = cKDTree(_oval_boundary(max(4 * nb, 2000)))
    inner = _lattice_points(h, dense, 0.6)
    return np.vstack([rim, inner]), nb


def _edges_of(F: np.ndarray) -> np.ndarray:
    return np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])


def _ccw(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    a, b, c = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def _delaunay(P: np.ndarray) -> np.ndarray:
    F = Delaunay(P).simplices.astype(np.int64)
    flip = _ccw(P, F) < 0
    F[flip] = F[flip][:, [0, 2, 1]]
    return F


def _fix_rim_faces(P: np.ndarray, F: np.ndarray, nb: int) -> np.ndarray:
    """Flip away faces whose three corners are rim vertices (indices < nb)."""
    F = F.copy()
    for _ in range(100):
        leaf = np.flatnonzero((F < nb).all(axis=1))
        if leaf.size == 0:
            return F
        emap: dict[tuple[int, int], int] = {}
        for f, (a, b, c) in enumerate(F.tolist()):
            emap[(a, b)] = f
            emap[(b, c)] = f
            emap[(c, a)] = f
        changed = False
        touched: set[int] = set()
        for f in leaf.tolist():
            if f in touched:
                continue
            tri = F[f].tolist()
            for k in range(3):
                a, b, c = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
                g = emap.get((b, a))  # neighbour across edge a-b
                if g is None or g in touched:
                    continue
                d = [x for x in F[g].tolist() if x != a and x != b][0]
                if d < nb:
                    continue
                t1 = np.array([[c, a, d], [c, d, b]])
                if (_ccw(P, t1) > 1e-12).all():
                    F[f], F[g] = t1[0], t1[1]
                    touched.update((f, g))
                    changed = True
                    break
        if not changed:
            break
    raise RuntimeError("could not remove faces with all corners on the rim")


@lru_cache(maxsize=8)
def _layout_cached(n_vertices: int) -> tuple[np.ndarray, np.ndarray, int]:
    area = np.pi * _A * _B  # the egg term integrates to zero
    perimeter = _oval_perimeter()
    # n ~ area / (sqrt(3)/2 h^2) + perimeter / (2 h)  (the rim strip is half empty): solve for h.
    a = area / (np.sqrt(3.0) / 2.0)
    b = perimeter / 2.0
    h = (b + np.sqrt(b * b + 4.0 * n_vertices * a)) / (2.0 * n_vertices)
    for _ in range(6):
        P, nb = _points_for_spacing(h)
        ratio = len(P) / n_vertices
        if abs(ratio - 1.0) < 0.005:
            break
        h *= np.sqrt(ratio)
    # Relax the interior points (rim fixed) by Laplacian sweeps on the Delaunay edges: evens out
    # the seam between the lattice and the rim (the lattice itself is a fixed point).
    F = _delaunay(P)
    n = len(P)
    key = np.unique(np.sort(_edges_of(F), axis=1) @ np.array([n, 1], np.int64))
    ea, eb = key // n, key % n
    deg = np.bincount(ea, minlength=n) + np.bincount(eb, minlength=n)
    P = P.copy()
    for _ in range(8):
        su = np.bincount(ea, P[eb, 0], n) + np.bincount(eb, P[ea, 0], n)
        sv = np.bincount(ea, P[eb, 1], n) + np.bincount(eb, P[ea, 1], n)
        avg = np.column_stack([su, sv]) / deg[:, None]
        P[nb:] = 0.5 * P[nb:] + 0.5 * avg[nb:]
    F = _delaunay(P)
    F = _fix_rim_faces(P, F, nb)
    # the boundary must be exactly the rim polygon (it is, the oval being convex)
    E = _edges_of(F)
    rim_edges = np.column_stack([np.arange(nb), (np.arange(nb) + 1) % nb])
    directed = E[:, 0] * n + E[:, 1]
    if not (
        np.isin(rim_edges[:, 0] * n + rim_edges[:, 1], directed).all()
        and len(np.unique(np.sort(E, axis=1), axis=0)) * 2 - len(E) == nb
        and len(np.unique(F)) == n
    ):  # pragma: no cover - guarded by the construction and the tests
        raise RuntimeError("the triangulated layout is not a disk bounded by the rim")
    P.setflags(write=False)
    F.setflags(write=False)
    return P, F, nb


def layout(n_vertices: int = 6000) -> tuple[np.ndarray, np.ndarray]:
    """The planar layout every variant shares: ``(P, F)``, ``P`` (n, 2) in cm, ``F`` CCW.

    The first vertices (a contiguous block) are the rim, in counter-clockwise order.
    """
    P, F, _ = _layout_cached(_check_n(n_vertices))
    return P.copy(), F.copy()


def _check_n(n_vertices) -> int:
    try:
        n = int(n_vertices)
    except (TypeError, ValueError):
        raise UserError(f"n_vertices must be an integer, got {n_vertices!r}") from None
    if n != n_vertices or not (MIN_VERTICES <= n <= MAX_VERTICES):
        raise UserError(
            f"n_vertices={n_vertices!r} is out of range; pass an integer between "
            f"{MIN_VERTICES} and {MAX_VERTICES}"
        )
    return n


# ----------------------------------------------------------------------------------------------
# Shape primitives (all smooth)
# ----------------------------------------------------------------------------------------------


def _gauss(u, v, cu, cv, su, sv):
    return np.exp(-0.5 * (((u - cu) / su) ** 2 + ((v - cv) / sv) ** 2))


def _superbump(u, v, cu, cv, ru, rv, p=1.6):
    r2 = ((u - cu) / ru) ** 2 + ((v - cv) / rv) ** 2
    return np.exp(-(r2**p))


def _smoothstep(x, a, b):
    t = np.clip((x - a) / (b - a), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _tube(u, v, curve, sigma, taper=0.0):
    """Gaussian ridge of unit height along a polyline ``curve`` (k, 2).

    ``taper`` > 0 fades it out towards both ends (weight ``exp(-taper * (2s-1)^6)``, ``s`` the
    relative arc length of the nearest point), so the ridge has no hard ends.
    """
    c = np.asarray(curve, float)
    lo = c.min(axis=0) - 5.0 * sigma
    hi = c.max(axis=0) + 5.0 * sigma
    near = (u > lo[0]) & (u < hi[0]) & (v > lo[1]) & (v < hi[1])
    out = np.zeros(np.shape(u))
    if not near.any():
        return out
    u, v = u[near], v[near]
    a, b = c[:-1], c[1:]
    ab = b - a
    L = np.hypot(ab[:, 0], ab[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(L)])
    pu = u[:, None] - a[None, :, 0]
    pv = v[:, None] - a[None, :, 1]
    t = np.clip((pu * ab[None, :, 0] + pv * ab[None, :, 1]) / (L * L)[None, :], 0.0, 1.0)
    du = pu - t * ab[None, :, 0]
    dv = pv - t * ab[None, :, 1]
    d2 = du * du + dv * dv
    j = np.argmin(d2, axis=1)
    rows = np.arange(len(u))
    d2min = d2[rows, j]
    s = (cum[j] + t[rows, j] * L[j]) / cum[-1]
    w = np.exp(-0.5 * d2min / sigma**2)
    if taper > 0.0:
        w = w * np.exp(-taper * (2.0 * s - 1.0) ** 6)
    out[near] = w
    return out


def _arc(p0, p1, bulge, n=24):
    """Quadratic curve from p0 to p1 whose middle is pushed by ``bulge`` (cm) to the left normal."""
    p0 = np.asarray(p0, float)
    p1 = np.asarray(p1, float)
    m = 0.5 * (p0 + p1)
    d = p1 - p0
    nrm = np.array([-d[1], d[0]]) / np.hypot(*d)
    ctrl = m + 2.0 * bulge * nrm
    t = np.linspace(0.0, 1.0, n)[:, None]
    return (1 - t) ** 2 * p0 + 2 * (1 - t) * t * ctrl + t * t * p1


# ----------------------------------------------------------------------------------------------
# Anatomy (layout coordinates, cm; u to the subject's left = +x)
# ----------------------------------------------------------------------------------------------

_EYE_C = 3.05  # |u| of the eye centre
_EYE_HALF = 1.45  # half the eye width (inner corner 1.6, outer 4.5)
_EYE_V = 2.0
_MOUTH_V = -5.8
_MOUTH_HALF = 2.45


def _eye_line(side: float, n=24):
    """Closed-lid line from inner to outer corner (slightly arched down, outer corner higher)."""
    s = np.linspace(-1.0, 1.0, n)
    u = side * (_EYE_C + _EYE_HALF * s)
    v = _EYE_V - 0.18 * (1.0 - s * s) + 0.08 * s
    return np.column_stack([u, v])


def _brow_line(side: float, n=24):
    s = np.linspace(0.0, 1.0, n)
    u = side * (1.35 + 4.3 * s)
    v = 3.25 + 0.55 * np.sin(np.pi * s**0.85) - 0.15 * s
    return np.column_stack([u, v])


_ANATOMY = {
    "right_eye_outer": (-(_EYE_C + _EYE_HALF), _EYE_V + 0.08),
    "right_eye_inner": (-(_EYE_C - _EYE_HALF), _EYE_V - 0.08),
    "left_eye_inner": (_EYE_C - _EYE_HALF, _EYE_V - 0.08),
    "left_eye_outer": (_EYE_C + _EYE_HALF, _EYE_V + 0.08),
    "nose_bridge": (0.0, 2.1),
    "nose_tip": (0.0, -2.45),
    "subnasale": (0.0, -3.55),
    "mouth_right": (-_MOUTH_HALF, _MOUTH_V),
    "mouth_left": (_MOUTH_HALF, _MOUTH_V),
    "upper_lip_top": (0.0, _MOUTH_V + 0.72),
    "lower_lip_bottom": (0.0, _MOUTH_V - 0.95),
    "chin": (0.0, -9.1),
    "right_brow_outer": (-5.55, 3.25),
    "right_brow_inner": (-1.45, 3.3),
    "left_brow_inner": (1.45, 3.3),
    "left_brow_outer": (5.55, 3.25),
}

_NOSE_PROFILE = PchipInterpolator(
    [-4.2, -3.7, -3.35, -2.95, -2.45, -1.9, -0.8, 0.6, 1.6, 2.2, 2.9, 3.8],
    [0.0, 0.15, 0.75, 1.6, 1.98, 1.92, 1.5, 1.0, 0.66, 0.55, 0.42, 0.0],
    extrapolate=False,
)
_NOSE_WIDTH = PchipInterpolator(
    [-4.2, -3.2, -2.45, -1.5, 0.0, 1.5, 2.5, 3.8],
    [0.85, 0.85, 0.8, 0.62, 0.5, 0.46, 0.6, 0.9],
    extrapolate=True,
)


def _identity_params(identity: int) -> dict[str, float]:
    p = {
        "width": 1.0,  # horizontal scale
        "height": 1.0,  # vertical scale
        "depth": 1.0,  # relief scale
        "nose_len": 0.0,  # cm, tip moves down (+) / up (-)
        "nose_proj": 1.0,  # nose height scale
        "nose_width": 1.0,  # wings scale
        "eye_sep": 0.0,  # cm, eyes move apart (+)
        "lips": 1.0,  # lip fullness
        "mouth_width": 0.0,  # cm, corners move out (+)
        "chin": 1.0,  # chin prominence
        "brow": 1.0,  # brow ridge prominence
        "cheek": 1.0,  # cheek fullness
        "jaw": 1.0,  # jaw radius scale (smaller: the sides fall back more)
    }
    if int(identity) == 0:
        return p
    rng = np.random.default_rng([20240613, int(identity) & 0xFFFFFFFF])
    ranges = {
        "width": (0.92, 1.08),
        "height": (0.94, 1.06),
        "depth": (0.9, 1.1),
        "nose_len": (-0.35, 0.35),
        "nose_proj": (0.8, 1.2),
        "nose_width": (0.85, 1.2),
        "eye_sep": (-0.25, 0.25),
        "lips": (0.7, 1.35),
        "mouth_width": (-0.3, 0.3),
        "chin": (0.7, 1.35),
        "brow": (0.6, 1.5),
        "cheek": (0.6, 1.4),
        "jaw": (0.9, 1.1),
    }
    for k in p:
        lo, hi = ranges[k]
        p[k] = float(rng.uniform(lo, hi))
    return p


def _warp(u, v, ip, expression):
    """Smooth near-identity displacement of the layout: (du, dv)."""
    du = np.zeros_like(u)
    dv = np.zeros_like(v)
    # identity: eyes apart, mouth wider, nose longer (gentle, wide gaussians: |grad| < 0.2)
    for side in (-1.0, 1.0):
        g = _gauss(u, v, side * _EYE_C, _EYE_V, 1.6, 1.6)
        du += side * ip["eye_sep"] * g
        g = _gauss(u, v, side * _MOUTH_HALF, _MOUTH_V, 1.5, 1.3)
        du += side * ip["mouth_width"] * g
    dv -= ip["nose_len"] * _gauss(u, v, 0.0, -2.8, 1.8, 1.6)
    if expression == "smile":
        for side in (-1.0, 1.0):
            g = _gauss(u, v, side * _MOUTH_HALF, _MOUTH_V, 1.05, 0.95)
            du += side * 0.45 * g
            dv += 0.6 * g
            g = _gauss(u, v, side * 3.4, -2.4, 1.5, 1.4)  # cheeks ride up
            dv += 0.35 * g
            du += side * 0.12 * g
            g = _gauss(u, v, side * _EYE_C, _EYE_V - 0.55, 1.2, 0.45)  # lower lid up: narrower eye
            dv += 0.16 * g
        # the upper lip is pulled up and slightly stretched
        dv += 0.12 * _gauss(u, v, 0.0, _MOUTH_V + 0.4, 2.2, 0.7)
    elif expression == "jawopen":
        below = 1.0 / (1.0 + np.exp((v - (_MOUTH_V - 0.05)) / 0.3))
        wide = np.exp(-0.5 * (u / 4.6) ** 2)
        dv -= 1.5 * below * wide
        du -= 0.08 * u * below * wide  # the corners come in a little
        # upper lip rises a touch
        dv += 0.1 * _gauss(u, v, 0.0, _MOUTH_V + 0.35, 1.8, 0.5)
    return du, dv


def _relief(u, v, ip, expression):
    """Height field (cm, along +z) on layout coordinates."""
    smile = expression == "smile"
    jaw = expression == "jawopen"
    h = np.zeros_like(u)

    # forehead: frontal eminences, glabella; temples
    h += 0.35 * (_gauss(u, v, -2.6, 6.3, 2.0, 2.2) + _gauss(u, v, 2.6, 6.3, 2.0, 2.2))
    h += 0.25 * _gauss(u, v, 0.0, 3.25, 0.9, 0.7)
    h -= 0.55 * (_gauss(u, v, -6.3, 3.4, 1.2, 1.8) + _gauss(u, v, 6.3, 3.4, 1.2, 1.8))

    # brow ridges
    for side in (-1.0, 1.0):
        h += 0.42 * ip["brow"] * _tube(u, v, _brow_line(side), 0.62, taper=1.2)

    # eye sockets, closed eyelids, lid line, lid crease, under-eye
    for side in (-1.0, 1.0):
        cu = side * _EYE_C
        h -= 1.45 * _gauss(u, v, cu, _EYE_V + 0.15, 1.6, 1.15)
        lid = _superbump(u, v, cu, _EYE_V + 0.05, 1.3, 0.85 if not smile else 0.75, p=1.0)
        h += 0.9 * lid
        h -= 0.16 * _tube(u, v, _eye_line(side), 0.12, taper=0.6)
        crease = _eye_line(side)
        crease[:, 1] += 0.55 + 0.15 * np.sin(np.linspace(0, np.pi, len(crease)))
        h -= 0.09 * _tube(u, v, crease, 0.12, taper=1.5)
        if smile:  # crow's feet bunching, lower lid puffed
            h += 0.12 * _gauss(u, v, cu, _EYE_V - 0.75, 1.0, 0.3)

    # cheekbones and cheeks; buccal hollows
    cheek = ip["cheek"] * (1.5 if smile else 1.0)
    for side in (-1.0, 1.0):
        h += 0.4 * _gauss(u, v, side * 4.6, 0.5, 1.3, 0.85)
        h += 0.8 * cheek * _gauss(u, v, side * 3.5, -1.6, 1.45, 1.35)
        h -= 0.3 * _gauss(u, v, side * 5.2, -4.6, 1.1, 1.5)

    # nose: dorsum ridge with a varying cross-section, tip, wings with their crease, nostrils
    prof = np.nan_to_num(_NOSE_PROFILE(v), nan=0.0)
    wid = _NOSE_WIDTH(v)
    h += ip["nose_proj"] * prof * np.exp(-np.abs(u / wid) ** 2.2)
    h += 0.22 * ip["nose_proj"] * _gauss(u, v, 0.0, -2.55, 0.55, 0.5)
    nw = ip["nose_width"]
    for side in (-1.0, 1.0):
        ala = _superbump(u, v, side * 1.05 * nw, -2.9, 0.62 * nw, 0.52, p=1.3)
        h += 0.95 * ala
        h -= 0.35 * _gauss(u, v, side * 0.5, -3.25, 0.22, 0.14) * ip["nose_proj"]
        crease = _arc((side * 0.75 * nw, -2.15), (side * 1.35 * nw, -3.45), side * 0.45)
        h -= 0.17 * _tube(u, v, crease, 0.12, taper=1.0)

    # nasolabial folds (deeper in a smile)
    for side in (-1.0, 1.0):
        corner = np.array([side * (_MOUTH_HALF + 0.55), _MOUTH_V - 0.45])
        fold = _arc((side * 1.7, -2.95), corner, -side * 0.35)
        h -= (0.38 if smile else 0.16) * _tube(u, v, fold, 0.28 if smile else 0.32, taper=1.0)

    # muzzle (teeth arch) and lips with a closed mouth line
    h += 1.1 * _gauss(u, v, 0.0, -5.4, 2.2, 1.9)
    t = u / _MOUTH_HALF
    q = np.clip(1.0 - t * t, 0.0, None)
    lips = ip["lips"] * (0.8 if smile else 1.0)
    # vermilion heights: full in the middle, vanishing at the corners; Cupid's bow on the upper lip
    hu = 0.7 * q**0.6 - 0.09 * np.exp(-0.5 * (u / 0.25) ** 2) + 0.03
    hl = 0.95 * q**0.6 + 0.03
    h += 0.45 * lips * q**0.5 * np.exp(-0.5 * ((v - (_MOUTH_V + 0.5 * hu)) / (0.36 * hu)) ** 2)
    h += 0.52 * lips * q**0.5 * np.exp(-0.5 * ((v - (_MOUTH_V - 0.5 * hl)) / (0.38 * hl)) ** 2)
    # white roll along the upper vermilion border
    h += 0.08 * lips * q * np.exp(-0.5 * ((v - (_MOUTH_V + hu)) / 0.1) ** 2)
    line = np.exp(-1.0 * t**8)
    h -= 0.3 * line * np.exp(-0.5 * ((v - _MOUTH_V) / 0.15) ** 2)
    if jaw:  # the stretched mouth line becomes a dark recess
        h -= 1.3 * line * np.exp(-0.5 * ((v - _MOUTH_V) / 0.26) ** 2)
    # philtrum: groove with two columns
    ph = _smoothstep(v, _MOUTH_V + 0.5, _MOUTH_V + 1.1) * (1.0 - _smoothstep(v, -4.3, -3.5))
    h += ph * (0.05 * (_gauss(u, v, 0.42, -4.6, 0.22, 9.0) + _gauss(u, v, -0.42, -4.6, 0.22, 9.0))
               - 0.05 * np.exp(-0.5 * (u / 0.25) ** 2))

    # groove under the lower lip, chin
    h -= 0.3 * _gauss(u, v, 0.0, -7.45, 1.5, 0.35)
    chin = ip["chin"]
    h += 1.0 * chin * _superbump(u, v, 0.0, -9.0, 1.55, 1.05, p=1.2)
    h += 0.45 * chin * _gauss(u, v, 0.0, -8.6, 2.8, 1.6)
    if jaw:
        below = 1.0 / (1.0 + np.exp((v - (_MOUTH_V - 0.05)) / 0.3))
        h -= 0.5 * below * np.exp(-0.5 * (u / 4.6) ** 2)

    return ip["depth"] * h


def _bend(u, v, ip):
    """Map (warped) layout coordinates onto the base mask surface: returns x, y, z."""
    u = u * ip["width"]
    v = v * ip["height"]
    # vertical profile: bend around a horizontal axis, extra curl under the chin
    vs = np.linspace(-16.0, 14.0, 3001)
    v0 = -1.0 * ip["height"]
    under_chin = np.log1p(np.exp((-9.8 * ip["height"] - vs) / 0.6))
    phi = (vs - v0) / _PROFILE_RADIUS - 0.35 * under_chin
    phi = 1.3 * np.tanh(phi / 1.3)  # never steeper than 75 degrees: stays a graph over (x, y)
    step = vs[1] - vs[0]
    dy, dz = np.cos(phi), -np.sin(phi)
    ys = np.concatenate([[0.0], np.cumsum(0.5 * (dy[1:] + dy[:-1]) * step)])
    zs = np.concatenate([[0.0], np.cumsum(0.5 * (dz[1:] + dz[:-1]) * step)])
    ys -= np.interp(0.0, vs, ys)
    zs -= np.interp(v0, vs, zs)
    y = np.interp(v, vs, ys)
    zv = np.interp(v, vs, zs)
    # horizontal: a cross-section flatter at the front and curling back at the sides (tangent
    # angle psi grows with the arc length, faster at the jaw), integrated by Gauss-Legendre
    jaw = (1.0 - _smoothstep(v / ip["height"], -9.0, -2.0)) / ip["jaw"]
    top = _smoothstep(v / ip["height"], 3.0, 10.0)
    curl = 1.0 + _JAW_CURL * jaw + _TOP_CURL * top
    nodes, weights = np.polynomial.legendre.leggauss(12)
    s = 0.5 * u[:, None] * (1.0 + nodes[None, :])
    sw = s / ip["width"]
    psi = curl[:, None] * (sw / _FRONT_RADIUS + _CURL * sw**3 / 3.0)
    # saturate below 83 degrees: the surface stays a graph over (x, y)
    psi = psi / (1.0 + (np.abs(psi) / 1.45) ** 6) ** (1.0 / 6.0)
    x = 0.5 * u * (np.cos(psi) @ weights)
    z = zv - 0.5 * np.abs(u) * (np.sin(np.abs(psi)) @ weights)
    return x, y, z


def _surface(P: np.ndarray, ip, expression) -> np.ndarray:
    out = np.empty((len(P), 3))
    for lo in range(0, len(P), _CHUNK):  # bounded temporaries for very large meshes
        u, v = P[lo : lo + _CHUNK, 0], P[lo : lo + _CHUNK, 1]
        du, dv = _warp(u, v, ip, expression)
        x, y, z = _bend(u + du, v + dv, ip)
        out[lo : lo + _CHUNK] = np.column_stack([x, y, z + _relief(u, v, ip, expression)])
    return out


def _landmarks(V: np.ndarray, P: np.ndarray, nb: int, ip) -> dict[str, int]:
    pts = np.array(list(_ANATOMY.values()), float)
    anat = _surface(pts, ip, "neutral")
    interior = np.arange(nb, len(V))
    tree = cKDTree(V[interior])
    k = min(8, len(interior))
    _, idx = tree.query(anat, k=k)
    used: set[int] = set()
    out: dict[str, int] = {}
    for name, cand in zip(_ANATOMY, idx):
        for c in np.atleast_1d(cand):
            vi = int(interior[c])
            if vi not in used:
                used.add(vi)
                out[name] = vi
                break
    return {name: out[name] for name in LANDMARK_NAMES}


def make_face(n_vertices: int = 6000, expression: str = "neutral", identity: int = 0) -> FaceSample:
    """A SYNTHETIC face-like open disk mesh (see the module docstring).

    ``n_vertices`` is the target vertex count (the result is within 1-2 %); ``expression`` one of
    :data:`EXPRESSIONS`; ``identity`` an integer: 0 is the default face, any other value draws a
    different synthetic person (face width and height, nose, eyes, lips, chin, ...) from a fixed
    seed. For a given ``n_vertices`` every expression and identity shares ``F`` and the landmark
    indices of the neutral face of that identity, and vertex ``i`` is the same material point.
    """
    if expression not in EXPRESSIONS:
        raise UserError(
            f"unknown expression {expression!r}; pass one of {', '.join(EXPRESSIONS)}"
        )
    try:
        identity = int(identity)
    except (TypeError, ValueError):
        raise UserError(f"identity must be an integer seed, got {identity!r}") from None
    P, F, nb = _layout_cached(_check_n(n_vertices))
    ip = _identity_params(identity)
    V = _surface(P, ip, expression)
    # every variant must be a graph over the (x, y) plane: all projected triangles CCW
    if not (_ccw(V[:, :2], F) > 0.0).all():  # pragma: no cover - guarded by design and tests
        raise RuntimeError("synthetic face folded over; shape parameters out of range")
    Vn = V if expression == "neutral" else _surface(P, ip, "neutral")
    lms = _landmarks(Vn, P, nb, ip)
    name = f"synthetic_face_id{identity}_{expression}"
    return FaceSample(
        V=np.ascontiguousarray(V, np.float64), F=np.array(F, np.int64), landmarks=lms, name=name
    )


# ----------------------------------------------------------------------------------------------
# Files
# ----------------------------------------------------------------------------------------------


def write_sample(out_dir, n_vertices: int = 6000) -> dict[str, Path]:
    """Write the neutral and smiling synthetic faces (shared connectivity) and their landmarks.

    Files: ``sample_face_neutral.obj``, ``sample_face_smile.obj``, ``sample_face_landmarks.json``
    (``{"source": ..., "landmarks": {name: index}}``, 0-based vertex indices, valid for both).
    Returns the paths under the keys ``"neutral"``, ``"smile"``, ``"landmarks"``.
    """
    from pipeline.io.artifacts import atomic_write_text
    from pipeline.io.meshio import write_obj

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    lms = None
    for expr in ("neutral", "smile"):
        face = make_face(n_vertices, expression=expr)
        lms = lms or face.landmarks
        p = out / f"sample_face_{expr}.obj"
        header = (
            f"{face.name}: SYNTHETIC face-like surface generated by sem-pipeline sample.py "
            f"(not a scan); cm, +y up, +z to the viewer; "
            f"{len(face.V)} vertices, {len(face.F)} faces"
        )
        write_obj(p, face.V, face.F, header=header)
        paths[expr] = p
    p = out / "sample_face_landmarks.json"
    atomic_write_text(p, json.dumps({"source": "synthetic (sem-pipeline sample.py)",
                                     "landmarks": lms}, indent=2) + "\n")
    paths["landmarks"] = p
    return paths
