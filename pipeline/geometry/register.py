"""Landmark registration of two disk maps (§8 of ALGORITHM.md): align, deform, compose.

Given SEM disk maps ``f_s`` of a source surface and ``f_t`` of a target surface and paired
landmark vertices ``ℓ_s`` (source) and ``ℓ_t`` (target), the registration is the map

    source surface --f_s--> disk --A--> disk --φ--> disk --f_t⁻¹ (eq. 1)--> target surface

1. **Alignment** ``A`` (:func:`fit_rotation`, :func:`fit_mobius`): the rotation
   ``z ↦ e^{iθ} z`` that minimises ``Σ_k |A(f_s(ℓ_s,k)) − f_t(ℓ_t,k)|²`` (closed form,
   ``e^{iθ} = Σ conj(z_s) z_t / |Σ conj(z_s) z_t|``), or optionally the disk automorphism
   ``z ↦ e^{iθ} (z − a) / (1 − ā z)`` (``|a| < 1``) fitted by a small nonlinear least squares
   started from the rotation. Both map the unit disk onto itself and the circle onto the circle.
2. **Deformation** ``φ`` (:func:`deform_to_landmarks`): a displacement of the aligned source disk
   that is zero on the boundary (the circle stays fixed) and moves every source landmark exactly
   onto its target landmark's disk position. The displacement minimises a quadratic smoothness
   energy with the landmarks as interior Dirichlet constraints: by default the biharmonic energy
   ``dᵀ L M⁻¹ L d`` (``L`` = cotangent Laplacian of the current disk map with weights clamped
   positive, ``M`` = lumped disk areas), which interpolates the landmark displacements smoothly;
   or the harmonic energy ``dᵀ L d``. The solve is tried in one step first. If it flips a face,
   the landmarks are moved along straight lines in increments (*continuation*): each sub-step is
   a constrained solve from the current map with the matrices rebuilt on it; a sub-step that flips
   a face is rejected and halved, an accepted one lets the next grow again. If the sub-step falls
   below ``min_step`` the landmark paths cannot be followed without folding (e.g. landmarks whose
   straight paths cross or crowd): the one-step solve is returned (method ``stalled``, with how
   far the continuation got) and its flipped faces are counted and reported as a failure, never
   hidden. Between sub-steps the
   free vertices are relaxed by a few descent steps on the symmetric Dirichlet energy of the
   deformation (:class:`InjectiveRelaxation`), which is infinite for a degenerate or flipped
   face, so relaxing never flips a face and it makes room for the next sub-step.
3. **Composition** (:func:`compose_with_inverse`): every deformed source point is located in the
   target disk mesh and lifted barycentrically to the target surface (eq. 1), via
   :mod:`pipeline.geometry.locate`. A landmark lands exactly on its target landmark's disk
   position, so it is mapped to the target landmark vertex itself (set exactly, not located).

All functions are pure (numpy in, numpy out). Disk points are complex inside this module;
the public functions accept n×2 arrays too.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .harmonic import clamp_positive
from .laplacian import corner_dot_over_area, face_double_areas, laplacian_matrix, unique_edges
from .metrics import signed_double_areas
from .solvers import make_solver, solve_complex

ENERGIES = ("biharmonic", "harmonic")

__all__ = ["ENERGIES", "Alignment", "DeformOptions", "DeformResult", "as_complex", "as_uv",
           "fit_rotation", "mobius", "fit_mobius", "align", "smoothness_matrix",
           "deform_to_landmarks", "InjectiveRelaxation", "compose_with_inverse", "snap_landmarks",
           "flipped_count", "error_summary"]


def as_complex(uv) -> np.ndarray:
    """Disk points as complex numbers: an n×2 array, or complex (or real) numbers."""
    uv = np.asarray(uv)
    if np.iscomplexobj(uv) or uv.ndim == 1:
        return uv.astype(np.complex128, copy=False).ravel()
    return uv[:, 0] + 1j * uv[:, 1]


def as_uv(z: np.ndarray) -> np.ndarray:
    return np.column_stack([z.real, z.imag])


def flipped_count(F: np.ndarray, z: np.ndarray) -> int:
    """Image faces with non-positive signed area (ALGORITHM.md §7)."""
    return int(np.count_nonzero(signed_double_areas(as_uv(as_complex(z)), F) <= 0))


# ------------------------------------------------------------------------------ 1. alignment


def fit_rotation(zs, zt) -> complex:
    """The unit complex number ``e^{iθ}`` minimising ``Σ_k |e^{iθ} zs_k − zt_k|²``.

    ``Σ|e^{iθ} zs − zt|² = Σ|zs|² + Σ|zt|² − 2 Re(e^{iθ} Σ zs ẑt̄)`` is smallest when
    ``e^{iθ}`` points along ``Σ conj(zs) zt``."""
    s = np.sum(np.conj(as_complex(zs)) * as_complex(zt))
    return complex(1.0) if abs(s) == 0 else complex(s / abs(s))


def mobius(z, theta: float, a: complex) -> np.ndarray:
    """The disk automorphism ``z ↦ e^{iθ} (z − a) / (1 − ā z)`` (``|a| < 1``)."""
    z = as_complex(z)
    return np.exp(1j * theta) * (z - a) / (1.0 - np.conj(a) * z)


def _a_of(p1: float, p2: float) -> complex:
    """Unconstrained (p1, p2) ∈ R² ↦ a in the open unit disk (smooth, a = b / √(1 + |b|²))."""
    b = complex(p1, p2)
    return b / np.sqrt(1.0 + abs(b) ** 2)


def fit_mobius(zs, zt) -> tuple[float, complex, float]:
    """Least-squares disk automorphism ``(θ, a)`` with ``mobius(zs, θ, a) ≈ zt``.

    Started from the best rotation (``a = 0``); ``scipy.optimize.least_squares`` on
    ``(θ, b)`` with ``a = b / √(1 + |b|²)`` so that ``|a| < 1`` always. Returns ``(θ, a, rms)``.
    """
    from scipy.optimize import least_squares

    zs, zt = as_complex(zs), as_complex(zt)
    theta0 = float(np.angle(fit_rotation(zs, zt)))

    def residual(p):
        d = mobius(zs, p[0], _a_of(p[1], p[2])) - zt
        return np.concatenate([d.real, d.imag])

    sol = least_squares(residual, np.array([theta0, 0.0, 0.0]), method="lm", xtol=1e-15,
                        ftol=1e-15, gtol=1e-15, max_nfev=2000)
    theta, a = float(sol.x[0]), _a_of(sol.x[1], sol.x[2])
    rms = float(np.sqrt(np.mean(np.abs(mobius(zs, theta, a) - zt) ** 2)))
    return theta, a, rms


@dataclass
class Alignment:
    kind: str            # "rotation" | "mobius"
    theta: float         # radians
    a: complex           # 0 for a rotation
    z: np.ndarray        # aligned source disk points (complex, n)
    rms_before: float    # landmark RMS distance on the disk before alignment
    rms_after: float     # … after

    def as_dict(self) -> dict:
        return {"kind": self.kind, "theta_rad": self.theta, "theta_deg": float(np.degrees(
            self.theta)), "a": [float(self.a.real), float(self.a.imag)],
            "landmark_rms_disk_before": self.rms_before,
            "landmark_rms_disk_after": self.rms_after}


def align(uv_source, landmarks_source, z_target_landmarks, use_mobius: bool = False
          ) -> Alignment:
    """Align the source disk to the target landmarks by a rotation (or a disk Möbius map)."""
    z = as_complex(uv_source)
    zs, zt = z[landmarks_source], as_complex(z_target_landmarks)
    rms0 = float(np.sqrt(np.mean(np.abs(zs - zt) ** 2)))
    if use_mobius:
        theta, a, rms = fit_mobius(zs, zt)
        return Alignment("mobius", theta, a, mobius(z, theta, a), rms0, rms)
    r = fit_rotation(zs, zt)
    za = z * r
    rms = float(np.sqrt(np.mean(np.abs(za[landmarks_source] - zt) ** 2)))
    return Alignment("rotation", float(np.angle(r)), 0j, za, rms0, rms)


# --------------------------------------------------------------------------- 2. deformation


@dataclass
class DeformOptions:
    energy: str = "biharmonic"      # smoothness of the displacement: biharmonic | harmonic
    min_step: float = 1.0 / 1024    # smallest continuation sub-step (fraction of the path)
    max_substeps: int = 400         # accepted + rejected sub-steps before giving up
    relax_iterations: int = 10      # injective relaxation steps after each accepted sub-step
    solver: str = "auto"


@dataclass
class DeformResult:
    z: np.ndarray                   # complex n: deformed disk map
    flipped_faces: int
    method: str                     # direct | continuation | stalled
    substeps: int = 1               # accepted sub-steps
    rejected_substeps: int = 0
    path_reached: float = 1.0       # fraction of the landmark path done by continuation
    history: list = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.flipped_faces == 0

    def as_dict(self) -> dict:
        return {"method": self.method, "flipped_faces": self.flipped_faces,
                "accepted_substeps": self.substeps, "rejected_substeps": self.rejected_substeps,
                "continuation_path_reached": self.path_reached, "history": self.history}


def smoothness_matrix(F: np.ndarray, z: np.ndarray, energy: str = "biharmonic",
                      edges=None) -> sp.csr_matrix:
    """The n×n quadratic form of the displacement energy on the disk map ``z``.

    ``harmonic``: ``L`` with the cotangent weights of the disk map clamped positive (so every
    row is a convex combination, cf. :func:`~pipeline.geometry.harmonic.clamp_positive`);
    ``biharmonic``: ``L M⁻¹ L`` with ``M`` the lumped (⅓ of the incident) disk face areas.
    """
    if energy not in ENERGIES:
        raise ValueError(f"energy must be one of {ENERGIES}, got {energy!r}")
    P = as_uv(as_complex(z))
    n = len(P)
    if edges is None:
        edges = unique_edges(F)
    E, corner_edge = edges
    A2 = face_double_areas(P, F)
    A2 = np.maximum(A2, 1e-300)
    cot = corner_dot_over_area(P, F, A2)
    w = 0.5 * np.bincount(corner_edge.ravel(), weights=cot.ravel(), minlength=len(E))
    L = laplacian_matrix(F, n, clamp_positive(w), E)
    if energy == "harmonic":
        return L
    mass = np.bincount(F.ravel(), weights=np.repeat(A2 / 6.0, 3), minlength=n)
    mass = np.maximum(mass, 1e-12 * mass.mean())
    return (L @ sp.diags(1.0 / mass) @ L).tocsr()


def _constrained_solve(Q: sp.csr_matrix, fixed: np.ndarray, values: np.ndarray,
                       free: np.ndarray, solver_kind: str) -> np.ndarray:
    """Minimise ``dᴴ Q d`` with ``d[fixed] = values``: ``Q_FF d_F = −Q_FK values``."""
    d = np.zeros(Q.shape[0], dtype=np.complex128)
    d[fixed] = values
    if len(free):
        Qc = Q[:, fixed]
        rhs = -(Qc[free] @ values)
        d[free] = solve_complex(make_solver(solver_kind), Q[free][:, free].tocsc(), rhs)
    return d


def _frames(F: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Per-face 2×2 edge matrices ``[z1 − z0, z2 − z0]`` (columns; rows = x, y)."""
    e1, e2 = z[F[:, 1]] - z[F[:, 0]], z[F[:, 2]] - z[F[:, 0]]
    D = np.empty((len(F), 2, 2))
    D[:, 0, 0], D[:, 0, 1], D[:, 1, 0], D[:, 1, 1] = e1.real, e2.real, e1.imag, e2.imag
    return D


