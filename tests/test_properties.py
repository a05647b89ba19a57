"""Property-based tests (Hypothesis) of the command line on random small input.

Random small meshes (valid, degenerate, non-manifold, holed, flipped), random configs and random
landmark files: the CLI returns 0, 1 or 2 and never raises (a traceback); 2 is one ``error:``
line; 0 means a complete output folder whose map is bijective (every face positively oriented
on the disk, the boundary on the unit circle).
"""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pipeline.cli import main
from pipeline.geometry.metrics import signed_double_areas
from pipeline.io.outputs import MARKER

SETTINGS = settings(max_examples=25, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])


def grid(k: int, noise: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x, y = np.meshgrid(np.arange(k + 1.0), np.arange(k + 1.0))
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    V += noise[: len(V)]
    idx = np.arange((k + 1) ** 2).reshape(k + 1, k + 1)
    F = [[idx[i, j], idx[i, j + 1], idx[i + 1, j + 1]] for i in range(k) for j in range(k)]
    F += [[idx[i, j], idx[i + 1, j + 1], idx[i + 1, j]] for i in range(k) for j in range(k)]
    return V, np.array(F, dtype=np.int64)


@st.composite
def meshes(draw):
    """A small grid disk, then some of: faces dropped, duplicated, degenerate, flipped, a
    non-manifold fin, a second component, vertices collapsed, two boundary vertices made one
    (a bowtie where the rim touches itself), a global scale."""
    k = draw(st.integers(1, 5))
    noise = np.array(draw(st.lists(st.floats(-0.4, 0.4), min_size=108, max_size=108))
                     ).reshape(36, 3)
    V, F = grid(k, noise)
    ops = draw(st.lists(st.sampled_from(["drop", "dup", "degenerate", "flip", "fin", "island",
                                         "collapse", "pinch", "scale"]), max_size=3))
    for op in ops:
        i = draw(st.integers(0, len(F) - 1))
        if op == "drop" and len(F) > 1:
            F = np.delete(F, i, axis=0)
        elif op == "dup":
            F = np.vstack([F, F[i]])
        elif op == "degenerate":
            F = np.vstack([F, [[F[i, 0], F[i, 0], F[i, 1]]]])
        elif op == "flip":
            F[i] = F[i, ::-1]
        elif op == "fin":
            V = np.vstack([V, V[F[i, :2]].mean(axis=0) + [0, 0, 1]])
            F = np.vstack([F, [[F[i, 0], F[i, 1], len(V) - 1]]])
        elif op == "island":
            F = np.vstack([F, F + len(V)])
            V = np.vstack([V, V + [100, 0, 0]])
        elif op == "collapse":
            V[F[i, 1]] = V[F[i, 0]]
        elif op == "pinch":
            rim = np.flatnonzero(np.bincount(F.ravel(), minlength=len(V)) < 6)
            a, b = (int(rim[draw(st.integers(0, len(rim) - 1))]) for _ in range(2))
            F = np.where(F == b, a, F)
        elif op == "scale":
            V = V * draw(st.sampled_from([1e-9, 1e9, -1.0, 1e80]))
    return V, F


def write_obj_text(path: Path, V, F) -> None:
    path.write_text("".join(f"v {float(a)!r} {float(b)!r} {float(c)!r}\n" for a, b, c in V)
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F))


def call(argv, capsys) -> tuple[int, str]:
    code = main([str(a) for a in argv])          # an exception fails the test: a traceback
    _, err = capsys.readouterr()
    assert code in (0, 1, 2), (code, err)
    if code == 2:
        lines = [s for s in err.splitlines() if s.startswith("error:")]
        assert len(lines) == 1 and "Traceback" not in err, err
    return code, err


def assert_bijective(folder: Path) -> None:
    with np.load(folder / "parameterization.npz") as z:
        uv, F, b = z["uv"], z["faces"], z["boundary"]
    assert np.all(signed_double_areas(uv, F) > 0)
    np.testing.assert_allclose(np.hypot(uv[b, 0], uv[b, 1]), 1.0, atol=1e-9)


