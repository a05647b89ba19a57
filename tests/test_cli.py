"""The command line's contracts (shared/docs/DESIGN.md): files written, exit codes, one-line errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO, run_cli
from pipeline.cli import main
from pipeline.io.meshio import write_obj



def assert_one_line_error(code, err, *words):
    assert code == 2, err
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    assert "Traceback" not in err
    for w in words:
        assert w.lower() in lines[0].lower(), lines[0]


def read_obj_vt(path):
    v, vt, f = [], [], []
    for line in Path(path).read_text().splitlines():
        if line.startswith("v "):
            v.append(line)
        elif line.startswith("vt "):
            vt.append([float(x) for x in line.split()[1:3]])
        elif line.startswith("f "):
            f.append([tuple(int(i) for i in tok.split("/")) for tok in line.split()[1:]])
    return v, np.array(vt), f


def test_parameterize_writes_the_contract_files(small_face, tmp_path):
    path, s = small_face
    code, out, err = run_cli("parameterize", path, "-o", tmp_path / "out", "--no-figures")
    assert code == 0, err
    out_dir = tmp_path / "out"
    npz = np.load(out_dir / "parameterization.npz")
    assert set(npz.files) == {"vertices", "faces", "uv", "boundary", "source_index"}
    np.testing.assert_array_equal(npz["vertices"], s.V)   # nothing to repair: same vertices
    np.testing.assert_array_equal(npz["faces"], s.F)
    np.testing.assert_array_equal(npz["source_index"], np.arange(len(s.V)))
    uv = npz["uv"]
    assert uv.shape == (len(s.V), 2)
    np.testing.assert_allclose(np.abs(uv[npz["boundary"]] @ [1, 1j]), 1.0, atol=1e-12)
    v, vt, f = read_obj_vt(out_dir / "parameterized.obj")
    assert len(v) == len(vt) == len(s.V)                   # one vt per vertex
    np.testing.assert_allclose(vt, uv, atol=1e-8)
    assert all(a == b for face in f for a, b in face)      # f i/i: vt index = vertex index
    m = json.loads((out_dir / "metrics.json").read_text())
    assert m["status"] == "ok" and m["distortion"]["flipped_faces"] == 0
    assert m["history"][0]["phase"] == "harmonic"
    assert not [p for p in out_dir.iterdir() if p.name.startswith(".partial")]


def test_run_sample_config_writes_manifest_and_figures(tmp_path):
    cfg = tmp_path / "sample.yaml"
    cfg.write_text("run: {name: s}\ninput: {sample: {vertices: 800}}\n"
                   "parameterize: {mode: paper}\n")
    code, out, err = run_cli("run", cfg, "--out", tmp_path / "o")
    assert code == 0, err
    run = tmp_path / "o" / "s"
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["config"]["parameterize"]["mode"] == "paper"
    for name in ("parameterization.npz", "parameterized.obj", "metrics.json",
                 "disk_area_ratio.png", "area_ratio_histogram.png", "convergence.png",
                 "angle_histogram.png", "surface_and_disk.png"):
        assert (run / "parameterize" / name).stat().st_size > 0, name
    landmarks = json.loads((run / "input" / "sample_face_landmarks.json").read_text())
    assert len(landmarks["landmarks"]) == 16


def test_repo_configs_are_valid():
    from pipeline.config import Config
    import yaml
    for path in sorted((REPO / "configs").glob("*.yaml")):
        if path.name.startswith("experiment_"):     # expanded in tests/test_experiments.py
            continue
        Config.model_validate(yaml.safe_load(path.read_text()))


# ---- bad input: exit code 2 and one line -------------------------------------------------

def _closed_torus(path, k=6):
    """A closed genus-1 mesh: only genus-0 closed meshes have a (spherical) map."""
    u, v = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    a, b = 2 * np.pi * u.ravel() / k, 2 * np.pi * v.ravel() / k
    V = np.stack([(3 + np.cos(b)) * np.cos(a), (3 + np.cos(b)) * np.sin(a), np.sin(b)], axis=1)
    idx = np.arange(k * k).reshape(k, k)
    F = [[idx[i, j], idx[(i + 1) % k, j], idx[(i + 1) % k, (j + 1) % k]] for i in range(k)
         for j in range(k)]
    F += [[idx[i, j], idx[(i + 1) % k, (j + 1) % k], idx[i, (j + 1) % k]] for i in range(k)
          for j in range(k)]
    return write_obj(path, V, np.array(F))


def _grid(k=4):
    x, y = np.meshgrid(np.arange(k + 1.0), np.arange(k + 1.0))
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    idx = np.arange((k + 1) ** 2).reshape(k + 1, k + 1)
    F = []
    for i in range(k):
        for j in range(k):
            a, b, c, d = idx[i, j], idx[i, j + 1], idx[i + 1, j + 1], idx[i + 1, j]
            F += [[a, b, c], [a, c, d]]
    return V, np.array(F)


def _holed_grid(path):
    V, F = _grid(6)
    centre = {(3, 3)}
    keep = [t for t in F if not any((int(v) // 7, int(v) % 7) in centre for v in t)]
    return write_obj(path, V, np.array(keep))


def _nonmanifold(path):
    V, F = _grid(2)
    V = np.vstack([V, [[1.0, 0.5, 1.0]]])
    F = np.vstack([F, [[0, 4, 9]]])            # a third face on the interior edge 0–4
    return write_obj(path, V, F)


def _nan(path):
    V, F = _grid(2)
    V[3, 1] = np.nan
    return write_obj(path, V, F)


@pytest.mark.parametrize("make, words", [
    (_closed_torus, ["closed", "genus 1"]),
    (_holed_grid, ["boundary loops", "close"]),
    (_nan, ["nan"]),
])
def test_bad_meshes_exit_2_with_one_line(tmp_path, make, words):
    path = make(tmp_path / "bad.obj")
    code, out, err = run_cli("parameterize", path, "-o", tmp_path / "out")
    assert_one_line_error(code, err, *words)
    assert not (tmp_path / "out" / "parameterization.npz").exists()


def test_a_fin_on_an_edge_is_removed_and_reported_or_refused_on_request(tmp_path):
    path = _nonmanifold(tmp_path / "fin.obj")
    code, out, err = run_cli("parameterize", path, "-o", tmp_path / "out", "--no-figures")
    assert code == 0, err
    assert "removed 1 face at 1 non-manifold edge" in err
    with np.load(tmp_path / "out" / "parameterization.npz") as z:
        assert 9 not in z["source_index"] and len(z["faces"]) >= 8
    page = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    assert "repairs by the intake" in page and "removed 1 face at 1 non-manifold edge" in page
    code, out, err = run_cli("parameterize", path, "-o", tmp_path / "out2",
                             "--no-remove-nonmanifold-edge-faces")
    assert_one_line_error(code, err, "non-manifold edge", "remove_nonmanifold_edge_faces")
    assert not (tmp_path / "out2" / "parameterization.npz").exists()


def test_a_decimation_request_on_a_torus_names_its_genus(tmp_path):
    """With --decimate, a closed genus-1 mesh is refused for its genus (what the user must
    change), not for a decimation that could not keep genus 0."""
    path = _closed_torus(tmp_path / "torus.obj", k=12)
    code, out, err = run_cli("parameterize", path, "-o", tmp_path / "out", "--decimate", 100)
    assert_one_line_error(code, err, "closed", "genus 1")
    assert "decimat" not in err


def test_empty_file_and_unknown_format(tmp_path):
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    code, _, err = run_cli("parameterize", empty, "-o", tmp_path / "o")
    assert_one_line_error(code, err, "empty")
    odd = tmp_path / "mesh.xyz"
    odd.write_text("1 2 3\n")
    code, _, err = run_cli("parameterize", odd, "-o", tmp_path / "o")
    assert_one_line_error(code, err, ".xyz")


def test_close_holes_option_parameterizes_the_holed_grid(tmp_path):
    path = _holed_grid(tmp_path / "holed.obj")
    code, _, err = run_cli("parameterize", path, "-o", tmp_path / "o", "--close-holes",
                           "--no-figures")
    assert code == 0, err
    npz = np.load(tmp_path / "o" / "parameterization.npz")
    assert (npz["source_index"] == -1).sum() >= 1
    assert "closed" in err.lower() or "hole" in err.lower()   # the repair is reported


def test_remesh_of_the_holed_grid_keeps_the_hole(tmp_path):
    path = _holed_grid(tmp_path / "holed.obj")
    code, out, err = run_cli("remesh", path, "-o", tmp_path / "o", "--close-holes",
                             "--vertices", 300, "--no-compare", "--no-report")
    assert code == 0, err
    assert "one disk with 1 hole, as the input" in out and "covers" not in err
    metrics = json.loads((tmp_path / "o" / "remesh_metrics.json").read_text())
    assert metrics["methods"]["sem"]["facts"]["boundary_loops"] == 2


def test_remesh_of_the_holed_grid_warns_that_it_covers_the_hole(tmp_path):
    path = _holed_grid(tmp_path / "holed.obj")
    code, _, err = run_cli("remesh", path, "-o", tmp_path / "o", "--close-holes", "--vertices",
                           300, "--no-compare", "--no-report", "--cover-holes")
    assert code == 0, err
    warning = ("the remesh covers the 1 hole close_holes filled with fans to a new centre "
               "vertex: it has one boundary where the input had 2")
    assert f"remesh: warning: {warning}" in err
    metrics = json.loads((tmp_path / "o" / "remesh_metrics.json").read_text())
    assert any(w.startswith(warning) for w in metrics["warnings"])


@pytest.mark.parametrize("text, words", [
    ("input: {mesh: a.obj\n  bad: [", ["malformed yaml", "line"]),
    ("input: {sample: {vertices: 800}}\nparameterize: {max_iters: 3}\n",
     ["parameterize.max_iters", "unknown key", "max_iter"]),
    ("input: {sample: {vertices: 800}}\nparameterize: {max_iter: many}\n",
     ["parameterize.max_iter", "integer"]),
    ("input: {mesh: does_not_exist.obj}\n", ["input.mesh", "not found"]),
    ("input: {}\n", ["input", "exactly one"]),
    ("- just\n- a list\n", ["mapping"]),
    ("input: {sample: {vertices: 800}}\nparameterize: {mode: fast}\n", ["parameterize.mode"]),
    ("input: !!python/object/apply:os.system ['echo hi']\n", ["malformed yaml"]),
])
def test_bad_configs_exit_2_with_one_line(tmp_path, text, words):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    code, out, err = run_cli("run", cfg, "--out", tmp_path / "o")
    assert_one_line_error(code, err, *words)


def test_missing_config_and_bad_arguments(tmp_path, capsys):
    assert main(["run", str(tmp_path / "nope.yaml")]) == 2
    assert "not found" in capsys.readouterr().err
    assert main(["parameterize"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert main(["parameterize", "x.obj", "-o", str(tmp_path), "--solver", "magic"]) == 2


def _run_python(code: str):
    """Run ``code`` in a fresh interpreter with block-buffered output to pipes."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                          text=True, timeout=60, env=dict(env, PYTHONPATH=str(REPO)))
    return proc.returncode, proc.stdout, proc.stderr


