"""Registration of two closed genus-0 meshes on their spherical maps
(:mod:`pipeline.geometry.register_sphere`, :func:`pipeline.stages.register.register_spheres`).

The data has no closed meshes with landmarks, so the pairs are built here: an icosphere and a
rotated, stretched copy of it with known spherical maps (exact case), and igl_bunny against a
smoothly warped, decimated copy (different connectivity), landmarks by farthest-point sampling
on the source and the nearest target vertex of each warped landmark.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import require_data
from pipeline.geometry.register_sphere import (deform_sphere_to_landmarks, fit_sphere_rotation,
                                               group_linear_map, kernel_step,
                                               landmark_linear_maps, reversed_landmark_faces,
                                               rotation_summary)
from pipeline.geometry.locate_sphere import locate_on_sphere
from pipeline.geometry.repair import RepairedMesh
from pipeline.geometry.sem import SEMOptions
from pipeline.geometry.sphere import folded_faces, triple_products
from pipeline.stages.load import Intake
from pipeline.stages.parameterize import Parameterization
from pipeline.stages.register import Face, Pair, register_maps, write_registration
from test_sphere import icosphere


def random_rotation(seed):
    q = np.random.default_rng(seed).normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def closed_side(V, F, S, landmarks, label):
    """A pair side built by hand (the intake refuses closed meshes until it learns them)."""
    n = len(V)
    mesh = RepairedMesh(V=V, F=F, colors=None, source_index=np.arange(n),
                        boundary=np.empty(0, np.int64), added_vertices=np.empty(0, np.int64))
    info = {"source": label, "input_vertices": n, "input_faces": len(F)}

    class Sem:                                   # what the stage reads of a spherical result
        iterations, status = 0, "given"
    p = Parameterization(mesh, uv=None, sem=Sem(), options=SEMOptions(), metrics={}, sphere=S)
    return Face(Intake(mesh, info), np.asarray(landmarks, np.int64), label), p


def test_rotation_fit_is_a_rotation_and_recovers_a_known_one():
    rng = np.random.default_rng(0)
    P = rng.normal(size=(9, 3))
    P /= np.linalg.norm(P, axis=1, keepdims=True)
    R0 = random_rotation(1)
    R = fit_sphere_rotation(P, P @ R0.T)
    np.testing.assert_allclose(R, R0, atol=1e-12)
    info = rotation_summary(R)
    assert abs(info["det"] - 1) < 1e-12 and info["orthogonality_error"] < 1e-12
    R = fit_sphere_rotation(P, -P)                 # a reflection fits best: must stay det +1
    assert abs(np.linalg.det(R) - 1) < 1e-12


def test_locate_on_sphere_reproduces_points():
    V, F = icosphere(3)
    rng = np.random.default_rng(2)
    q = rng.normal(size=(500, 3))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    face, bary = locate_on_sphere(V, F, np.vstack([q, V[:20]]))
    assert (bary >= 0).all() and np.allclose(bary.sum(axis=1), 1)
    flat = np.einsum("ij,ijk->ik", bary, V[F[face]])
    np.testing.assert_allclose(flat / np.linalg.norm(flat, axis=1, keepdims=True),
                               np.vstack([q, V[:20]]), atol=1e-12)


def test_exact_pair_rotation_then_identity(tmp_path):
    """Icosphere → rotated, stretched copy; the target's map is the rotated identity, so the
    rotation is recovered exactly, nothing deforms and every vertex lands on its partner."""
    V, F = icosphere(3)
    R0 = random_rotation(3)
    VT = (V * [1.6, 1.0, 0.7]) @ R0.T
    lm = np.arange(0, len(V), 61)[:10]
    src, ps = closed_side(V, F, V.copy(), lm, "icosphere")
    tgt, pt = closed_side(VT, F, V @ R0.T, lm, "stretched")
    reg = register_maps(Pair(src, tgt, None, truth=VT, truth_label="same vertices"), ps, pt)
    m = reg.metrics
    assert reg.ok and m["flipped_faces"] == 0 and m["domain"] == "sphere"
    assert abs(m["alignment"]["det"] - 1) < 1e-12
    np.testing.assert_allclose(reg.alignment.R, R0, atol=1e-10)
    assert m["landmark_residual"]["after"]["max"] <= 1e-6
    assert m["landmark_residual"]["after_located_max"] <= 1e-6
    assert m["dense_error"]["ours"]["max"] < 1e-9
    files = write_registration(reg, tmp_path / "reg")
    with np.load(files["npz"]) as z:
        n = len(V)
        assert z["mapped_points"].shape == (n, 3) and z["target_face"].shape == (n,)
        assert z["target_barycentric"].shape == (n, 3) and z["rotation"].shape == (3, 3)
    assert (tmp_path / "reg" / "spheres.png").is_file()


def test_deformation_moves_landmarks_exactly_without_folds():
    V, F = icosphere(3)
    rng = np.random.default_rng(5)
    lm = rng.choice(len(V), 10, replace=False)
    T = V[lm] + 0.15 * rng.normal(size=(10, 3))
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    de = deform_sphere_to_landmarks(F, V, lm, T)
    assert de.ok and folded_faces(de.S, F) == 0
    np.testing.assert_allclose(de.S[lm], T, atol=1e-15, rtol=0)
    np.testing.assert_allclose(np.linalg.norm(de.S, axis=1), 1, atol=1e-12)


def sliver_at_landmark_case(seed: int):
    """icosphere(3), 10 random landmarks, landmark 0 moved 1e-8 from the opposite edge of one
    of its faces (det ~1e-8 of the median, as equiareal maps leave them), goals the landmarks
    + 0.15·N(0, 1), normalized."""
    V, F = icosphere(3)
    rng = np.random.default_rng(seed)
    lm = rng.choice(len(V), 10, replace=False)
    faces = np.flatnonzero((F == lm[0]).any(axis=1))
    v, w = [x for x in F[faces[0]] if x != lm[0]]
    ring = np.setdiff1d(F[faces], [lm[0]])
    S = V.copy()
    p = (1 - 1e-8) * (V[v] + V[w]) / 2 + 1e-8 * V[ring].mean(axis=0)
    S[lm[0]] = p / np.linalg.norm(p)
    T = S[lm] + 0.15 * rng.normal(size=(10, 3))
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    return F, S, lm, T


def test_a_sliver_at_a_landmark_moves_with_it():
    """Over 20 seeds: where the landmark moves toward the sliver's opposite edge, held-back
    neighbours would fold the sliver at any step length; moving them with the landmark's linear
    map keeps it positive, and the landmarks exact. The seeds include adjacent landmarks that
    approach each other (2, 12): the faces on their shared edge keep their orientation by moving
    with both landmarks' group map."""
    failed, carried = [], []
    for seed in range(20):
        F, S, lm, T = sliver_at_landmark_case(seed)
        det = triple_products(S, F)
        assert det.min() > 0 and det.min() < 1e-7 * np.median(det)
        assert not len(reversed_landmark_faces(F, S[lm], lm, T))     # a feasible configuration
        de = deform_sphere_to_landmarks(F, S, lm, T)
        if not (de.ok and (triple_products(de.S, F) > 0).all()
                and all(h["flipped_after_hold_back"] == 0 for h in de.history if h["accepted"])
                and np.abs(de.S[lm] - T).max() <= 1e-15):
            failed.append((seed, de.method, de.flipped_faces))
        if de.carried_vertices:
            carried.append(seed)
    assert not failed, failed
    assert 2 in carried and 12 in carried


