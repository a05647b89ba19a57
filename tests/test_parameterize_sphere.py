"""Closed genus-0 meshes through ``input`` and ``parameterize`` (issue #22): the spherical
domain's files and measures (DESIGN.md "Closed genus-0 meshes"), the domain choice, the genus
refusal, and the stages that still need a disk refusing closed meshes in one line.

Exact facts on constructed meshes (an icosphere, an ellipsoid); the real genus-0 meshes of
``shared/data/closed`` through the CLI (paper mode, no figures: the map's quality is the kernel's
business, :mod:`tests.test_sphere`; here: files, keys, shapes, folds and the measures recomputed
from the files).
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from conftest import require_data
from pipeline.cli import main
from pipeline.errors import UserError
from pipeline.geometry import sphere
from pipeline.geometry.laplacian import face_double_areas
from pipeline.geometry.metrics import corner_angles
from pipeline.geometry.repair import repair_mesh
from pipeline.geometry.sem import (REMESH_DISK_STEPS, REMESH_SPHERE_FREE_STEPS,
                                   REMESH_SPHERE_STEPS, SEMOptions)
from pipeline.geometry.sphere_metrics import (sphere_angular_distortion,
                                              sphere_distortion_summary,
                                              sphere_local_area_ratios,
                                              spherical_corner_angles)
from pipeline.io.meshio import read_mesh, write_obj
from pipeline.stages.parameterize import (Parameterization, ParameterizationFailed,
                                          parameterize_stage, resolve_domain, sphere_options,
                                          write_parameterization)
from test_sphere import icosphere, torus

GENUS_ZERO = ["igl_arm", "igl_bumpy_cube", "igl_bunny", "igl_decimated_max", "igl_elephant"]
NPZ_KEYS = ["faces", "source_index", "sphere", "vertices"]


def cli(*args) -> tuple[int, str, str]:
    """``sem-pipeline ARGS`` in this process: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return code, out.getvalue(), err.getvalue()


def error_line(err: str, *skip: str) -> str:
    """The one ``error:`` line of stderr (progress lines starting with ``skip`` left out)."""
    lines = [ln for ln in err.strip().splitlines() if ln.strip() and not ln.startswith(skip)]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return lines[0]


def ellipsoid(level: int = 3):
    """An icosphere stretched to an ellipsoid (semi-axes 2, 1, 0.7): closed, genus 0, outward."""
    V, F = icosphere(level)
    return V * [2.0, 1.0, 0.7], F


# ----------------------------------------------------------------------- exact facts (kernels)

def test_spherical_corner_angles_obey_girard_and_fold_sign():
    V, F = icosphere(2)
    ang = spherical_corner_angles(V, F)
    excess = sphere.spherical_triangle_areas(V, F)
    np.testing.assert_allclose(ang.sum(axis=1), np.pi + excess, atol=1e-12)
    # the octant triangle (x, y, z) has three right angles
    octant = np.eye(3)
    np.testing.assert_allclose(spherical_corner_angles(octant, np.array([[0, 1, 2]])),
                               [[np.pi / 2] * 3], atol=1e-15)
    # reversed faces are folded: every angle negative
    assert np.all(spherical_corner_angles(V, F[:, ::-1]) < 0)


def test_identity_map_of_the_unit_icosphere_measures():
    V, F = icosphere(2)
    d = sphere_distortion_summary(V, F, V)
    assert d["flipped_faces"] == 0 and d["max_radius_error"] < 1e-15
    assert d["image_area"] == pytest.approx(4 * np.pi, rel=1e-12)
    # flat surface triangles against their geodesic caps: small but not zero
    assert 0 < d["face_area_distortion"] < 0.01 and 0 < d["total_area_distortion_eq28"] < 0.01
    assert d["energy_ratio"] >= 1.0 and d["energy_ratio"] == pytest.approx(1.0, abs=1e-4)
    # the angle measure is |flat corner − geodesic corner|, the geodesic corners exceed by E/3
    ang = sphere_angular_distortion(V, F, V)
    np.testing.assert_allclose(
        ang, np.degrees(np.abs(corner_angles(V, F) - spherical_corner_angles(V, F))))
    assert d["angular_distortion_max_deg"] == pytest.approx(ang.max())
    R = sphere_local_area_ratios(V, F, V)
    assert R.shape == (len(V),) and np.all(np.abs(R - 1) < 0.01)
    # a scaled surface changes nothing (ratios of areas)
    assert sphere_distortion_summary(3 * V, F, V)["face_area_distortion"] == \
        pytest.approx(d["face_area_distortion"], rel=1e-12)
    # a reflected map folds every face
    assert sphere_distortion_summary(V, F, V * [1, 1, -1])["flipped_faces"] == len(F)