class InjectiveRelaxation:
    """Symmetric Dirichlet energy of the deformation relative to a reference disk map, and a
    flip-free preconditioned descent on it (free vertices only).

    ``E(z) = Σ_τ |τ_ref| (‖J_τ‖² + ‖J_τ⁻¹‖²)`` with ``J_τ`` the Jacobian of the piecewise-linear
    map from the reference triangle to the current one; ``‖J⁻¹‖² = ‖J‖² / det(J)²`` in 2D, so
    ``E`` is infinite as soon as a face degenerates or flips: a step that lowers ``E`` never flips
    a face. The descent direction is ``−P⁻¹ ∇E`` with ``P`` the positive Laplacian of the
    reference on the free vertices, factored once. Used between continuation sub-steps to spread
    the deformation away from the landmarks, so the next sub-step has room.
    """

    def __init__(self, F: np.ndarray, z_ref: np.ndarray, free: np.ndarray, solver_kind: str):
        self.F, self.free = F, free
        R = _frames(F, z_ref)
        self.area = 0.5 * np.abs(np.linalg.det(R))
        self.Rinv = np.linalg.inv(R)
        P = smoothness_matrix(F, z_ref, "harmonic")[free][:, free].tocsc()
        self.solver = make_solver(solver_kind)
        self.solver.factorize(P)

    def energy(self, z: np.ndarray, gradient: bool = False):
        J = _frames(self.F, z) @ self.Rinv
        det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        if np.any(det <= 0):
            return np.inf, None
        fro = (J ** 2).sum(axis=(1, 2))
        E = float(np.sum(self.area * fro * (1.0 + det ** -2)))
        if not gradient:
            return E, None
        cof = np.empty_like(J)                                  # d det / dJ
        cof[:, 0, 0], cof[:, 0, 1], cof[:, 1, 0], cof[:, 1, 1] = (J[:, 1, 1], -J[:, 1, 0],
                                                                  -J[:, 0, 1], J[:, 0, 0])
        dJ = self.area[:, None, None] * (2.0 * J * (1.0 + det ** -2)[:, None, None]
                                         - (2.0 * fro * det ** -3)[:, None, None] * cof)
        dD = dJ @ np.transpose(self.Rinv, (0, 2, 1))
        g1 = dD[:, 0, 0] + 1j * dD[:, 1, 0]
        g2 = dD[:, 0, 1] + 1j * dD[:, 1, 1]
        n = len(z)
        g = np.zeros(n, dtype=np.complex128)
        for idx, val in ((self.F[:, 1], g1), (self.F[:, 2], g2), (self.F[:, 0], -(g1 + g2))):
            g += (np.bincount(idx, weights=val.real, minlength=n)
                  + 1j * np.bincount(idx, weights=val.imag, minlength=n))
        return E, g

    def relax(self, z: np.ndarray, iterations: int) -> np.ndarray:
        E, g = self.energy(z, gradient=True)
        if not np.isfinite(E):
            return z
        free = self.free
        for _ in range(iterations):
            X = self.solver.solve(np.column_stack([g[free].real, g[free].imag]))
            d = -(X[:, 0] + 1j * X[:, 1])
            s = 1.0
            while s > 1e-6:
                c = z.copy()
                c[free] += s * d
                E_new, _ = self.energy(c)
                if E_new < E:
                    break
                s /= 2.0
            else:
                break
            z = c
            E, g = self.energy(z, gradient=True)
        return z