def test_adjacent_landmarks_share_one_linear_map():
    """Two landmarks of one face with one group map: both reach their goals exactly, and the
    face's third vertex moved by it keeps the face's orientation."""
    V, F = icosphere(2)
    a, b, c = F[0]
    goal = V[[a, b]] + np.array([[0.05, 0.0, 0.0], [-0.05, 0.02, 0.0]])
    goal /= np.linalg.norm(goal, axis=1, keepdims=True)
    maps = landmark_linear_maps(V, np.array([a, b]), goal, 2.0)
    M = group_linear_map(maps, V[[a, b]], goal)
    np.testing.assert_allclose(V[[a, b]] @ M.T, goal, atol=1e-14)
    assert np.linalg.det(M) > 0 and np.linalg.det(np.stack([goal[0], goal[1], M @ V[c]])) > 0


def test_a_reversed_face_of_three_landmarks_is_reported_infeasible():
    """The landmarks are placed exactly, so a face of three landmarks whose goals reverse its
    orientation folds whatever the rest does: reported as ``infeasible``, not attempted."""
    V, F = icosphere(2)
    lm = np.array(F[0])
    T = V[lm[[0, 2, 1]]]                           # two corners swapped: the face reversed
    assert len(reversed_landmark_faces(F, V[lm], lm, T)) == 1
    de = deform_sphere_to_landmarks(F, V, lm, T)
    assert de.method == "infeasible" and not de.ok and de.landmark_faces_reversed == 1