def test_closed_mesh_decimates_into_a_closed_outward_genus_zero_mesh():
    from pipeline.geometry.repair import RepairOptions
    from pipeline.geometry.topology import boundary_edges, euler_characteristic

    V, F = ellipsoid(4)
    r = repair_mesh(V, F, options=RepairOptions(decimate_to_faces=1000))
    assert r.closed and r.report["decimated_from_faces"] == len(F)
    assert 900 <= r.report["decimated_to_faces"] == len(r.F) <= 1100
    assert len(boundary_edges(r.F)) == 0 and euler_characteristic(r.F, len(r.V)) == 2
    assert sphere.signed_volume(r.V, r.F) > 0


def test_domain_resolution_and_its_messages():
    assert resolve_domain("auto", True) == "sphere" and resolve_domain("auto", False) == "disk"
    assert resolve_domain("sphere", True) == "sphere" and resolve_domain("disk", False) == "disk"
    with pytest.raises(UserError, match=r"is 'disk' but the mesh is closed.*--domain sphere"):
        resolve_domain("disk", True)
    with pytest.raises(UserError, match=r"--no-weld.*welding 3 vertices"):
        resolve_domain("disk", True, welded=3)
    with pytest.raises(UserError, match=r"is 'sphere' but the mesh has a boundary.*--domain "
                                        r"disk"):
        resolve_domain("sphere", False)


def test_auto_mode_is_a_few_paper_steps_on_the_disk_and_on_the_sphere():
    auto = SEMOptions(mode="auto", max_iter=None)
    assert auto.for_domain("disk").mode == "paper"
    assert auto.for_domain("disk").iterations() == REMESH_DISK_STEPS == 2
    assert auto.for_domain("disk").free_iter is None
    assert SEMOptions(mode="auto", max_iter=7).for_domain("disk").iterations() == 7   # asked
    sphere_auto = auto.for_domain("sphere")
    assert sphere_auto.mode == "paper"
    assert sphere_auto.iterations() == REMESH_SPHERE_STEPS == 2
    assert sphere_auto.free_iter == REMESH_SPHERE_FREE_STEPS == 3
    assert sphere_options(sphere_auto) == \
        {"solver": "auto", "method": "hemisphere", "max_iter": 2, "gradient_iter": 0,
         "cycles": 1, "free_iter": 3}
    asked = SEMOptions(mode="auto", max_iter=7, free_iter=0).for_domain("sphere")
    assert (asked.iterations(), asked.free_iter) == (7, 0)
    assert SEMOptions(mode="paper").for_domain("sphere").mode == "paper"   # asked: kept
    assert SEMOptions(mode="paper").for_domain("sphere").free_iter is None
    assert SEMOptions(mode="converged").for_domain("sphere").mode == "converged"
    assert SEMOptions().for_domain("disk").mode == "converged"


def test_auto_sphere_map_is_a_bijection_of_a_mesh_with_long_spikes():
    """The remesh's sphere map (``mode: auto``) of a closed mesh whose Tutte start crowds six
    spikes into tiny areas: every spherical triangle positively oriented and their areas
    summing to 4π (a covering of degree 1: one preimage per point, which the remesh's point
    location needs), and much less area distortion than the start."""
    V, F = icosphere(4)
    D = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]])
    theta = np.arccos(np.clip(V @ D.T, -1, 1))
    V = V * (1 + 3.0 * np.exp(-(theta / 0.3) ** 2).sum(axis=1))[:, None]
    p = parameterize_stage(repair_mesh(V, F), SEMOptions(mode="auto"))
    assert p.options.mode == "paper" and p.options.free_iter == REMESH_SPHERE_FREE_STEPS
    S, F = p.sphere, p.mesh.F
    assert np.all(sphere.triple_products(S, F) > 0)
    assert sphere.spherical_triangle_areas(S, F).sum() == pytest.approx(4 * np.pi, rel=1e-9)
    assert p.metrics["status"] == "ok" and p.flipped_faces == 0
    measures = p.sem.measures
    assert measures["face_area_distortion"] < 0.1 * p.sem.start["face_area_distortion"]


