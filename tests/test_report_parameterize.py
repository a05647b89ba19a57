"""Figures of a disk parameterization (pipeline/report/parameterize.py): PNG files of the right
pixel size, written atomically (no temp files left), no figures left open, robust to odd input."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from pipeline.geometry.metrics import angular_distortion, local_area_ratios  # noqa: E402
from pipeline.geometry.sem import SEMOptions, stretch_energy_minimization  # noqa: E402
from pipeline.sample import make_face  # noqa: E402
from pipeline.report import parameterize as figures  # noqa: E402


def _boundary_loop(F, V):
    from pipeline.geometry.topology import boundary_loops
    return boundary_loops(F, V)[0]


@pytest.fixture(scope="module")
def mapped():
    s = make_face(2000)
    V, F = np.asarray(s.V, dtype=float), np.asarray(s.F)
    res = stretch_energy_minimization(V, F, _boundary_loop(F, V),
                                      SEMOptions(mode="converged", max_iter=60))
    assert res.flipped_faces == 0
    return {"V": V, "F": F, "uv": res.uv, "history": res.history,
            "R": local_area_ratios(V, F, res.uv), "angles": angular_distortion(V, F, res.uv)}


def _check_png(path, name):
    """Non-empty PNG of the size FIGURE_SIZES[name] × DPI, alone in its folder, no open figure."""
    assert path.is_file() and path.stat().st_size > 1000
    img = mpimg.imread(path)
    w, h = figures.FIGURE_SIZES[name]
    assert img.shape[:2] == (round(h * figures.DPI), round(w * figures.DPI))
    assert img.std() > 0.01                                   # not a blank canvas
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]   # no temp file left
    assert plt.get_fignums() == []


def test_disk_area_ratio(mapped, tmp_path):
    out = tmp_path / "a" / "b" / "disk.png"                  # parents are created
    got = figures.plot_disk_area_ratio(mapped["uv"], mapped["F"], mapped["R"], out,
                                       title="synthetic face")
    assert got == out
    _check_png(out, "disk_area_ratio")


def test_disk_area_ratio_small_mesh_with_edges_and_bad_ratios(tmp_path):
    # a fan of 12 triangles (edges drawn) with an infinite and an undefined ratio
    t = np.linspace(0, 2 * np.pi, 13)[:-1]
    uv = np.vstack([[0, 0], np.column_stack([np.cos(t), np.sin(t)])])
    F = np.array([[0, 1 + i, 1 + (i + 1) % 12] for i in range(12)])
    R = np.ones(13) + np.linspace(-0.05, 0.05, 13)
    R[3], R[5] = np.inf, np.nan
    out = figures.plot_disk_area_ratio(uv, F, R, tmp_path / "fan.png")
    _check_png(out, "disk_area_ratio")


def test_area_ratio_histogram(mapped, tmp_path):
    out = figures.plot_area_ratio_histogram(mapped["R"], tmp_path / "hist.png", title="face")
    _check_png(out, "area_ratio_histogram")


def test_area_ratio_histogram_constant_and_nonfinite(tmp_path):
    R = np.ones(100)
    R[0] = np.inf
    out = figures.plot_area_ratio_histogram(R, tmp_path / "hist.png")
    _check_png(out, "area_ratio_histogram")


def test_angle_histogram(mapped, tmp_path):
    out = figures.plot_angle_histogram(mapped["angles"], tmp_path / "angles.png")
    _check_png(out, "angle_histogram")


def test_convergence(mapped, tmp_path):
    phases = {h["phase"] for h in mapped["history"]}
    assert {"harmonic", "sem"} <= phases
    out = figures.plot_convergence(mapped["history"], tmp_path / "conv.png", title="face")
    _check_png(out, "convergence")


@pytest.mark.parametrize("case", ["flips", "paper", "single", "empty"])
def test_convergence_odd_histories(mapped, tmp_path, case):
    hist = [dict(h) for h in mapped["history"]]
    if case == "flips":
        hist[2]["flipped_faces"] = 3
        hist[1]["energy_ratio"] = 1.0                          # ratio − 1 = 0 on a log axis
    elif case == "paper":
        hist = [h for h in hist if h["phase"] != "gradient"][:11]
    elif case == "single":
        hist = hist[:1]
    else:
        hist = []
    out = figures.plot_convergence(hist, tmp_path / "conv.png")
    _check_png(out, "convergence")


def test_surface_and_disk(mapped, tmp_path):
    out = figures.plot_surface_and_disk(mapped["V"], mapped["F"], mapped["uv"], mapped["R"],
                                        tmp_path / "both.png", title="face")
    _check_png(out, "surface_and_disk")


def test_surface_and_disk_other_values(mapped, tmp_path):
    out = figures.plot_surface_and_disk(mapped["V"], mapped["F"], mapped["uv"],
                                        mapped["V"][:, 2], tmp_path / "both.png",
                                        value_label="depth z (cm)")
    _check_png(out, "surface_and_disk")


def test_overwrite_keeps_single_file(mapped, tmp_path):
    out = tmp_path / "hist.png"
    out.write_bytes(b"old")
    figures.plot_area_ratio_histogram(mapped["R"], out)
    figures.plot_area_ratio_histogram(mapped["R"], out)
    _check_png(out, "area_ratio_histogram")


def test_failed_save_leaves_nothing(mapped, tmp_path, monkeypatch):
    def boom(self, *args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(Figure, "savefig", boom)
    with pytest.raises(RuntimeError):
        figures.plot_area_ratio_histogram(mapped["R"], tmp_path / "hist.png")
    assert list(tmp_path.iterdir()) == []
    assert plt.get_fignums() == []


def test_robust_colour_limit_ignores_outliers():
    rng = np.random.default_rng(0)
    R = 1 + 0.002 * rng.standard_normal(10_000)
    R[:50] = 3.0                                               # 0.5 % wild outliers
    limit = figures.log2_ratio_limit(R)
    assert 0.002 < 2 ** limit - 1 < 0.02
    assert figures.log2_ratio_limit(np.ones(10)) == figures.MIN_LOG2_LIMIT
    assert figures.log2_ratio_limit(np.array([np.inf, np.nan])) == 1.0


def test_tick_labels_are_short_and_exact():
    assert figures._tick_labels([0.99, 1.0, 1.01]) == ["0.99", "1.00", "1.01"]
    assert figures._tick_labels([0.9975, 1.0, 1.0025]) == ["0.9975", "1.0000", "1.0025"]