def test_exit_now_flushes_runs_atexit_and_keeps_the_code(tmp_path):
    """The console command ends without the interpreter's teardown, but what a normal exit
    does for the user still happens: buffered output shown, atexit handlers run, the code."""
    marker = tmp_path / "atexit.txt"
    code, out, err = _run_python(
        "import atexit, sys\n"
        "from pipeline.cli import exit_now\n"
        f"atexit.register(lambda: open({str(marker)!r}, 'w').write('ran'))\n"
        "print('partial line, no newline', end='')\n"
        "print('to stderr', end='', file=sys.stderr)\n"
        "exit_now(5)\n"
        "print('never')\n")
    assert code == 5, err
    assert out == "partial line, no newline"
    assert err == "to stderr"
    assert marker.read_text() == "ran"


def test_exit_now_waits_for_running_threads(tmp_path):
    """With a Python thread still working, the exit is a normal one: the thread finishes."""
    marker = tmp_path / "thread.txt"
    code, _, err = _run_python(
        "import threading, time\n"
        "from pipeline.cli import exit_now\n"
        "def work():\n"
        "    time.sleep(0.3)\n"
        f"    open({str(marker)!r}, 'w').write('done')\n"
        "threading.Thread(target=work).start()\n"
        "exit_now(3)\n")
    assert code == 3, err
    assert marker.read_text() == "done"