def deform_to_landmarks(F: np.ndarray, uv, boundary: np.ndarray, landmarks: np.ndarray,
                        targets, options: DeformOptions | None = None,
                        progress=None) -> DeformResult:
    """Move ``landmarks`` of the disk map ``uv`` exactly onto ``targets``, boundary fixed,
    without flipping a face if possible (see the module docstring, step 2).

    ``uv`` is n×2 (or complex n) and flip-free; ``targets`` k×2 (or complex k) inside the disk.
    The returned map has ``z[landmarks] == targets`` exactly and ``z[boundary] == uv[boundary]``.
    """
    opt = options or DeformOptions()
    F = np.asarray(F, dtype=np.int64)
    z0 = as_complex(uv).copy()
    T = as_complex(targets)
    landmarks = np.asarray(landmarks, dtype=np.int64)
    boundary = np.asarray(boundary, dtype=np.int64)
    n = len(z0)
    fixed_mask = np.zeros(n, bool)
    fixed_mask[boundary] = True
    fixed_mask[landmarks] = True
    fixed = np.r_[boundary, landmarks]
    free = np.flatnonzero(~fixed_mask)
    edges = unique_edges(F)
    history = []

    def step_to(z, goal):
        Q = smoothness_matrix(F, z, opt.energy, edges)
        d = _constrained_solve(Q, fixed, np.r_[np.zeros(len(boundary)), goal - z[landmarks]],
                               free, opt.solver)
        out = z + d
        out[boundary] = z[boundary]
        out[landmarks] = goal
        return out

    start = z0[landmarks].copy()
    z = z0
    relaxation = None
    tau, dtau = 0.0, 1.0
    accepted = rejected = 0
    direct = None                       # the one-step solve from the aligned map
    while tau < 1.0 and accepted + rejected < opt.max_substeps:
        step = min(dtau, 1.0 - tau)
        new_tau = 1.0 if tau + step >= 1.0 - 1e-12 else tau + step
        goal = T if new_tau == 1.0 else start + new_tau * (T - start)
        cand = step_to(z, goal)
        if direct is None:
            direct = cand
        flips = flipped_count(F, cand)
        history.append({"tau": new_tau, "step": step, "flipped_faces": flips,
                        "accepted": flips == 0})
        if progress is not None:
            progress(history[-1])
        if flips == 0:
            z, tau, accepted = cand, new_tau, accepted + 1
            dtau = min(1.0, 2.0 * step)
            if tau < 1.0 and opt.relax_iterations > 0:
                if relaxation is None:
                    relaxation = InjectiveRelaxation(F, z0, free, opt.solver)
                z = relaxation.relax(z, opt.relax_iterations)
        else:
            rejected += 1
            dtau = step / 2.0
            if dtau < opt.min_step:
                break
    method = "direct" if (accepted == 1 and rejected == 0) else "continuation"
    if tau < 1.0:                       # stalled: report the one-step solve and its flips
        z, method = direct, "stalled"
    return DeformResult(z, flipped_count(F, z), method, accepted, rejected, tau, history)