def test_landmark_linear_map_matches_the_kernel_step_to_first_order():
    rng = np.random.default_rng(0)
    S = rng.normal(size=(200, 3))
    S /= np.linalg.norm(S, axis=1, keepdims=True)
    lm = np.arange(8)
    goal = S[lm] + 0.2 * rng.normal(size=(8, 3))
    goal /= np.linalg.norm(goal, axis=1, keepdims=True)
    M = landmark_linear_maps(S, lm, goal, 2.0)
    np.testing.assert_allclose(np.einsum("lab,lb->la", M, S[lm]), goal, atol=1e-14)
    for h in (1e-2, 1e-3):                         # the gap shrinks as h², not h
        x = S[lm] + h * rng.normal(size=(8, 3))
        x /= np.linalg.norm(x, axis=1, keepdims=True)
        gaps = [np.linalg.norm(kernel_step(np.vstack([S, x[[k]]]), lm, goal, 2.0)[-1]
                               - (m := M[k] @ x[k]) / np.linalg.norm(m)) for k in range(8)]
        assert max(gaps) < 20 * h * h


def test_landmark_swap_is_reported_as_failure():
    V, F = icosphere(2)
    a, b = 0, int(np.argmax(V @ V[0] < 0.7) )
    de = deform_sphere_to_landmarks(F, V, np.array([a, b, 5]), V[[b, a, 5]])
    assert de.method == "stalled" and de.flipped_faces > 0 and not de.ok


# ------------------------------------------------------------- a real closed pair (igl_bunny)

def warp(X, centre, size):
    """A smooth non-rigid deformation of space (a sine field and a 1.2× stretch along x)."""
    Y = (X - centre) / size
    Y = Y + 0.08 * np.column_stack([np.sin(3 * Y[:, 1]), np.sin(2.5 * Y[:, 2] + 0.3),
                                    np.sin(3 * Y[:, 0])])
    Y[:, 0] *= 1.2
    return Y * size + centre


def farthest_points(V, count, first=0):
    """``count`` vertices by farthest-point sampling from vertex ``first``."""
    picked = [first]
    d = np.linalg.norm(V - V[first], axis=1)
    for _ in range(count - 1):
        picked.append(int(np.argmax(d)))
        d = np.minimum(d, np.linalg.norm(V - V[picked[-1]], axis=1))
    return np.array(picked)


@pytest.fixture(scope="module")
def bunny_pair():
    """igl_bunny decimated to ~1400 vertices (source) and the bunny decimated differently and
    warped (target; other connectivity), 10 landmarks (farthest points on the source, nearest
    target vertex to each warped landmark), their spherical maps, and the warped source as an
    approximate ground truth (the target surface is the warped bunny, decimated)."""
    import fast_simplification

    from pipeline.geometry.repair import triangulate_polygons
    from pipeline.geometry.sphere import spherical_sem
    from pipeline.io.meshio import read_mesh

    raw = read_mesh(require_data("closed", "igl_bunny.obj"))
    V = np.asarray(raw.V, np.float64)
    F = triangulate_polygons(raw.faces, len(V))[0]
    centre, size = V.mean(axis=0), np.ptp(V, axis=0).max()
    Vs, Fs = fast_simplification.simplify(V, F, target_reduction=0.6)
    Vt, Ft = fast_simplification.simplify(V, F, target_reduction=0.7)
    Vt = warp(Vt, centre, size)
    ls = farthest_points(Vs, 10)
    truth = warp(Vs, centre, size)
    lt = np.array([int(np.argmin(np.linalg.norm(Vt - truth[i], axis=1))) for i in ls])
    rs, rt = spherical_sem(Vs, Fs), spherical_sem(Vt, Ft)
    src, ps = closed_side(Vs, rs.F, rs.S, ls, "bunny (decimated)")
    tgt, pt = closed_side(Vt, rt.F, rt.S, lt, "bunny (warped, decimated)")
    return Pair(src, tgt, None, truth=truth, truth_label="warped source"), ps, pt