def test_entry_under_cprofile_writes_the_profile(tmp_path):
    """``python -m cProfile -o F -m pipeline ...``: the profiler writes its results at the
    normal exit, which the command then takes (cProfile itself swallows the exit code)."""
    profile = tmp_path / "cli.prof"
    result = subprocess.run([sys.executable, "-m", "cProfile", "-o", str(profile), "-m",
                             "pipeline", "remesh", str(tmp_path / "missing.obj"), "-o",
                             str(tmp_path / "r"), "--vertices", "500"],
                            capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert "missing.obj' does not exist" in result.stderr
    assert profile.stat().st_size > 0


def test_module_entry_point_exit_codes(tmp_path):
    """``python -m pipeline``: 0 on success with its closing line on stdout, 2 with one line on
    a user mistake (through :func:`pipeline.cli.entry`)."""
    code, out, err = run_cli("sample", "-o", tmp_path / "s", "--vertices", 400)
    assert code == 0, err
    assert out.strip() and all(Path(p).exists() for p in out.split())
    code, _, err = run_cli("remesh", tmp_path / "missing.obj", "-o", tmp_path / "r",
                           "--vertices", 500)
    assert_one_line_error(code, err, "missing.obj")


def run_entry_on_a_missing_mesh(tmp_path, before: str, env=None):
    """``sem-pipeline remesh missing.obj`` through :func:`pipeline.cli.entry` in a fresh
    interpreter that first runs the code ``before`` (atexit hooks that print what to check):
    the finished process."""
    code = (before + "import sys\n"
            "sys.argv = ['sem-pipeline', 'remesh', 'missing.obj', '-o', 'out', '--vertices',"
            " '500']\n"
            "from pipeline.cli import entry\n"
            "entry()\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=60,
                          env=dict(os.environ if env is None else env, PYTHONPATH=str(REPO)))
    assert proc.returncode == 2, proc.stderr
    return proc


@pytest.mark.parametrize("given, expected", [(None, "1"), ("2", "2")])
def test_entry_runs_openblas_on_one_thread_unless_told(given, expected, tmp_path):
    """The console command starts NumPy with ``OPENBLAS_NUM_THREADS=1`` (its OpenBLAS workers
    would only spin), and keeps a value the user set."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    proc = run_entry_on_a_missing_mesh(
        tmp_path, "import atexit, os, sys\n"
                  "atexit.register(lambda: print(os.environ.get('OPENBLAS_NUM_THREADS'),"
                  " 'numpy' in sys.modules))\n", env)
    assert proc.stdout.split() == [expected, "True"]


def test_entry_freezes_what_the_imports_made(tmp_path):
    """The console command imports its modules with the collector paused and then freezes
    what they made (``gc.freeze``), so no later collection goes over those objects again;
    the collector is back on for the command's own work."""
    proc = run_entry_on_a_missing_mesh(
        tmp_path, "import atexit, gc\n"
                  "atexit.register(lambda: print(gc.isenabled(), gc.get_freeze_count()))\n")
    enabled, frozen = proc.stdout.split()
    assert enabled == "True"
    assert int(frozen) > 50_000           # NumPy, SciPy, pydantic and the stages' objects


def test_entry_leaves_the_deferred_numpy_modules_unrun(tmp_path):
    """The console command imports SciPy without running the NumPy submodules of
    ``DEFERRED_MODULES`` (SciPy only looks them up); each is a module on its package and in
    ``sys.modules``, and runs, whole, when first used."""
    proc = run_entry_on_a_missing_mesh(
        tmp_path, "import atexit, sys\n"
                  "def report():\n"
                  "    import numpy\n"
                  "    from pipeline.cli import DEFERRED_MODULES\n"
                  "    ran = [n for n in ('numpy.f2py.crackfortran',"
                  " 'numpy.testing._private.utils', 'numpy.polynomial.legendre')"
                  " if n in sys.modules]\n"
                  "    lazy = all(n in sys.modules for n in DEFERRED_MODULES)\n"
                  "    x = numpy.polynomial.legendre.leggauss(2)[0][1]\n"
                  "    print(ran, lazy, 'scipy.sparse' in sys.modules, round(x * x * 3, 9))\n"
                  "atexit.register(report)\n")
    assert proc.stdout.split() == ["[]", "True", "True", "1.0"]


def test_entry_leaves_scipy_spatial_transform_unrun_and_scipy_doc_parser_back(tmp_path):
    """The console command imports ``scipy.spatial`` (the remesh's Delaunay triangulation and
    KD-tree) without running ``scipy.spatial.transform`` (``DEFERRED_SUBMODULES``): a lazy
    module on its package that runs, whole, when first used; SciPy's docstring-writing
    decorators have their own parser back once the imports are done."""
    proc = run_entry_on_a_missing_mesh(
        tmp_path, "import atexit, sys\n"
                  "def report():\n"
                  "    import scipy.spatial\n"
                  "    from scipy._lib import _array_api, _docscrape, _util\n"
                  "    ran = 'scipy.spatial.transform._rotation' in sys.modules\n"
                  "    r = scipy.spatial.transform.Rotation.from_euler('z', 90, degrees=True)\n"
                  "    print(ran, round(float(r.as_matrix()[1, 0]), 9),\n"
                  "          _array_api.FunctionDoc is _docscrape.FunctionDoc"
                  " is _util.FunctionDoc)\n"
                  "atexit.register(report)\n")
    assert proc.stdout.split() == ["False", "1.0", "True"]


def test_entry_imports_with_scipys_parser_when_the_stand_in_fails(tmp_path):
    """If a SciPy asks the docstring stand-in for more than :class:`pipeline.cli._DocKept`
    answers (a decorator changed within a version it is used for), the command imports again
    with SciPy's own parser and runs as usual."""
    proc = run_entry_on_a_missing_mesh(
        tmp_path, "import atexit, sys\n"
                  "import pipeline.cli\n"
                  "def refuse(self, func, *args, **kwargs):\n"
                  "    raise TypeError('not as this stand-in knows it')\n"
                  "pipeline.cli._DocKept.__init__ = refuse\n"
                  "def report():\n"
                  "    from scipy._lib import _array_api, _docscrape\n"
                  "    import scipy.spatial\n"
                  "    print(_array_api.FunctionDoc is _docscrape.FunctionDoc,\n"
                  "          'scipy.spatial' in sys.modules, 'pipeline.runner' in sys.modules)\n"
                  "atexit.register(report)\n")
    assert "missing.obj" in proc.stderr
    assert proc.stdout.split() == ["True", "True", "True"]


def test_doc_kept_gives_back_the_docstring_as_scipys_decorators_read_it():
    """:class:`pipeline.cli._DocKept` answers SciPy's decorators' uses of ``FunctionDoc`` (a
    note appended to a section, the parameters read, the text less its first line) with the
    function's own docstring."""
    from pipeline.cli import _DocKept

    def f():
        """Add one.

        Notes
        -----
        None.
        """

    doc = _DocKept(f)
    doc["Notes"].append("a note")
    assert [p.name for p in doc["Parameters"]] == []
    assert str(doc).split("\n", 1)[1] == f.__doc__
    assert str(_DocKept(lambda: None)).split("\n", 1)[1] == ""


BEFORE_USE = "before = 'email.mime.nonmultipart' in sys.modules\n"   # what it imports


@pytest.mark.parametrize("function, steps, used, made", [
    ("defer_imports", BEFORE_USE + "import email.mime.text\n", "email.mime.text",
     ["email.mime.text"]),
    ("defer_submodules", "from email.mime import text\n" + BEFORE_USE, "text",
     ["email.mime.text", "email.no_such_module"])])
def test_deferred_modules_skip_imported_ones_and_run_on_first_use(tmp_path, function, steps,
                                                                 used, made):
    """:func:`pipeline.cli.defer_imports` (at once) and :func:`pipeline.cli.defer_submodules`
    (when the module is imported, by name, from its package) make only modules not yet
    imported lazy (the first also skips names that do not exist); a lazy module runs on first
    attribute access."""
    code = ("import sys, json\n"
            f"from pipeline.cli import {function}\n"
            f"made = {function}(['json', 'email.mime.text', 'email.no_such_module'])\n"
            + steps +
            f"after = {used}.MIMEText('x').get_payload()\n"
            "print(made == " + repr(made) + ", before, after)\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=60, env=dict(os.environ, PYTHONPATH=str(REPO)))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["True", "False", "x"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
@pytest.mark.parametrize("given, expected", [(None, "True"), ("2", "False")])
def test_keep_freed_memory_applies_unless_a_malloc_variable_is_set(given, expected):
    """The command's ``malloc`` settings go through glibc's ``mallopt``, and a ``MALLOC_*``
    variable the user set wins over them."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    if given is not None:
        env["MALLOC_ARENA_MAX"] = given
    code = "from pipeline.cli import keep_freed_memory\nprint(keep_freed_memory())\n"
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                          text=True, timeout=60, env=dict(env, PYTHONPATH=str(REPO)))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == expected