# -------------------------------------------------------------------------- 3. composition


def compose_with_inverse(z_source, V_target: np.ndarray, F_target: np.ndarray, uv_target,
                         boundary_target: np.ndarray | None = None,
                         landmarks_source: np.ndarray | None = None,
                         landmarks_target: np.ndarray | None = None):
    """Lift deformed source disk points to the target surface through the inverse map (eq. 1).

    Returns ``(points n×3, face n, barycentric n×3)``. Source landmarks (which sit exactly on
    their target landmarks' disk positions) are assigned the target landmark vertex exactly:
    face = a face containing it, barycentric = the corner's unit vector.
    """
    from .locate import lift, locate_points

    z = as_complex(z_source)
    uv_t = as_uv(as_complex(uv_target))
    F_target = np.asarray(F_target, dtype=np.int64)
    face, bary = locate_points(uv_t, F_target, as_uv(z), boundary=boundary_target)
    if landmarks_source is not None and len(landmarks_source):
        face, bary = snap_landmarks(F_target, face, bary, landmarks_source, landmarks_target,
                                    len(uv_t))
    points = lift(np.asarray(V_target, dtype=np.float64), F_target, face, bary)
    return np.asarray(points, dtype=np.float64), face, bary


def snap_landmarks(F_target: np.ndarray, face: np.ndarray, bary: np.ndarray,
                   landmarks_source: np.ndarray, landmarks_target: np.ndarray, n_target: int
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Located points with each source landmark set exactly on its target landmark vertex.

    Parameters
    ----------
    F_target : (m, 3) int array
    face : (n,) int array, bary : (n, 3) float array
        Located source points (face of ``F_target`` and barycentrics).
    landmarks_source, landmarks_target : (k,) int arrays
        Paired vertex indices (source rows, target vertices).
    n_target : int
        Target vertex count.

    Returns
    -------
    face, bary : copies where row ``landmarks_source[j]`` is a face containing
        ``landmarks_target[j]`` and that corner's unit vector.
    """
    face = np.asarray(face, dtype=np.int64).copy()
    bary = np.asarray(bary, dtype=np.float64).copy()
    ls = np.asarray(landmarks_source, dtype=np.int64)
    lt = np.asarray(landmarks_target, dtype=np.int64)
    first_face = np.full(n_target, -1, dtype=np.int64)
    corner = np.zeros(n_target, dtype=np.int64)
    for c in (2, 1, 0):                         # any face containing the vertex
        first_face[F_target[:, c]] = np.arange(len(F_target))
    for c in range(3):
        hit = F_target[first_face[lt], c] == lt
        corner[lt[hit]] = c
    face[ls] = first_face[lt]
    bary[ls] = np.eye(3)[corner[lt]]
    return face, bary


def error_summary(err: np.ndarray, scale: float) -> dict:
    """Mean, 95th percentile and max of ``err / scale`` (e.g. relative to a bbox diagonal)."""
    e = np.asarray(err, dtype=np.float64) / scale
    if len(e) == 0:
        return {"mean": float("nan"), "p95": float("nan"), "max": float("nan"), "count": 0}
    return {"mean": float(e.mean()), "p95": float(np.percentile(e, 95)), "max": float(e.max()),
            "count": int(len(e))}