def test_sphere_options_map_the_section():
    assert sphere_options(SEMOptions()) == {"solver": "auto"}
    assert sphere_options(SEMOptions(mode="paper")) == \
        {"solver": "auto", "method": "hemisphere", "max_iter": 10, "gradient_iter": 0,
         "cycles": 1}
    assert sphere_options(SEMOptions(max_iter=7, tol=1e-4, solver="scipy")) == \
        {"solver": "scipy", "newton_iter": 7, "tol": 1e-4}
    assert sphere_options(SEMOptions(free_iter=4)) == {"solver": "auto", "free_iter": 4}


def test_folded_map_writes_its_diagnosis_but_no_map(tmp_path):
    """A map with folds: metrics.json (status failed) and report.html, no npz/OBJ, and
    ParameterizationFailed (exit 1), as for the disk."""
    V, F = ellipsoid(1)
    mesh = repair_mesh(V, F)
    S = V / np.linalg.norm(V, axis=1, keepdims=True)
    S[0] = -S[0]                                    # one vertex thrown across the sphere
    measures = sphere.sphere_measures(V, F, S)
    result = sphere.SphereResult(S=S, F=mesh.F, start={}, measures=measures, iterations=3,
                                 status="max_iter", history=[{"iteration": 0,
                                                              "energy_ratio": 2.0,
                                                              "folded_faces": 5,
                                                              "seconds": 0.1}],
                                 timings={"sem": 0.1})
    dist = sphere_distortion_summary(mesh.V, mesh.F, S)
    p = Parameterization(mesh, None, result, SEMOptions(),
                         {"status": "failed", "domain": "sphere", "mesh": {}, "distortion": dist,
                          "history": result.history, "seconds": {"sem": 0.1}}, sphere=S)
    assert p.domain == "sphere" and p.flipped_faces == measures["folded_faces"] > 0
    assert not p.ok
    with pytest.raises(ParameterizationFailed, match="folded faces remain"):
        write_parameterization(p, tmp_path / "out")
    names = sorted(f.name for f in (tmp_path / "out").iterdir())
    assert "metrics.json" in names and "report.html" in names and "convergence.png" in names
    assert not {"parameterization.npz", "parameterized.obj", "sphere.obj"} & set(names)
    assert json.loads((tmp_path / "out" / "metrics.json").read_text())["status"] == "failed"


# ------------------------------------------------------------------ the CLI, constructed meshes

@pytest.fixture(scope="module")
def ellipsoid_file(tmp_path_factory):
    V, F = ellipsoid(3)
    return write_obj(tmp_path_factory.mktemp("closed") / "ellipsoid.obj", V, F)


def test_inward_closed_mesh_is_flipped_reported_and_mapped(tmp_path):
    V, F = ellipsoid(2)
    path = write_obj(tmp_path / "inward.obj", V, F[:, ::-1])
    code, out, err = cli("parameterize", path, "-o", tmp_path / "o", "--mode", "paper",
                         "--no-figures")
    assert code == 0, err
    assert "reversed all 320 faces" in err and "outward" in err
    z = np.load(tmp_path / "o" / "parameterization.npz")
    assert [tuple(np.roll(f, -int(np.argmin(f)))) for f in z["faces"]] == \
        [tuple(np.roll(f, -int(np.argmin(f)))) for f in F]      # outward again, same turn
    assert sphere.folded_faces(z["sphere"], z["faces"]) == 0
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["input"]["repair"]["faces_flipped_outward"] == 320
    assert m["input"]["repair"]["closed"] is True and m["mesh"]["closed"] is True


