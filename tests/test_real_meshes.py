"""Acceptance on the shared real meshes: bijective maps everywhere, the issue's distortion bounds,
and the fast paths (MKL PARDISO, CHOLMOD) equal to the SciPy path.

Converged mode runs with an iteration cap here to keep the suite to a few minutes; the default
(tol-based) run goes further — its figures are in the README and benchmarks.
"""

from __future__ import annotations

import os
from functools import lru_cache

import numpy as np
import pytest
from conftest import DATA_DIR, require_data

from pipeline.geometry.metrics import distortion_summary
from pipeline.geometry.repair import RepairOptions
from pipeline.geometry.sem import SEMOptions, stretch_energy_minimization
from pipeline.geometry.solvers import cholmod_available, pardiso_available
from pipeline.stages.load import load_stage

MESHES = ["c3d_alligator", "choi_chinese_lion", "choi_hand", "choi_human_brain",
          "choi_human_face", "gpp_bunny", "gpp_face", "igl_camel_b", "igl_camelhead", "igl_lion"]
ICT = ["A_neutral", "A_smile", "B_neutral", "B_smile_jawopen"]

# Face-based total area distortion reached by a patched public MATLAB SEM after 200 iterations
# (the bounds), and the cap that reaches them here with margin.
BOUNDS = {"choi_human_face": (0.0091, 300), "igl_camelhead": (0.021, 300),
          "choi_hand": (0.028, 250), "igl_lion": (0.034, 300)}


@lru_cache(maxsize=None)
def _mesh(relpath: str, close_holes: bool = False):
    return load_stage(DATA_DIR / relpath, RepairOptions(close_holes=close_holes)).mesh


@lru_cache(maxsize=None)
def _converged(relpath: str, close_holes: bool, max_iter: int):
    m = _mesh(relpath, close_holes)
    r = stretch_energy_minimization(m.V, m.F, m.boundary, SEMOptions(max_iter=max_iter))
    return m, r


def _cap(name: str) -> int:
    return BOUNDS.get(name, (None, 150))[1]


@pytest.mark.parametrize("name", MESHES)
def test_every_shared_mesh_gets_a_bijective_map(name):
    require_data("meshes", f"{name}.obj")
    m, r = _converged(f"meshes/{name}.obj", False, _cap(name))
    summary = distortion_summary(m.V, m.F, r.uv)
    assert r.flipped_faces == 0 and summary["flipped_faces"] == 0
    np.testing.assert_allclose(np.hypot(*r.uv[m.boundary].T), 1.0, atol=1e-12)
    # every accepted map along the way was fold-free too
    assert all(h["flipped_faces"] == 0 for h in r.history)
    # far better than the harmonic start
    assert summary["face_area_distortion"] < 0.25 * r.history[0]["face_area_distortion"]


@pytest.mark.parametrize("name, kind", [(n, k) for n in ICT for k in ("disk", "holes")]
                         + [("canonical", "disk"), ("canonical", "holes")])
def test_every_face_gets_a_bijective_map(name, kind):
    folder = "mediapipe" if name == "canonical" else "ict"
    prefix = "mediapipe" if name == "canonical" else "ict"
    rel = f"faces/{folder}/{prefix}_{name}_{kind}.obj"
    require_data(rel)
    m, r = _converged(rel, kind == "holes", 150)
    assert r.flipped_faces == 0
    assert distortion_summary(m.V, m.F, r.uv)["flipped_faces"] == 0
    if kind == "holes" and folder == "ict":
        assert (m.source_index == -1).sum() == 3       # eye, eye, mouth centres


@pytest.mark.parametrize("name", list(BOUNDS))
def test_converged_mode_beats_the_public_matlab_sem(name):
    require_data("meshes", f"{name}.obj")
    bound, cap = BOUNDS[name]
    m, r = _converged(f"meshes/{name}.obj", False, cap)
    d = distortion_summary(m.V, m.F, r.uv)
    assert d["flipped_faces"] == 0
    assert d["face_area_distortion"] <= bound, d["face_area_distortion"]
    assert abs(d["local_area_ratio_mean"] - 1) < 2e-3


