"""Experiments: config → items, cached resumable runs, failures recorded, pool = Dask, summary.

Fast by design: tiny synthetic faces (400-800 vertices), mostly paper mode, no figures except
where an item must take a moment (the kill test).
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import REPO, require_data
from pipeline.cli import main
from pipeline.config import Config
from pipeline.errors import UserError
from pipeline.experiments.cache import FileHashes, item_hash
from pipeline.experiments.execute import run_experiment
from pipeline.experiments.spec import expand_experiment, load_experiment
from pipeline.io.meshio import write_obj

CONFIGS = REPO / "configs"
SAMPLE_IDS = [f"parameterize.mode={m}__input.sample.vertices={n}"
              for m in ("paper", "converged") for n in (400, 800)]
TIMING = ("seconds",)          # columns that hold wall times: differ from run to run


def read_summary(run_dir: Path) -> list[dict]:
    with open(run_dir / "summary.csv", newline="") as f:
        return list(csv.DictReader(f))


def untimed(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if not any(t in k for t in TIMING)} for r in rows]


def mtimes(run_dir: Path) -> dict:
    return {p.parent.name: p.stat().st_mtime_ns for p in run_dir.glob("*/item.json")}


def leftovers(root: Path) -> list[Path]:
    return [p for p in root.rglob("*") if p.name.startswith((".partial-", ".trash-"))]


@pytest.fixture(scope="module")
def pool_run(tmp_path_factory):
    """The sample experiment on a local pool of 2 processes (shared by several tests)."""
    out = tmp_path_factory.mktemp("pool")
    outcome = run_experiment(load_experiment(CONFIGS / "experiment_sample.yaml"), out,
                             workers=2, progress=False)
    return outcome, read_summary(outcome.run_dir)


# ------------------------------------------------------------------------------- expansion


def test_sample_config_expands_to_readable_unique_items():
    exp = load_experiment(CONFIGS / "experiment_sample.yaml")
    assert [i.id for i in exp.items] == SAMPLE_IDS
    item = exp.items[3]
    assert item.config.parameterize.mode == "converged"
    assert item.config.input.sample.vertices == 800
    assert item.params == {"parameterize.mode": "converged", "input.sample.vertices": 800}
    assert item.config.run.name == item.id
    assert exp.run_dir("x") == Path("x") / "experiment_sample"


def test_register_ict_config_expands_to_every_ordered_pair_and_set():
    require_data("faces", "ict", "ict_landmarks.json")
    exp = load_experiment(CONFIGS / "experiment_register_ict.yaml")
    assert len(exp.items) == 4 * 3 * 2
    ids = {i.id for i in exp.items}
    assert len(ids) == 24
    assert "A_neutral-to-B_smile_jawopen__register.landmark_set=ibug68" in ids
    assert "B_smile_jawopen-to-A_neutral__register.landmark_set=named" in ids
    for item in exp.items:
        r = item.config.register
        assert r.source != r.target and r.truth == r.target
        assert Path(r.source).is_absolute() and Path(r.source_landmarks).name == \
            "ict_landmarks.json"
        assert r.landmark_set in ("named", "ibug68")


def test_remesh_all_config_expands_to_every_mesh_at_two_densities():
    require_data("meshes")
    if "remesh" not in Config.model_fields:
        pytest.skip("the 'remesh' config section is not in the schema yet")
    exp = load_experiment(CONFIGS / "experiment_remesh_all.yaml")
    meshes = sorted(p.stem for p in require_data("meshes").glob("*.obj"))
    assert len(exp.items) == 2 * len(meshes)
    assert "choi_human_face__remesh.vertices=5000" in {i.id for i in exp.items}
    assert {i.config.remesh.vertices for i in exp.items} == {5000, 20000}


def test_pairs_and_faces_datasets_expand(tmp_path):
    for name in ("x_a_scan", "x_b_scan", "x_c_scan"):
        (tmp_path / f"{name}.obj").write_text("")
        (tmp_path / f"{name}.json").write_text("{}")
    pairs = expand_experiment({"dataset": {"pairs": [
        {"source": "x_a_scan.obj", "target": "x_b_scan.obj", "source_landmarks": "x_a_scan.json",
         "target_landmarks": "x_b_scan.json", "name": "ab"},
        {"source": "x_b_scan.obj", "target": "x_c_scan.obj", "source_landmarks": "lm.json"}]},
        "register": {"mobius": True}, "sweep": {"register.energy": ["harmonic"]}}, tmp_path)
    assert [i.id for i in pairs.items] == ["ab__register.energy=harmonic",
                                          "x_b_scan-to-x_c_scan__register.energy=harmonic"]
    r = pairs.items[1].config.register
    assert r.mobius and r.energy == "harmonic" and r.target_landmarks is None
    assert r.source_landmarks == str(tmp_path.resolve() / "lm.json")    # missing: run-time error
    faces = expand_experiment({"dataset": {"faces": {
        "meshes": "x_*_scan.obj", "landmarks": "{stem}.json"}}}, tmp_path)
    assert [i.id for i in faces.items] == ["a-to-b", "a-to-c", "b-to-a", "b-to-c", "c-to-a",
                                          "c-to-b"]
    r = faces.items[0].config.register
    assert Path(r.target_landmarks).name == "x_b_scan.json" and r.truth is None
    assert faces.items[0].params == {"source": "a", "target": "b"}


@pytest.mark.parametrize("data, words", [
    ({"sweeps": {}}, ["sweeps: unknown key", "did you mean 'sweep'"]),
    ({"sweep": {"parameterize.max_iters": [1, 2]}},
     ["item 'parameterize.max_iters=1'", "max_iters: unknown key", "'max_iter'"]),
    ({"sweep": {"parameterize.max_iter": [5, -1]}},
     ["item 'parameterize.max_iter=-1'", "parameterize.max_iter", "greater than or equal"]),
    ({"sweep": {"parameterize.mode": "paper"}}, ["sweep.parameterize.mode", "valid list"]),
    ({"sweep": {"run.name": ["a"]}}, ["run.name", "sweep a stage setting"]),
    ({"dataset": {"meshes": "nowhere/*.obj"}}, ["dataset.meshes", "matches no file"]),
    ({"dataset": {"meshes": "a.obj", "pairs": []}}, ["dataset", "exactly one of"]),
    ({"dataset": {"meshes": ["a.obj"]}, "sweep": {"input.sample.vertices": [400]}},
     ["sweep.input.sample.vertices", "dataset sets 'input'"]),
])
def test_bad_experiment_configs_are_one_line_errors(tmp_path, data, words):
    data = {"input": {"sample": {"vertices": 400}}, **data}
    if "dataset" in data:
        del data["input"]
    with pytest.raises(UserError) as exc:
        expand_experiment(data, tmp_path, "exp.yaml")
    message = str(exc.value)
    assert "\n" not in message and message.startswith("exp.yaml: ")
    for w in words:
        assert w in message, message


def test_cli_bad_experiment_config_exits_2_with_one_line(tmp_path):
    cfg = tmp_path / "exp.yaml"
    cfg.write_text("input: {sample: {vertices: 400}}\nsweep: {parameterize.mode: [papr]}\n")
    proc = subprocess.run([sys.executable, "-m", "pipeline", "experiment", str(cfg)],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(REPO)))
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert lines[0].startswith("error: ") and "parameterize.mode" in lines[0]
    assert "item 'parameterize.mode=papr'" in lines[0]
    assert not (tmp_path / "outputs").exists()


# ------------------------------------------------------------------------------- hashing


def test_content_hash_follows_file_bytes_and_settings_not_paths(tmp_path, synthetic_face):
    face = synthetic_face(400)
    a = write_obj(tmp_path / "a.obj", face.V, face.F)
    data = {"dataset": {"meshes": ["a.obj"]}}
    hashes = FileHashes(tmp_path / "h.json")
    item = expand_experiment(data, tmp_path).items[0]
    h1 = item_hash(item, tmp_path, hashes)
    assert hashes.reads == 1
    assert item_hash(item, tmp_path, hashes) == h1 and hashes.reads == 1   # cached
    hashes.save()
    assert FileHashes(tmp_path / "h.json").digest(a) == hashes.digest(a)

    moved = tmp_path / "elsewhere"
    moved.mkdir()
    (moved / "a.obj").write_bytes(a.read_bytes())
    item_moved = expand_experiment(data, moved).items[0]
    assert item_hash(item_moved, moved, hashes) == h1           # same bytes, same settings

    other = expand_experiment(dict(data, parameterize={"max_iter": 3}), tmp_path).items[0]
    assert item_hash(other, tmp_path, hashes) != h1
    a.write_text(a.read_text() + "\n# edited\n")
    assert item_hash(item, tmp_path, hashes) != h1 and hashes.reads == 3
    a.unlink()
    assert item_hash(item, tmp_path, hashes) not in (h1, None)


# ------------------------------------------------------------------------------- running


def test_sample_experiment_runs_writes_summary_and_logs(pool_run):
    outcome, rows = pool_run
    run_dir = outcome.run_dir
    assert outcome.ok and sorted(outcome.ran) == sorted(SAMPLE_IDS) and not outcome.skipped
    assert outcome.backend == "process pool x2"
    assert [r["item"] for r in rows] == SAMPLE_IDS
    assert all(r["status"] == "ok" for r in rows)
    for r in rows:
        assert float(r["parameterize.distortion.face_area_distortion"]) < 0.2
        assert float(r["parameterize.seconds.sem"]) > 0
        assert r["parameterize.distortion.flipped_faces"] == "0"
    for item_id in SAMPLE_IDS:
        d = run_dir / item_id
        record = json.loads((d / "item.json").read_text())
        assert record["status"] == "ok" and len(record["hash"]) == 64
        assert (d / "parameterize" / "parameterization.npz").is_file()
        assert (d / "manifest.json").is_file()
        assert Config.model_validate(yaml.safe_load((d / "config.yaml").read_text()))
        log = (d / "log.txt").read_text()
        assert "OPENBLAS_NUM_THREADS=1" in log and "OMP_NUM_THREADS=1" in log
        assert "iteration    0" in log            # the stage's progress line, captured
    page = (run_dir / "summary.html").read_text()
    assert "function sortBy" in page and "<script src" not in page and "http" not in page
    assert f"href='{SAMPLE_IDS[0]}/parameterize/metrics.json'" in page.replace("%3D", "=")
    assert leftovers(run_dir) == []
    # A measure equal in every item is listed once below the table, not as a column.
    head = page.split("<tbody>")[0]
    assert "<th onclick='sortBy(this)'>parameterize.distortion.face_area_distortion</th>" in head
    assert "parameterize.options.inversion" not in head
    assert "<th>parameterize.parameterization.options.inversion</th><td>false</td>" in page


def test_constant_columns_are_those_with_one_value_in_every_row():
    from pipeline.experiments.summary import constant_columns

    rows = [{"a": 1, "b": 2.0, "c": None, "d": "x"}, {"a": 1, "b": 3.0, "d": "x"}]
    assert constant_columns(["a", "b", "c", "d"], rows) == ["a", "c", "d"]
    assert constant_columns(["a", "b", "c", "d"], rows, keep={"a"}) == ["c", "d"]
    assert constant_columns(["a"], rows[:1]) == []


def test_second_run_skips_everything_and_deleted_item_reruns(pool_run):
    outcome, rows = pool_run
    run_dir = outcome.run_dir
    exp = load_experiment(CONFIGS / "experiment_sample.yaml")
    before = mtimes(run_dir)
    again = run_experiment(exp, run_dir.parent, workers=2, progress=False)
    assert again.ran == [] and sorted(again.skipped) == sorted(SAMPLE_IDS)
    assert mtimes(run_dir) == before
    assert untimed(read_summary(run_dir)) == untimed(rows)

    import shutil
    shutil.rmtree(run_dir / SAMPLE_IDS[1])
    third = run_experiment(exp, run_dir.parent, workers=2, progress=False)
    assert third.ran == [SAMPLE_IDS[1]] and third.backend == "serial"
    after = mtimes(run_dir)
    assert {k: v for k, v in after.items() if k != SAMPLE_IDS[1]} == \
        {k: v for k, v in before.items() if k != SAMPLE_IDS[1]}
    assert untimed(read_summary(run_dir)) == untimed(rows)


def test_failing_items_are_recorded_and_the_others_finish(tmp_path, capsys, synthetic_face):
    face = synthetic_face(400)
    write_obj(tmp_path / "good.obj", face.V, face.F)
    k = 5                                        # a closed torus: genus 1 has no map
    a, b = np.meshgrid(2 * np.pi * np.arange(k) / k, 2 * np.pi * np.arange(k) / k, indexing="ij")
    V = np.stack([((3 + np.cos(b)) * np.cos(a)).ravel(), ((3 + np.cos(b)) * np.sin(a)).ravel(),
                  np.sin(b).ravel()], axis=1)
    idx = np.arange(k * k).reshape(k, k)
    F = np.array([[idx[i, j], idx[(i + 1) % k, j], idx[(i + 1) % k, (j + 1) % k]]
                  for i in range(k) for j in range(k)]
                 + [[idx[i, j], idx[(i + 1) % k, (j + 1) % k], idx[i, (j + 1) % k]]
                    for i in range(k) for j in range(k)])
    write_obj(tmp_path / "closed.obj", V, F)
    cfg = tmp_path / "exp.yaml"
    cfg.write_text(yaml.safe_dump({
        "run": {"name": "fails"}, "dataset": {"meshes": ["good.obj", "missing.obj",
                                                        "closed.obj"]},
        "parameterize": {"mode": "paper"}, "report": {"figures": False}}))
    out = tmp_path / "out"

    code = main(["experiment", str(cfg), "--out", str(out), "--workers", "1"])
    stdout = capsys.readouterr().out
    assert code == 1
    assert "3 items: 3 ran (serial), 0 skipped, 2 failed" in stdout
    run_dir = out / "fails"
    rows = {r["item"]: r for r in read_summary(run_dir)}
    assert rows["good"]["status"] == "ok"
    assert rows["missing"]["status"] == "failed"
    assert "input.mesh" in rows["missing"]["error"] and "not found" in rows["missing"]["error"]
    assert rows["closed"]["status"] == "failed" and "is closed with genus 1" in \
        rows["closed"]["error"]
    log = (run_dir / "closed" / "log.txt").read_text()
    assert "Traceback" in log and "UserError" in log
    assert json.loads((run_dir / "closed" / "item.json").read_text())["error_type"] == \
        "UserError"

    # Same bytes, same bad input: kept failed without recomputing, unless asked.
    again = run_experiment(load_experiment(cfg), out, workers=1, progress=False)
    assert again.ran == [] and sorted(again.failed) == ["closed", "missing"]
    retried = run_experiment(load_experiment(cfg), out, workers=1, progress=False,
                             retry_failed=True)
    assert sorted(retried.ran) == ["closed", "missing"]
    # The missing file appears: its hash changes, so it runs.
    write_obj(tmp_path / "missing.obj", face.V, face.F)
    fixed = run_experiment(load_experiment(cfg), out, workers=1, progress=False)
    assert fixed.ran == ["missing"] and fixed.failed == ["closed"]
    assert leftovers(run_dir) == []


def test_face_pairs_run_the_register_stage_and_summarize_its_metrics(tmp_path):
    from pipeline.sample import write_sample

    write_sample(tmp_path / "faces", n_vertices=500)
    exp = expand_experiment({
        "run": {"name": "pairs"}, "dataset": {"faces": {
            "meshes": "faces/sample_face_*.obj", "landmarks": "faces/sample_face_landmarks.json",
            "shared_connectivity": True}},
        "parameterize": {"mode": "paper"}, "report": {"figures": False}}, tmp_path)
    assert [i.id for i in exp.items] == ["neutral-to-smile", "smile-to-neutral"]
    outcome = run_experiment(exp, tmp_path / "out", workers=1, progress=False)
    assert outcome.ok, outcome.records
    for row in read_summary(outcome.run_dir):
        assert row["register.flipped_faces"] == "0"
        assert float(row["register.landmark_residual.after.max"]) < 1e-6
        assert float(row["register.dense_error.ours.mean"]) < 0.05
    log = (outcome.run_dir / "neutral-to-smile" / "log.txt").read_text()
    assert "landmarks paired by name" in log


def test_killed_run_resumes_without_partial_folders(tmp_path):
    cfg = tmp_path / "exp.yaml"
    cfg.write_text(yaml.safe_dump({
        "run": {"name": "killed"}, "input": {"sample": {"vertices": 600}},
        "parameterize": {"mode": "paper"}, "report": {"figures": True},   # ~1 s per item
        "sweep": {"input.sample.identity": [0, 1, 2]}}))
    out = tmp_path / "out"
    run_dir = out / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "pipeline", "experiment", str(cfg), "--out",
                             str(out), "--workers", "1"], cwd=tmp_path, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env=dict(os.environ, PYTHONPATH=str(REPO)))
    try:
        deadline = time.monotonic() + 120
        while not list(run_dir.glob("*/item.json")):
            assert proc.poll() is None and time.monotonic() < deadline, "no item finished"
            time.sleep(0.02)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    finished = {p.parent.name for p in run_dir.glob("*/item.json")}
    assert 1 <= len(finished) < 3

    outcome = run_experiment(load_experiment(cfg), out, workers=1, progress=False)
    assert outcome.ok and set(outcome.skipped) == finished
    assert len(outcome.ran) == 3 - len(finished)
    assert leftovers(out) == []
    assert sorted(p.name for p in run_dir.iterdir() if p.is_dir()) == \
        sorted(i.id for i in load_experiment(cfg).items)
    assert all(r["status"] == "ok" for r in read_summary(run_dir))


def test_pool_and_dask_local_cluster_give_identical_metrics(pool_run, tmp_path):
    distributed = pytest.importorskip("distributed")
    _, pool_rows = pool_run
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        outcome = run_experiment(load_experiment(CONFIGS / "experiment_sample.yaml"), tmp_path,
                                 scheduler=cluster.scheduler_address, progress=False)
    assert outcome.ok and outcome.backend.startswith("dask tcp://")
    assert sorted(outcome.ran) == sorted(SAMPLE_IDS)
    dask_rows = read_summary(outcome.run_dir)
    assert untimed(dask_rows) == untimed(pool_rows)
    log = (outcome.run_dir / SAMPLE_IDS[0] / "log.txt").read_text()
    assert "dask tcp://" in log and "OPENBLAS_NUM_THREADS=1" in log