@SETTINGS
@given(mesh=meshes(), mode=st.sampled_from(["paper", "converged"]))
def test_random_meshes_exit_0_1_or_2_and_0_is_bijective(mesh, mode, capsys):
    V, F = mesh
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.obj"
        write_obj_text(path, V, F)
        out = Path(tmp) / "out"
        code, err = call(["parameterize", path, "-o", out, "--no-figures", "--mode", mode,
                          "--max-iter", "20"], capsys)
        if code == 0:
            assert (out / MARKER).is_file()
            assert_bijective(out)
        elif code == 2:
            assert not (out / "parameterization.npz").exists()


ODD = st.sampled_from([None, -1, 0, 1.5, math.nan, math.inf, "x", "", [], {}, True, 10**12])


@st.composite
def configs(draw):
    """A config of a small sample face with random (often invalid) values."""
    pick = lambda good: draw(st.one_of(st.sampled_from(good), ODD))   # noqa: E731
    data = {"input": {"sample": {"vertices": pick([300, 350])}},
            "parameterize": {"mode": pick(["paper"]), "max_iter": pick([0, 3, 5]),
                             "tol": pick([1e-3, 1e-7])},
            "report": {"figures": pick([False])}}
    if draw(st.booleans()):
        data["run"] = {"name": pick(["r", "a b", "x.y"]) if draw(st.booleans())
                       else draw(st.sampled_from(["../x", "/abs", "a/b", "..", ".", " r"]))}
    if draw(st.booleans()):
        data["remesh"] = {"vertices": pick([150, 200]), "compare": False, "report": False,
                          "improve": pick([False]), "distance_samples": 1000}
    if draw(st.booleans()):
        data["repair"] = {"weld_tolerance": pick([1e-9]), "close_holes": pick([False, True])}
    for section in draw(st.lists(st.sampled_from(list(data)), max_size=2)):
        data[section] = draw(st.sampled_from([None, [], "text", {"unknown_key": 1}]))
    return data


@SETTINGS
@given(data=configs())
def test_random_configs_exit_0_1_or_2(data, capsys):
    with tempfile.TemporaryDirectory() as tmp:
        cfg = Path(tmp) / "c.yaml"
        cfg.write_text(yaml.safe_dump(data, allow_unicode=True))
        out = Path(tmp) / "out"
        code, err = call(["run", cfg, "--out", out], capsys)
        runs = [p for p in out.iterdir() if p.is_dir()] if out.is_dir() else []
        if code == 0:
            assert len(runs) == 1 and (runs[0] / "manifest.json").is_file()
            assert (runs[0] / MARKER).is_file()
            assert_bijective(runs[0] / "parameterize")
        elif code == 2:
            assert runs == []
        assert not list(Path(tmp).rglob(".*.partial-*"))


LANDMARK = st.one_of(st.integers(-3, 60),
                     st.lists(st.one_of(st.floats(-10, 10), st.just(math.nan)), min_size=2,
                              max_size=4),
                     st.sampled_from([None, "7", True, 2.5, 1e9]))


@SETTINGS
@given(values=st.lists(LANDMARK, min_size=0, max_size=6),
       named=st.booleans(), names=st.lists(st.sampled_from("abcd"), min_size=6, max_size=6),
       fmt=st.sampled_from(["json", "csv"]))
def test_random_landmark_files_exit_0_1_or_2(values, named, names, fmt, capsys):
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        V, F = grid(6, np.zeros((49, 3)))
        V[:, 2] = 0.2 * np.sin(V[:, 0]) * np.cos(V[:, 1])
        write_obj_text(tmp / "s.obj", V, F)
        write_obj_text(tmp / "t.obj", V * [1.0, 1.1, 1.5], F)
        if fmt == "json":
            body = {n: v for n, v in zip(names, values)} if named else values
            text = json.dumps({"landmarks": body}, allow_nan=True)
        else:
            rows = [" ".join(map(str, v)) if isinstance(v, list) else str(v) for v in values]
            text = "\n".join(f"{n}, {r}" if named else r for n, r in zip(names, rows))
        lm = tmp / f"lm.{fmt}"
        lm.write_text(text)
        out = tmp / "out"
        code, _ = call(["register", tmp / "s.obj", tmp / "t.obj", "--source-landmarks", lm,
                        "-o", out, "--no-figures", "--mode", "paper", "--max-iter", "5"], capsys)
        if code == 0:
            with np.load(out / "registration.npz") as z:
                assert np.isfinite(z["mapped_points"]).all()
        elif code == 2:
            assert not out.exists() or not any(out.iterdir())