def test_paper_mode_on_the_human_face_reaches_the_papers_accuracy():
    require_data("meshes", "choi_human_face.obj")
    m = _mesh("meshes/choi_human_face.obj")
    r = stretch_energy_minimization(m.V, m.F, m.boundary, SEMOptions(mode="paper"))
    d = distortion_summary(m.V, m.F, r.uv)
    assert r.iterations == 10 and d["flipped_faces"] == 0
    assert d["total_area_distortion_eq28"] <= 0.0045


@lru_cache(maxsize=None)
def _loop_subdivided(name: str):
    """One Loop subdivision (every face → 4, vertices smoothed) of a shared mesh: a finer mesh
    of the same shape, where plain SEM passes through folded maps."""
    import trimesh

    from pipeline.geometry.topology import boundary_loops

    m = _mesh(f"meshes/{name}.obj")
    V, F = trimesh.remesh.subdivide_loop(m.V, m.F, iterations=1)
    return V, F, boundary_loops(F, V)[0]


@pytest.mark.parametrize("name", MESHES + ["choi_human_face×4", "igl_camelhead×4"])
def test_paper_mode_runs_its_ten_iterations_without_a_fold(name):
    """Paper mode (Algorithm 1, damped where it would stop early) on every shared mesh and on
    Loop subdivisions: all 10 iterations, no flipped face, E_S non-increasing (Remark 3), and
    D(f) (eq. 28) at most 1.5 × what 10 converged-mode iterations reach."""
    base = name.removesuffix("×4")
    require_data("meshes", f"{base}.obj")
    if name.endswith("×4"):
        V, F, b = _loop_subdivided(base)
    else:
        m = _mesh(f"meshes/{name}.obj")
        V, F, b = m.V, m.F, m.boundary
    paper = stretch_energy_minimization(V, F, b, SEMOptions(mode="paper"))
    # converged mode's first 10 steps without Gauss–Newton: plain SEM steps (phase A), the
    # schedule this bound was set against (with Gauss–Newton from step ~8 it is far lower)
    conv = stretch_energy_minimization(V, F, b, SEMOptions(mode="converged", max_iter=10,
                                                           descent="gradient"))
    d = distortion_summary(V, F, paper.uv)
    assert paper.flipped_faces == 0 and d["flipped_faces"] == 0
    assert paper.status == "max_iter" and paper.iterations == 10, paper.stop_reason
    assert sum(paper.steps.values()) == paper.iterations and paper.stop_reason
    E = [h["stretch_energy"] for h in paper.history]
    assert all(b_ <= a_ for a_, b_ in zip(E, E[1:]))
    d_conv = distortion_summary(V, F, conv.uv)["total_area_distortion_eq28"]
    assert d["total_area_distortion_eq28"] <= 1.5 * d_conv, (d["total_area_distortion_eq28"],
                                                             d_conv)


def _need(kind):
    if not {"cholmod": cholmod_available, "pardiso": pardiso_available}[kind]():
        if os.environ.get("CI") == "true":
            pytest.fail(f"solver {kind} is not installed on CI; .ci/run installs it")
        pytest.skip(f"solver {kind} not installed")


@pytest.mark.parametrize("fast", ["pardiso", "cholmod"])
@pytest.mark.parametrize("name, options", [
    ("choi_human_face", dict(mode="paper")),
    ("choi_hand", dict(mode="paper")),
    ("gpp_face", dict(mode="paper")),
    ("igl_camel_b", dict(mode="paper")),
    ("igl_lion", dict(mode="converged", max_iter=40)),
])
def test_fast_path_equals_scipy_path(name, options, fast):
    """PARDISO, CHOLMOD (with PCG on old factors above 50k unknowns) and SuperLU give the same
    maps: same iterations, same stop, coordinates equal to 1e-9."""
    _need(fast)
    require_data("meshes", f"{name}.obj")
    m = _mesh(f"meshes/{name}.obj")
    maps = {}
    for solver in (fast, "scipy"):
        r = stretch_energy_minimization(m.V, m.F, m.boundary, SEMOptions(solver=solver, **options))
        assert r.solver == solver
        maps[solver] = r
    a, b = maps[fast], maps["scipy"]
    assert a.iterations == b.iterations and a.status == b.status
    assert np.abs(a.uv - b.uv).max() <= 1e-9 * np.abs(b.uv).max()