def test_bunny_pair_registration_is_exact_and_fold_free(bunny_pair, tmp_path):
    from pipeline.stages.morph import MorphConfig, load_morph_inputs, morph_stage, write_morph

    pair, ps, pt = bunny_pair
    assert len(pair.source.mesh.F) != len(pair.target.mesh.F)     # other connectivity
    reg = register_maps(pair, ps, pt)
    m = reg.metrics
    assert reg.ok and m["flipped_faces"] == 0
    assert folded_faces(reg.deform.S, reg.pair.source.mesh.F) == 0
    assert m["landmark_residual"]["after"]["max"] <= 1e-6
    assert m["landmark_residual"]["after_located_max"] <= 1e-6
    assert m["landmark_residual"]["before"]["max"] > 1e-3
    assert m["dense_error"]["ours"]["mean"] < 0.06
    files = write_registration(reg, tmp_path / "reg")
    with np.load(files["npz"]) as z:
        lifted = np.einsum("ij,ijk->ik", z["target_barycentric"],
                           z["target_vertices"][z["target_faces"][z["target_face"]]])
        np.testing.assert_allclose(lifted, z["mapped_points"], atol=1e-12)
    V0, V1, F = load_morph_inputs([str(tmp_path / "reg")])
    morph = morph_stage(V0, V1, F, MorphConfig(frames=5, size=96))
    out = write_morph(morph, tmp_path / "morph")
    from PIL import Image
    with Image.open(out["gif"]) as gif:
        assert gif.n_frames == 5


def test_a_closed_and_an_open_mesh_are_refused_in_one_line():
    from pipeline.errors import UserError
    from pipeline.stages.register import check_same_domain

    V, F = icosphere(1)
    src, ps = closed_side(V, F, V.copy(), np.arange(3), "sphere")
    disk = RepairedMesh(V=V, F=F, colors=None, source_index=np.arange(len(V)),
                        boundary=np.arange(5), added_vertices=np.empty(0, np.int64))
    tgt = Face(Intake(disk, {"source": "disk", "input_vertices": len(V)}), np.arange(3), "t")
    with pytest.raises(UserError) as exc:
        check_same_domain(Pair(src, tgt, None))
    assert "closed (sphere)" in str(exc.value) and "\n" not in str(exc.value)
    disk_map = Parameterization(disk, uv=np.zeros((len(V), 2)), sem=None, options=SEMOptions())
    with pytest.raises(UserError, match="two closed meshes"):
        register_maps(Pair(src, tgt, None), ps, disk_map)


def test_cli_register_and_morph_closed_meshes(bunny_pair, tmp_path):
    """The command line end to end on two closed OBJs (skipped while the intake refuses closed
    meshes, which the sphere branch of ``input``/``parameterize`` lifts)."""
    from conftest import run_cli
    from pipeline.io.meshio import write_obj

    pair, _, _ = bunny_pair
    S, T = pair.source, pair.target
    write_obj(tmp_path / "s.obj", S.mesh.V, S.mesh.F)
    write_obj(tmp_path / "t.obj", T.mesh.V, T.mesh.F)
    (tmp_path / "ls.txt").write_text("\n".join(map(str, S.landmarks)) + "\n")
    (tmp_path / "lt.txt").write_text("\n".join(map(str, T.landmarks)) + "\n")
    code, out, err = run_cli("register", tmp_path / "s.obj", tmp_path / "t.obj",
                             "--source-landmarks", tmp_path / "ls.txt", "--target-landmarks",
                             tmp_path / "lt.txt", "-o", tmp_path / "r")
    if code == 2 and "closed" in err:
        pytest.skip(f"the intake does not take closed meshes yet: {err.strip()}")
    assert code == 0, err
    m = __import__("json").loads((tmp_path / "r" / "metrics.json").read_text())
    assert m["domain"] == "sphere" and m["flipped_faces"] == 0
    assert m["landmark_residual"]["after"]["max"] <= 1e-6
    code, out, err = run_cli("morph", tmp_path / "r", "-o", tmp_path / "m", "--frames", "4",
                             "--size", "96")
    assert code == 0, err
    assert (tmp_path / "m" / "morph.gif").is_file()
