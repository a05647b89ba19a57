"""Landmark registration of two spherical maps: rotate, deform, compose.

Given fold-free spherical maps ``f_s`` (source) and ``f_t`` (target) of two closed genus-0
surfaces (:mod:`pipeline.geometry.sphere`) and paired landmark vertices ``ℓ_s``, ``ℓ_t``, the
registration is

    source --f_s--> S² --R--> S² --φ--> S² --f_t⁻¹ (eq. 1, central coordinates)--> target

1. **Rotation** ``R ∈ SO(3)`` (:func:`fit_sphere_rotation`): the rotation minimising
   ``Σ_k w_k |R p_k − q_k|²`` with ``p_k = f_s(ℓ_s,k)``, ``q_k = f_t(ℓ_t,k)`` (Wahba's problem,
   solved by Kabsch's SVD: ``H = Σ w_k p_k q_kᵀ = U Σ Vᵀ``, ``R = V diag(1, 1, d) Uᵀ``,
   ``d = sign det(V Uᵀ)`` so that ``det R = +1``). Rotations are the only maps of the sphere
   onto itself that keep every area, so the aligned map stays equiareal; the disk's Möbius
   option has no equiareal counterpart here. The sphere has no translation to fit.
2. **Deformation** ``φ`` (:func:`deform_sphere_to_landmarks`): a composition of smooth steps
   of the sphere, each ``x ↦ normalize(x + d(x))`` with ``d`` interpolating the landmarks'
   next moves exactly by Wendland's compactly supported C² kernel (eq. D1,
   :func:`kernel_step`), the landmarks moving along their great-circle arcs. As on the disk,
   the whole move is tried first and a step that folds a face is rejected and halved, an
   accepted one lets the next grow (*continuation*). Before a step is rejected, its folds are
   removed where possible by holding vertices back (:func:`hold_back_folds`): a vertex of a
   folded face falls back toward a position on which its faces cannot fold, either its place
   in the current, fold-free map (it stays) or, next to a landmark, its image under the step's
   linear map at that landmark (:func:`landmark_linear_maps`; it moves with the landmark).
   Landmarks that meet in a folded face (two corners of one face, or a landmark and a vertex
   moving with another) form a group of up to three that moves by one linear map sending each
   of them to its goal (:func:`group_linear_map`). Below ``min_step`` the run is ``stalled``:
   the one-step map is returned and its folds reported as a failure, never hidden. A face of
   three landmarks whose orientation their paths reverse folds whatever the other vertices do;
   it is detected before any step and the run is ``infeasible``
   (:func:`reversed_landmark_faces`).

   *Bijectivity.* Every accepted step leaves ``det[s0, s1, s2] > 0`` on every face (counted,
   not assumed), so the deformed map is again a fold-free triangulation of the sphere of degree
   one, whose flat triangles' central projections tile the sphere once: a bijection of the
   sphere onto itself (and, through ``f_s`` and ``f_t⁻¹``, of the surfaces).

   *Why the landmarks carry their faces.* A landmark must arrive, so it cannot stay behind; if
   the other vertices of its faces stay, a face whose landmark moves across the opposite edge
   folds at any step length. A sliver does so under the tiniest step: an equiareal map may
   leave one at a landmark (a converged Gauss–Newton map of the decimated bunny of the tests
   has a face of ~10⁻⁸ of the median ``det`` with a landmark as a corner), and with only the
   faces without a landmark held back the continuation stalled at every step length. A linear
   map ``M`` of R³ with ``det M > 0`` followed by central projection multiplies every face's
   ``det`` by a positive factor, so faces whose vertices all follow one landmark's ``M`` keep
   their orientation whatever their shape; ``M`` agrees with the kernel step to first order at
   the landmark, so the vertices that join it barely leave the smooth field and the faces
   between them and the rest of the map seldom fold for it.

   *Why adjacent landmarks share a map.* Two landmarks on one edge that approach each other
   squeeze the faces on that edge: their third vertex, moved by either landmark's ``M_ℓ``
   alone, lands on the wrong side of the edge between the two goals, since ``M_ℓ`` carries
   only its own landmark to its goal. The map nearest the mean of the two ``M_ℓ`` that sends
   both to their goals moves the third vertex with the edge, and the face's ``det`` is
   multiplied by a positive factor when that map's ``det`` is positive. A linear map of R³ is
   fixed by three landmarks, so groups stop at three (beyond, a least-squares map would not
   carry every landmark to its goal).

   *Limits.* The deformation does not make up for a poor map: a map that crowds most of its
   surface into a small part of the sphere (area ratios of 10⁻³ and less around most of the
   landmarks) makes the landmarks' path a strong compression, held-back vertices pile up and
   the continuation stalls; the run then says ``stalled`` with its folds. Groups of landmarks
   far apart have linear maps far from the smooth step (three of them fix the map entirely),
   so where held-back regions of distant landmarks meet, folds can remain and the run stalls.

   *Why not the disk's deformation.* The disk's mesh-based deformation
   (:func:`pipeline.geometry.register.deform_to_landmarks`), applied in the stereographic plane
   from a pole far from the landmarks or to a background triangulation of a cap, folds faces on
   the sphere: equiareal maps have slivers (image faces many orders of magnitude below the
   median area), which fold under any displacement that is not affine across them, and a
   mesh-based or piecewise-linear displacement is not smooth at the scale of the faces around a
   landmark. A smooth field moves small faces almost affinely.

   *Support.* ``ρ = 2`` (chordal), a global and smoother field: smaller supports make the
   continuation stall where landmarks move far, and ρ = 2 needs the fewest continuation steps
   with the lowest dense error on the warped, decimated pairs that the tests construct.
3. **Composition** (:func:`compose_with_inverse_sphere`): every deformed source point is located
   in the target's spherical triangulation (:mod:`pipeline.geometry.locate_sphere`) and lifted
   by eq. (1). A source landmark sits exactly on its target landmark's image, so it is mapped to
   the target landmark vertex itself (:func:`pipeline.geometry.register.snap_landmarks`).

Pure functions on arrays; ``S`` (n, 3) unit vectors, ``F`` (m, 3) faces with positive
``det[s0, s1, s2]`` (:func:`sphere_faces` orients them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .register import DeformResult, snap_landmarks
from .sphere import folded_faces, triple_products

__all__ = ["SphereAlignment", "SphereDeformResult", "sphere_faces", "chordal_rms",
           "fit_sphere_rotation", "rotation_summary", "align_sphere", "wendland",
           "kernel_matrix", "slerp", "kernel_step", "landmark_linear_maps", "group_linear_map",
           "hold_back_folds", "reversed_landmark_faces",
           "deform_sphere_to_landmarks",
           "compose_with_inverse_sphere"]


def sphere_faces(S: np.ndarray, F: np.ndarray) -> np.ndarray:
    """``F`` (m, 3) oriented for the map ``S``: reversed when the triple products sum negative
    (a consistently oriented mesh whose map runs clockwise seen from outside)."""
    F = np.asarray(F, dtype=np.int64)
    return F if triple_products(S, F).sum() >= 0 else np.ascontiguousarray(F[:, [0, 2, 1]])


def chordal_rms(P: np.ndarray, Q: np.ndarray) -> float:
    """Root mean square of ``|P_k − Q_k|`` (rows of two (k, 3) arrays)."""
    return float(np.sqrt(np.mean(np.sum((P - Q) ** 2, axis=1))))


# ------------------------------------------------------------------------------ 1. rotation


def fit_sphere_rotation(P: np.ndarray, Q: np.ndarray, weights: np.ndarray | None = None
                        ) -> np.ndarray:
    """The rotation ``R`` (3, 3), ``det R = +1``, minimising ``Σ_k w_k |R p_k − q_k|²``.

    Kabsch's solution of Wahba's problem (module docstring, step 1) for points ``P``, ``Q``
    (k, 3) and positive ``weights`` (k,) (default 1).
    """
    P, Q = np.asarray(P, dtype=np.float64), np.asarray(Q, dtype=np.float64)
    w = np.ones(len(P)) if weights is None else np.asarray(weights, dtype=np.float64)
    H = (w[:, None] * P).T @ Q
    U, _, Vt = np.linalg.svd(H)
    d = 1.0 if np.linalg.det(Vt.T @ U.T) >= 0 else -1.0
    return Vt.T @ np.diag([1.0, 1.0, d]) @ U.T


def rotation_summary(R: np.ndarray) -> dict:
    """Angle (degrees) and unit axis of a rotation, ``det R`` and ``max |RᵀR − I|``."""
    angle = float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    norm = np.linalg.norm(axis)
    if norm < 1e-12:                                  # 0 or π: the axis is an eigenvector
        w, v = np.linalg.eigh(R + R.T)
        axis, norm = v[:, -1], 1.0
    return {"matrix": R.tolist(), "angle_deg": float(np.degrees(angle)),
            "axis": (axis / norm).tolist(), "det": float(np.linalg.det(R)),
            "orthogonality_error": float(np.abs(R.T @ R - np.eye(3)).max())}


@dataclass
class SphereAlignment:
    """A rotation of the source sphere: ``R`` (3, 3), the rotated map ``S`` (n, 3) and the
    landmark chordal RMS distances before and after."""

    R: np.ndarray
    S: np.ndarray
    rms_before: float
    rms_after: float
    kind: str = "rotation"

    def as_dict(self) -> dict:
        return {"kind": self.kind, **rotation_summary(self.R),
                "landmark_rms_sphere_before": self.rms_before,
                "landmark_rms_sphere_after": self.rms_after}


def align_sphere(S_source: np.ndarray, landmarks_source: np.ndarray, targets: np.ndarray,
                 weights: np.ndarray | None = None) -> SphereAlignment:
    """Rotate the source map ``S_source`` (n, 3) so that its landmarks best meet ``targets``
    (k, 3) (:func:`fit_sphere_rotation`)."""
    S = np.asarray(S_source, dtype=np.float64)
    P = S[landmarks_source]
    R = fit_sphere_rotation(P, targets, weights)
    S_rot = S @ R.T
    return SphereAlignment(R, S_rot, chordal_rms(P, targets),
                           chordal_rms(S_rot[landmarks_source], targets))


# --------------------------------------------------------------------------- 2. deformation


def wendland(r: np.ndarray) -> np.ndarray:
    """Wendland's compactly supported C² kernel ``ψ(r) = (1 − r)⁴ (4r + 1)`` for ``r < 1``, else 0
    (positive definite in R³, so on the sphere's chordal distances)."""
    r = np.asarray(r, dtype=np.float64)
    return np.where(r < 1.0, (1.0 - r) ** 4 * (4.0 * r + 1.0), 0.0)


def kernel_matrix(X: np.ndarray, P: np.ndarray, support: float) -> np.ndarray:
    """``ψ(|x_i − p_k| / ρ)``, shape (len(X), len(P)), for points X (n, 3), centres P (k, 3)."""
    d = np.linalg.norm(X[:, None, :] - P[None, :, :], axis=2)
    return wendland(d / support)


def slerp(A: np.ndarray, B: np.ndarray, t: float) -> np.ndarray:
    """Points at the fraction ``t`` of the great-circle arcs from ``A`` to ``B`` (k, 3)."""
    om = np.arccos(np.clip(np.einsum("ij,ij->i", A, B), -1.0, 1.0))[:, None]
    s = np.sin(om)
    safe = np.where(s > 1e-12, s, 1.0)
    out = np.where(s > 1e-12, (np.sin((1.0 - t) * om) * A + np.sin(t * om) * B) / safe, A)
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def kernel_step(S: np.ndarray, landmarks: np.ndarray, goal: np.ndarray, support: float
                ) -> np.ndarray:
    """One smooth step of the sphere moving the landmarks onto ``goal`` (k, 3):

        x ↦ (x + Σ_k c_k ψ(|x − p_k|/ρ)) / |…|,   Σ_k c_k ψ(|p_j − p_k|/ρ) = g_j − p_j     (D1)

    (``p = S[landmarks]``, ``c_k ∈ R³``): the displacement interpolates the landmark moves
    exactly, is C² in space and zero farther than ``ρ`` (chordal) from every landmark."""
    P = S[landmarks]
    C = np.linalg.solve(kernel_matrix(P, P, support), goal - P)
    out = S + kernel_matrix(S, P, support) @ C
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    out[landmarks] = goal
    return out


def landmark_linear_maps(S: np.ndarray, landmarks: np.ndarray, goal: np.ndarray,
                         support: float) -> np.ndarray:
    """Per landmark ``ℓ`` at ``p = S[ℓ]``, the linear map ``M_ℓ`` (3, 3) of R³ that agrees with
    the kernel step (D1) ``Φ(x) = x + d(x)`` to first order at ``p`` and sends ``p`` to its
    goal ``g``; shape (k, 3, 3):

        M_ℓ = J + (g − J p) pᵀ,   J = DΦ(p) = I + Σ_k c_k ∇ψ(|x − p_k|/ρ)ᵀ |_{x=p}

    (``M_ℓ p = g`` as ``|p| = 1``; ``Φ(x) − M_ℓ x = O(|x − p|²)`` because ``1 − p·x =
    |x − p|²/2`` on the sphere). The map ``x ↦ normalize(M_ℓ x)`` multiplies every
    ``det[s0, s1, s2]`` by ``det M_ℓ / (|M s0| |M s1| |M s2|)``: it keeps the orientation of
    every face, however thin, when ``det M_ℓ > 0``. The hold-back of
    :func:`hold_back_folds` moves vertices near a landmark with it by this map."""
    P = S[landmarks]
    C = np.linalg.solve(kernel_matrix(P, P, support), goal - P)       # (k, 3) coefficients
    D = P[:, None, :] - P[None, :, :]                                  # p_ℓ − p_k
    r = np.linalg.norm(D, axis=2) / support
    dpsi = np.where(r < 1.0, -20.0 * (1.0 - r) ** 3 / support ** 2, 0.0)   # ∇ψ = dpsi (p − p_k)
    J = np.eye(3)[None] + np.einsum("lk,ka,lkb->lab", dpsi, C, D)
    Jp = np.einsum("lab,lb->la", J, P)
    return J + (goal - Jp)[:, :, None] * P[:, None, :]


def group_linear_map(maps: np.ndarray, P: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """One linear map (3, 3) for a group of landmarks at ``P`` (j, 3) with goals ``goal``
    (j, 3) and linear maps ``maps`` (j, 3, 3) (:func:`landmark_linear_maps`): the map nearest
    (Frobenius) to their mean ``M̄`` among those sending each ``p`` to its goal, where they
    exist,

        M = M̄ + (G − M̄ P) P⁺      (P, G as 3×j columns, P⁺ the pseudo-inverse)

    exact for up to three landmarks with independent positions (least squares beyond). For one
    landmark it is its own ``M_ℓ``; for two landmarks of one face it moves the face's third
    vertex with both, so the face keeps its orientation as long as ``det M > 0``."""
    Mbar = maps.mean(axis=0)
    Pc, Gc = P.T, goal.T
    return Mbar + (Gc - Mbar @ Pc) @ np.linalg.pinv(Pc)


def hold_back_folds(z: np.ndarray, G: np.ndarray, F: np.ndarray, landmarks: np.ndarray,
                    maps: np.ndarray, rounds: int = 48) -> tuple[np.ndarray, int]:
    """Remove a step's folds by holding vertices back: the candidate is

        c_v = normalize(b_v + α_v (G_v − b_v))

    with ``G`` the full step, ``α_v ∈ [0, 1]`` (1 at first) and the *fallback* ``b_v`` either
    ``z_v`` (the current, fold-free map: the vertex stays) or ``normalize(M z_v)`` (it moves
    linearly with a group of landmarks, ``M`` their :func:`group_linear_map`, at first each
    landmark alone with its ``M_ℓ`` of :func:`landmark_linear_maps`). Landmarks have
    ``b = goal``, ``α = 0``. Each round, at every folded face: the landmark groups of its
    vertices merge into one (two landmarks of one face, or a landmark and a vertex that moves
    with another, cannot each keep a map of its own: the face between them would fold when
    they approach each other), the face's vertices without a group join it (so the faces
    around a landmark, which cannot stay behind, move as one linear map with it and keep their
    orientation however thin they are), and the non-landmark vertices halve ``α`` (0 below
    2⁻¹⁰). A group of more than three landmarks or whose map would have ``det M ≤ 0`` is not
    formed; the face's other vertices then follow the group of a landmark corner of the face
    (which cannot move off its goal), if it has one. A face whose vertices all sit at their
    fallbacks is unchanged (``z``) or mapped by one ``M``, so folds remain only at faces
    between two fallbacks; the caller counts them. Returns ``(candidate (n, 3), vertices
    that joined a landmark group)``."""
    n, k = len(z), len(landmarks)
    region = np.full(n, -1, dtype=np.int64)        # the landmark group of a vertex, or −1
    region[landmarks] = np.arange(k)
    P, goal = z[landmarks], G[landmarks]
    gmap = maps.copy()                             # the linear map of each group (by id)
    ok_map = np.linalg.det(maps) > 0
    alpha = np.ones(n)
    alpha[landmarks] = 0.0
    B = z.copy()
    C = G.copy()
    B[landmarks] = C[landmarks] = goal
    det = triple_products(C, F)
    is_lm = np.zeros(n, bool)
    is_lm[landmarks] = True
    for _ in range(rounds):
        bad = np.flatnonzero(det <= 0)
        if not len(bad):
            break
        Fb = F[bad]
        newly = []
        for f in np.flatnonzero((region[Fb] >= 0).any(axis=1)):
            face = Fb[f]
            ids = np.unique(region[face][region[face] >= 0])
            if len(ids) > 1:                           # merge the groups met in the face
                members = np.flatnonzero(np.isin(region[landmarks], ids))
                M = (group_linear_map(maps[members], P[members], goal[members])
                     if len(members) <= 3 else None)
                if M is not None and np.linalg.det(M) > 0:
                    newly.append(np.flatnonzero(np.isin(region, ids) & ~is_lm))
                    region[np.isin(region, ids)] = ids[0]
                    gmap[ids[0]], ok_map[ids[0]] = M, True
                    ids = ids[:1]
                elif is_lm[face].any() and ok_map[region[face[is_lm[face]][0]]]:
                    ids = region[face[is_lm[face]]][:1]    # no merge: follow its landmark
                    move = face[~is_lm[face] & (region[face] != ids[0])]
                    region[move] = ids[0]
                    newly.append(move)
                    continue
                else:
                    continue
            join = face[region[face] < 0]
            if len(join) and ok_map[ids[0]]:
                region[join] = ids[0]
                newly.append(join)
        newly = np.unique(np.concatenate(newly)) if newly else np.zeros(0, np.int64)
        if len(newly):
            moved = np.einsum("vab,vb->va", gmap[region[newly]], z[newly])
            B[newly] = moved / np.linalg.norm(moved, axis=1, keepdims=True)
        idx = np.unique(Fb)
        idx = idx[~is_lm[idx]]
        alpha[idx] = np.where(alpha[idx] < 2.0 ** -10, 0.0, alpha[idx] / 2.0)
        touched = np.union1d(idx, newly)
        c = B[touched] + alpha[touched, None] * (G[touched] - B[touched])
        C[touched] = c / np.linalg.norm(c, axis=1, keepdims=True)
        mark = np.zeros(n, bool)
        mark[touched] = True
        faces = np.flatnonzero(mark[F].any(axis=1))
        det[faces] = triple_products(C, F[faces])
    return C, int(np.count_nonzero(region >= 0) - k)


@dataclass
class SphereDeformResult(DeformResult):
    """The deformed map and how it was reached: the disk's
    :class:`~pipeline.geometry.register.DeformResult` with ``z`` = ``S`` the deformed map
    (n, 3) unit vectors and the folds counted on the sphere, plus the kernel's support and the
    vertices held back at least once (faces that would have folded) and the most vertices an
    accepted step moved with a landmark (:func:`hold_back_folds`), and the faces whose three
    vertices are all landmarks and whose orientation the landmarks' paths reverse (method
    ``infeasible``: no fold-free map along these paths exists, :func:`reversed_landmark_faces`)."""

    support: float = 2.0
    held_vertices: int = 0
    carried_vertices: int = 0
    landmark_faces_reversed: int = 0

    @property
    def S(self) -> np.ndarray:
        return self.z

    def as_dict(self) -> dict:
        return {**super().as_dict(), "kernel": "Wendland C2", "support_chordal": self.support,
                "held_vertices": self.held_vertices, "carried_vertices": self.carried_vertices,
                "landmark_faces_reversed": self.landmark_faces_reversed}


def reversed_landmark_faces(F: np.ndarray, start: np.ndarray, landmarks: np.ndarray,
                            targets: np.ndarray, samples: int = 65) -> np.ndarray:
    """Faces whose three vertices are all landmarks and whose ``det`` is not positive at some
    point of the landmarks' great-circle paths from ``start`` to ``targets`` (sampled at
    ``samples`` fractions, the ends included). The landmarks are placed exactly, so such a face
    folds whatever the other vertices do: the goal configuration (or its path) is impossible
    without a fold."""
    F = np.asarray(F, dtype=np.int64)
    pos = np.full(int(F.max()) + 1, -1, dtype=np.int64)
    pos[landmarks] = np.arange(len(landmarks))
    faces = np.flatnonzero((pos[F] >= 0).all(axis=1))
    if not len(faces):
        return faces
    L = pos[F[faces]]
    bad = np.zeros(len(faces), bool)
    for t in np.linspace(0.0, 1.0, samples):
        X = slerp(start, targets, t) if 0.0 < t < 1.0 else (targets if t == 1.0 else start)
        bad |= np.einsum("fi,fi->f", X[L[:, 0]], np.cross(X[L[:, 1]], X[L[:, 2]])) <= 0
    return faces[bad]


def deform_sphere_to_landmarks(F: np.ndarray, S: np.ndarray, landmarks: np.ndarray,
                               targets: np.ndarray, support: float = 2.0,
                               min_step: float = 2.0 ** -14, max_substeps: int = 400,
                               hold_rounds: int = 48) -> SphereDeformResult:
    """Move ``landmarks`` of the spherical map ``S`` exactly onto ``targets`` without folding a
    face (module docstring, step 2).

    Parameters
    ----------
    F : (m, 3) int array, positive on ``S`` (:func:`sphere_faces`)
    S : (n, 3) float array of unit vectors, fold-free
    landmarks : (k,) int array
    targets : (k, 3) float array of unit vectors
    support : float
        Chordal support radius ``ρ`` of the kernel (D1); 2 (the default) reaches every point
        but the landmarks' antipodes (module docstring: why 2).
    min_step, max_substeps
        As :class:`~pipeline.geometry.register.DeformOptions`: the continuation gives up (method
        ``stalled``) below ``min_step`` of the path or after ``max_substeps`` tries. Finer than
        the disk's 1/1024: faces held back at a landmark can need shorter steps than that.
    hold_rounds : int
        Rounds of :func:`hold_back_folds` per step (each pulls the vertices of the faces still
        folded halfway back toward their fallbacks and lets the vertices of folded faces next
        to a landmark join it).

    Returns
    -------
    SphereDeformResult
        With ``ok``: ``S[landmarks] == targets`` exactly and no folded face. Stalled: the
        one-step map (landmarks exact, its folds counted). Infeasible: a face of three
        landmarks is reversed on their paths (:func:`reversed_landmark_faces`), so no step is
        tried; the one-step map is returned with its folds.
    """
    F = np.asarray(F, dtype=np.int64)
    S = np.asarray(S, dtype=np.float64)
    landmarks = np.asarray(landmarks, dtype=np.int64)
    T = np.asarray(targets, dtype=np.float64)
    T = T / np.linalg.norm(T, axis=1, keepdims=True)
    start, z = S[landmarks].copy(), S
    reversed_faces = reversed_landmark_faces(F, start, landmarks, T)
    if len(reversed_faces):
        z = kernel_step(S, landmarks, T, support)
        return SphereDeformResult(z, folded_faces(z, F), "infeasible", 0, 0, 0.0, [], support,
                                  0, 0, len(reversed_faces))
    tau, dtau, accepted, rejected = 0.0, 1.0, 0, 0
    direct, held, joined, history = None, np.zeros(len(S), bool), 0, []
    while tau < 1.0 and accepted + rejected < max_substeps:
        step = min(dtau, 1.0 - tau)
        new_tau = 1.0 if tau + step >= 1.0 - 1e-12 else tau + step
        goal = T if new_tau == 1.0 else slerp(start, T, new_tau)
        full = cand = kernel_step(z, landmarks, goal, support)
        if direct is None:
            direct = full
        raw = folded_faces(full, F)
        ring = 0
        if raw:                                      # hold back vertices of would-be folds
            maps = landmark_linear_maps(z, landmarks, goal, support)
            cand, ring = hold_back_folds(z, full, F, landmarks, maps, hold_rounds)
            cand[landmarks] = goal
        folds = folded_faces(cand, F)
        history.append({"tau": new_tau, "step": step, "flipped_faces": raw,
                        "flipped_after_hold_back": folds, "moved_with_landmark": ring,
                        "accepted": folds == 0})
        if folds == 0:
            held |= np.linalg.norm(cand - full, axis=1) > 1e-12
            joined = max(joined, ring)
            z, tau, accepted = cand, new_tau, accepted + 1
            dtau = min(1.0, 2.0 * step)
        else:
            rejected += 1
            dtau = step / 2.0
            if dtau < min_step:
                break
    method = "direct" if (accepted == 1 and rejected == 0) else "continuation"
    if tau < 1.0:
        z, method = direct, "stalled"
    return SphereDeformResult(z, folded_faces(z, F), method, accepted, rejected, tau, history,
                              support, int(held.sum()), joined)


# -------------------------------------------------------------------------- 3. composition


def compose_with_inverse_sphere(S_source: np.ndarray, V_target: np.ndarray,
                                F_target: np.ndarray, S_target: np.ndarray,
                                landmarks_source: np.ndarray | None = None,
                                landmarks_target: np.ndarray | None = None):
    """Lift deformed source sphere points (n, 3) to the target surface through the target's
    inverse spherical map (eq. 1 with the central coordinates of
    :mod:`pipeline.geometry.locate_sphere`).

    Returns ``(points (n, 3), face (n,), barycentric (n, 3))``; with landmarks, each source
    landmark is assigned its target landmark vertex exactly.
    """
    from .locate import lift
    from .locate_sphere import locate_on_sphere

    F_target = np.asarray(F_target, dtype=np.int64)
    face, bary = locate_on_sphere(S_target, F_target, S_source)
    if landmarks_source is not None and len(landmarks_source):
        face, bary = snap_landmarks(F_target, face, bary, landmarks_source, landmarks_target,
                                    len(S_target))
    points = lift(np.asarray(V_target, dtype=np.float64), F_target, face, bary)
    return np.asarray(points, dtype=np.float64), face, bary