def test_domain_mismatch_is_one_line(tmp_path, ellipsoid_file, small_face):
    code, _, err = cli("parameterize", ellipsoid_file, "-o", tmp_path / "a", "--domain", "disk")
    line = error_line(err)
    assert code == 2 and "'disk' but the mesh is closed" in line and "--domain sphere" in line
    code, _, err = cli("parameterize", small_face[0], "-o", tmp_path / "b", "--domain", "sphere")
    line = error_line(err)
    assert code == 2 and "'sphere' but the mesh has a boundary" in line
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_closed_mesh_remeshes_through_the_cli_and_pairs_only_with_closed(tmp_path,
                                                                       ellipsoid_file,
                                                                       small_face):
    code, _, err = cli("remesh", ellipsoid_file, "-o", tmp_path / "r", "--vertices", "300",
                       "--no-compare", "--no-report")
    assert code == 0, err
    out = read_mesh(tmp_path / "r" / "remeshed.obj")
    n, m = len(out.V), out.n_faces
    assert abs(n - 300) <= 6 and n - m // 2 == 2            # closed: E = 3m/2, χ = n − m/2
    rm = json.loads((tmp_path / "r" / "remesh_metrics.json").read_text())
    assert rm["parameterization"]["mode"] == "paper"   # --mode auto on the sphere
    assert rm["parameterization"]["iterations"] <= REMESH_SPHERE_STEPS
    code, _, err = cli("remesh", small_face[0], "-o", tmp_path / "d", "--vertices", "300",
                       "--no-compare", "--no-report")
    assert code == 0, err
    rm = json.loads((tmp_path / "d" / "remesh_metrics.json").read_text())
    assert rm["parameterization"]["mode"] == "paper"       # ... and on the disk
    lm, face_lm = tmp_path / "lm.txt", tmp_path / "face_lm.txt"
    lm.write_text("1\n2\n3\n")
    face_lm.write_text("\n".join(str(int(i)) for i in list(small_face[1].landmarks.values())[:3]) + "\n")
    code, _, err = cli("register", ellipsoid_file, small_face[0], "--source-landmarks", lm,
                       "--target-landmarks", face_lm, "-o", tmp_path / "g")
    assert code == 2
    assert "source is closed (sphere) but target is open (disk)" in error_line(err, "landmarks:")


def test_genus_one_is_refused_naming_the_genus(tmp_path):
    path = write_obj(tmp_path / "torus.obj", *torus())
    code, _, err = cli("parameterize", path, "-o", tmp_path / "o")
    line = error_line(err)
    assert code == 2 and "is closed with genus 1" in line and "cut its handles open" in line


# ---------------------------------------------------------------- the CLI, shared closed meshes

@pytest.fixture(scope="module")
def closed_runs(tmp_path_factory):
    """Every genus-0 mesh of ``closed/`` through ``parameterize --mode paper --no-figures``."""
    root = tmp_path_factory.mktemp("closed_runs")
    runs = {}
    for name in GENUS_ZERO:
        path = require_data("closed", f"{name}.obj")
        runs[name] = (root / name, cli("parameterize", path, "-o", root / name, "--mode",
                                       "paper", "--no-figures"))
    return runs


@pytest.mark.parametrize("name", GENUS_ZERO)
def test_closed_mesh_maps_to_the_sphere_without_folds(closed_runs, name):
    out, (code, stdout, err) = closed_runs[name]
    assert code == 0, err
    assert "on the sphere" in stdout and "folded faces = 0" in stdout
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == \
        ["metrics.json", "parameterization.npz", "parameterized.obj", "report.html", "sphere.obj"]
    z = np.load(out / "parameterization.npz")
    assert sorted(z.files) == NPZ_KEYS
    V, F, S, src = z["vertices"], z["faces"], z["sphere"], z["source_index"]
    n = len(V)
    assert V.shape == (n, 3) and F.shape[1] == 3 and S.shape == (n, 3) and src.shape == (n,)
    np.testing.assert_allclose(np.linalg.norm(S, axis=1), 1.0, atol=1e-12)
    assert np.all(sphere.triple_products(S, F) > 0)          # every triangle positive
    m = json.loads((out / "metrics.json").read_text())
    assert m["domain"] == "sphere" and m["status"] == "ok"
    d = m["distortion"]
    assert d["flipped_faces"] == 0
    A = face_double_areas(V, F)
    a = sphere.spherical_triangle_areas(S, F)
    face = float(np.abs(A / A.sum() - a / a.sum()).sum())
    assert face == pytest.approx(d["face_area_distortion"], rel=1e-9)
    assert d["image_area"] == pytest.approx(4 * np.pi, rel=1e-9)
    assert d["face_area_distortion"] <= 0.05
