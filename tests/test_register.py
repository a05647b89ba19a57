"""Landmark registration on the SEM disks (pipeline.geometry.register, pipeline.stages.register).

Exact checks on constructed cases (rotation, Möbius, deformation, inverse map), an end-to-end run
on the embedded synthetic face (files, CLI, baseline plumbing), and the ICT pairs from the shared
data: 0 flipped faces and landmark residual ≤ 1e-6 of the target diagonal for A_neutral →
{A_smile, B_neutral, B_smile_jawopen}, *_disk.obj and *_holes.obj, ibug68 and the 16 named
landmarks. Each ICT mesh is parameterized once per session.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial import Delaunay

from conftest import require_data, run_cli
from pipeline.errors import UserError
from pipeline.geometry.register import (DeformOptions, InjectiveRelaxation, align,
                                        compose_with_inverse, deform_to_landmarks, fit_mobius,
                                        fit_rotation, flipped_count, mobius)
from pipeline.geometry.repair import RepairOptions
from pipeline.geometry.sem import SEMOptions

ICT_SEM = SEMOptions(mode="converged", max_iter=100)


# ------------------------------------------------------------------- constructed disk meshes


def disk_mesh(rings=12):
    """Concentric rings (6k points on ring k) triangulated by Delaunay, CCW; the unit disk."""
    pts = [0j]
    for k in range(1, rings + 1):
        m = 6 * k
        pts += list(k / rings * np.exp(1j * (2 * np.pi * np.arange(m) / m + (0.5 / m) * (k % 2))))
    z = np.array(pts)
    F = Delaunay(np.column_stack([z.real, z.imag])).simplices.astype(np.int64)
    a, b = z[F[:, 1]] - z[F[:, 0]], z[F[:, 2]] - z[F[:, 0]]
    neg = (np.conj(a) * b).imag < 0
    F[neg] = F[neg][:, [0, 2, 1]]
    boundary = np.arange(len(z) - 6 * rings, len(z))
    return z, F, boundary


def nearest(z, p):
    return int(np.argmin(np.abs(z - p)))


def test_fit_rotation_recovers_a_known_rotation():
    rng = np.random.default_rng(1)
    zs = rng.uniform(-0.7, 0.7, 12) + 1j * rng.uniform(-0.7, 0.7, 12)
    for theta in (0.0, 0.4, -2.9, np.pi):
        r = fit_rotation(zs, zs * np.exp(1j * theta))
        assert abs(r - np.exp(1j * theta)) < 1e-13
    uv = np.column_stack([zs.real, zs.imag])
    al = align(uv, np.arange(12), zs * np.exp(0.7j))
    assert abs(al.theta - 0.7) < 1e-13 and al.rms_after < 1e-13 and al.kind == "rotation"


def test_mobius_maps_the_disk_to_itself():
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    rng = np.random.default_rng(2)
    inner = np.sqrt(rng.uniform(0, 0.999, 500)) * np.exp(2j * np.pi * rng.uniform(size=500))
    for theta, a in ((0.3, 0.2 - 0.5j), (-1.0, 0.9j), (2.0, 0.0)):
        np.testing.assert_allclose(np.abs(mobius(np.exp(1j * t), theta, a)), 1.0, atol=1e-13)
        assert np.all(np.abs(mobius(inner, theta, a)) < 1.0)
        assert abs(mobius(np.array([a]), theta, a)[0]) < 1e-15      # a ↦ 0
    # its inverse is the Möbius map with (−θ, −a e^{iθ})
    z = mobius(inner, 0.3, 0.2 - 0.5j)
    back = mobius(z, -0.3, -(0.2 - 0.5j) * np.exp(0.3j))
    np.testing.assert_allclose(back, inner, atol=1e-13)


def test_fit_mobius_recovers_a_known_map():
    rng = np.random.default_rng(3)
    zs = np.sqrt(rng.uniform(0, 0.8, 20)) * np.exp(2j * np.pi * rng.uniform(size=20))
    theta, a = 0.5, 0.15 + 0.1j
    th, aa, rms = fit_mobius(zs, mobius(zs, theta, a))
    assert rms < 1e-10 and abs(aa - a) < 1e-9 and abs(np.angle(np.exp(1j * (th - theta)))) < 1e-9


def test_deformation_puts_landmarks_exactly_and_keeps_the_boundary():
    z, F, B = disk_mesh(12)
    lm = np.array([nearest(z, p) for p in (0.3, 0.4j, -0.5 - 0.2j, 0.55 - 0.4j)])
    T = z[lm] + np.array([0.05, -0.04 + 0.03j, 0.06j, -0.05])
    r = deform_to_landmarks(F, z, B, lm, T)
    assert r.method == "direct" and r.flipped_faces == 0 and r.ok
    assert np.array_equal(r.z[lm], T)
    assert np.array_equal(r.z[B], z[B])


def test_continuation_avoids_folds_that_the_direct_solve_makes():
    z, F, B = disk_mesh(14)
    ang = 2 * np.pi * np.arange(6) / 6
    inner = [nearest(z, 0.3 * np.exp(1j * a)) for a in ang]
    outer = [nearest(z, 0.65 * np.exp(1j * (a + 0.3))) for a in ang]
    lm = np.array(inner + outer)
    T = np.r_[z[inner] * np.exp(1.5j), z[outer]]                    # twist the inner ring
    for energy in ("biharmonic", "harmonic"):
        r = deform_to_landmarks(F, z, B, lm, T, DeformOptions(energy=energy))
        assert r.method == "continuation" and r.rejected_substeps > 0
        assert r.flipped_faces == 0 and np.array_equal(r.z[lm], T)
        assert r.history[0]["flipped_faces"] > 0                     # the direct try folded


def test_impossible_landmark_paths_are_reported_not_hidden():
    z, F, B = disk_mesh(10)
    a, b = nearest(z, -0.3), nearest(z, 0.3)
    r = deform_to_landmarks(F, z, B, np.array([a, b]), z[[b, a]])   # swap two landmarks
    assert r.method == "stalled" and r.path_reached < 1.0
    assert r.flipped_faces > 0 and not r.ok
    assert r.flipped_faces == flipped_count(F, r.z)


def test_injective_relaxation_energy_and_gradient():
    z, F, B = disk_mesh(5)
    free = np.setdiff1d(np.arange(len(z)), B)
    rel = InjectiveRelaxation(F, z, free, "auto")
    E0, _ = rel.energy(z)
    assert abs(E0 - 4.0 * rel.area.sum()) < 1e-12                  # J = I: ‖J‖² (1 + 1) = 4
    rng = np.random.default_rng(4)
    w = z.copy()
    w[free] += 0.01 * (rng.normal(size=len(free)) + 1j * rng.normal(size=len(free)))
    E, g = rel.energy(w, gradient=True)
    d = np.zeros_like(w)
    d[free] = rng.normal(size=len(free)) + 1j * rng.normal(size=len(free))
    h = 1e-6
    fd = (rel.energy(w + h * d)[0] - rel.energy(w - h * d)[0]) / (2 * h)
    assert abs(fd - np.sum((np.conj(g) * d).real)) < 1e-5 * abs(fd)
    relaxed = rel.relax(w, 5)
    assert rel.energy(relaxed)[0] < E and flipped_count(F, relaxed) == 0


def test_compose_with_inverse_identity_and_exact_landmarks():
    z, F, B = disk_mesh(8)
    V = np.column_stack([z.real, z.imag, np.cos(z.real) * np.sin(z.imag)])
    q = 0.7 * z[::3] * np.exp(0.2j)
    P, face, bary = compose_with_inverse(q, V, F, z, B)
    np.testing.assert_allclose(P[:, :2], np.column_stack([q.real, q.imag]), atol=1e-12)
    np.testing.assert_allclose(bary.sum(axis=1), 1.0, atol=1e-12)
    lm_t = np.array([5, 40, 77])
    P, face, bary = compose_with_inverse(z[lm_t], V, F, z, B, np.arange(3), lm_t)
    assert np.array_equal(P, V[lm_t])
    assert all(F[face[k]][np.argmax(bary[k])] == lm_t[k] for k in range(3))


# ------------------------------------------------------------- the synthetic sample, end to end


@pytest.fixture(scope="module")
def sample_registration(tmp_path_factory):
    from pipeline.stages.register import RegisterConfig, register_stage, sample_pair

    pair = sample_pair(1200, "smile")
    reg = register_stage(pair, RegisterConfig(sample=True, sample_vertices=1200, baseline=True),
                         SEMOptions(mode="converged", max_iter=60))
    return reg


def test_sample_registration_is_exact_bijective_and_accurate(sample_registration):
    reg = sample_registration
    m = reg.metrics
    assert reg.ok and m["flipped_faces"] == 0 and m["status"] == "ok"
    assert m["landmark_residual"]["after"]["max"] <= 1e-6
    assert m["landmark_residual"]["after_located_max"] <= 1e-6      # without the snapping too
    assert m["landmark_residual"]["before"]["max"] > 1e-3
    de = m["dense_error"]
    assert de["ours"]["count"] == len(reg.pair.source.mesh.V)
    assert de["ours"]["mean"] < 0.01
    assert "nricp_amberg" in de and m["baseline"]["seconds"] > 0
    assert np.isfinite(reg.baseline["points"]).all()


def test_registration_files(sample_registration, tmp_path):
    from pipeline.stages.register import write_registration

    reg = sample_registration
    files = write_registration(reg, tmp_path / "reg")
    n = len(reg.pair.source.mesh.V)
    with np.load(files["npz"]) as z:
        assert z["mapped_points"].shape == (n, 3)
        assert z["target_face"].shape == (n,) and z["target_barycentric"].shape == (n, 3)
        T, FT = z["target_vertices"], z["target_faces"]
        lifted = np.einsum("ij,ijk->ik", z["target_barycentric"], T[FT[z["target_face"]]])
        np.testing.assert_allclose(lifted, z["mapped_points"], atol=1e-12)
    text = files["obj"].read_text()
    assert text.count("\nv ") + text.startswith("v ") == n
    m = json.loads(files["metrics"].read_text())
    assert m["flipped_faces"] == 0
    html = files["report"].read_text()
    assert "nricp_amberg" in html and "disks.png" in html
    for name in ("disks", "surfaces", "error_on_face"):
        assert files[name].stat().st_size > 10_000



def test_cli_register_writes_the_contract_files(sample_files, tmp_path):
    p = sample_files
    code, out, err = run_cli("register", p["neutral"], p["smile"], "--source-landmarks",
                             p["landmarks"], "--target-landmarks", p["landmarks"], "-o",
                             tmp_path / "r", "--truth", p["smile"], "--max-iter", "40",
                             "--no-figures")
    assert code == 0, err
    assert "flipped faces = 0" in out and "dense error" in out
    for name in ("registration.npz", "registered.obj", "metrics.json", "report.html"):
        assert (tmp_path / "r" / name).is_file()
    code, out, err = run_cli("morph", tmp_path / "r", "-o", tmp_path / "m", "--frames", "3",
                             "--size", "96")
    assert code == 0, err
    assert sorted(q.name for q in (tmp_path / "m" / "frames").iterdir()) == [
        "frame_000.obj", "frame_001.obj", "frame_002.obj"]


@pytest.mark.parametrize("extra, words", [
    (["--landmark-set", "ibug68"], ["no landmark set 'ibug68'"]),
    (["--truth", "TARGET_LM"], ["unsupported mesh format"]),
])
def test_cli_register_bad_input_is_one_line(sample_files, tmp_path, extra, words):
    p = sample_files
    extra = [str(p["landmarks"]) if e == "TARGET_LM" else e for e in extra]
    code, out, err = run_cli("register", p["neutral"], p["smile"], "--source-landmarks",
                             p["landmarks"], "-o", tmp_path / "r", *extra)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err
    for w in words:
        assert w in lines[0]


def test_cli_register_count_mismatch(sample_files, tmp_path):
    p = sample_files
    (tmp_path / "few.txt").write_text("10\n20\n30\n")
    code, _, err = run_cli("register", p["neutral"], p["smile"], "--source-landmarks",
                           p["landmarks"], "--target-landmarks", tmp_path / "few.txt",
                           "-o", tmp_path / "r")
    assert code == 2 and "16 source landmarks but 3 target landmarks" in err
    assert len(err.strip().splitlines()) == 1


def test_config_register_and_morph_sections(tmp_path):
    from pipeline.config import load_config

    def cfg(text):
        path = tmp_path / "c.yaml"
        path.write_text(text)
        return path

    config, _ = load_config(cfg("register: {sample: true}\nmorph: {frames: 5}\n"))
    assert config.input is None and config.morph.frames == 5
    for text, words in (("run: {name: x}\n", "give an 'input'"),
                        ("input: {sample: {}}\nmorph: {}\n", "needs a 'register'"),
                        ("register: {sample: true, source: a.obj}\n", "not both"),
                        ("register: {source: a.obj}\n", "give 'source', 'target'"),
                        ("register: {sample: true}\nmorph: {easing: bounce}\n", "morph.easing"),
                        ("register: {sample: true, energi: x}\n", "did you mean 'energy'"),
                        ("register: {source: a.obj, target: b.obj, source_landmarks: l.json}\n",
                         "register.source: file")):
        with pytest.raises(UserError) as exc:
            load_config(cfg(text))
        assert words in str(exc.value), str(exc.value)


# ----------------------------------------------------------------------------- ICT ground truth

ICT_TARGETS = ("A_smile", "B_neutral", "B_smile_jawopen")


@pytest.fixture(scope="session")
def ict():
    """Every ICT mesh read, repaired (holes closed) and SEM-parameterized once."""
    from pipeline.stages.load import load_stage
    from pipeline.stages.parameterize import parameterize_stage

    folder = require_data("faces", "ict")
    cache = {}

    def get(name, kind):
        key = (name, kind)
        if key not in cache:
            intake = load_stage(folder / f"ict_{name}_{kind}.obj",
                                RepairOptions(close_holes=True))
            p = parameterize_stage(intake.mesh, ICT_SEM)
            assert p.ok
            cache[key] = (intake, p)
        return cache[key]

    get.folder = folder
    return get


@pytest.mark.parametrize("kind", ["disk", "holes"])
@pytest.mark.parametrize("landmark_set", ["ibug68", None])
@pytest.mark.parametrize("target", ICT_TARGETS)
def test_ict_registration_is_bijective_and_exact(ict, target, landmark_set, kind):
    from pipeline.io.landmarks import pair_landmarks, read_landmarks, resolve_landmarks
    from pipeline.stages.register import Face, Pair, load_truth, register_maps

    si, ps = ict("A_neutral", kind)
    ti, pt = ict(target, kind)
    lms = read_landmarks(ict.folder / "ict_landmarks.json", landmark_set)
    ls, lt = pair_landmarks(lms, lms)
    face_s = Face(si, resolve_landmarks(ls, si.mesh, si.info["input_vertices"])[0], "source")
    face_t = Face(ti, resolve_landmarks(lt, ti.mesh, ti.info["input_vertices"])[0], "target")
    truth = ict.folder / f"ict_{target}_{kind}.obj"
    pair = Pair(face_s, face_t, ls.names, load_truth(truth, si), str(truth))
    reg = register_maps(pair, ps, pt)
    m = reg.metrics
    assert m["flipped_faces"] == 0 and reg.ok
    assert m["landmark_residual"]["after"]["max"] <= 1e-6
    assert m["landmark_residual"]["after_located_max"] <= 1e-6
    assert len(reg.pair.source.landmarks) == (68 if landmark_set else 16)
    assert m["dense_error"]["ours"]["count"] == si.info["input_vertices"]
    assert m["dense_error"]["ours"]["mean"] < 0.015                # measured ≤ 0.0094


def test_cli_register_reports_a_folded_registration_as_failure(sample_files, tmp_path):
    """Target landmarks with the mouth corners swapped (paired by order): their straight paths
    cross, no fold-free deformation follows them, so the run fails with exit code 1 and writes
    only its diagnosis (metrics, report, disk figure), never the map."""
    p = sample_files
    lms = json.loads(p["landmarks"].read_text())["landmarks"]
    src = list(lms.values())
    tgt = list(src)
    i, j = list(lms).index("mouth_left"), list(lms).index("mouth_right")
    tgt[i], tgt[j] = tgt[j], tgt[i]
    (tmp_path / "s.txt").write_text("\n".join(map(str, src)) + "\n")
    (tmp_path / "t.txt").write_text("\n".join(map(str, tgt)) + "\n")
    code, out, err = run_cli("register", p["neutral"], p["smile"], "--source-landmarks",
                             tmp_path / "s.txt", "--target-landmarks", tmp_path / "t.txt",
                             "-o", tmp_path / "r", "--max-iter", "40")
    assert code == 1, err
    assert "registration failed" in err and "flipped faces remain" in err
    out_dir = tmp_path / "r"
    m = json.loads((out_dir / "metrics.json").read_text())
    assert m["status"] == "failed" and m["flipped_faces"] > 0
    assert m["deformation"]["method"] == "stalled"
    assert (out_dir / "disks.png").is_file() and (out_dir / "report.html").is_file()
    assert not (out_dir / "registration.npz").exists()
    assert not (out_dir / "registered.obj").exists()
