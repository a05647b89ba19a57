"""Running an experiment's items: in this process, on a local process pool, or on Dask.

:func:`run_experiment` hashes every item, skips the finished ones (:mod:`.cache`), runs the
rest with a progress bar over items (tqdm, stderr) and writes the summary (:mod:`.summary`).
Each item runs :func:`run_item`: the ordinary single-run runner
(:func:`pipeline.runner.write_run`) into a staging folder, its stderr/stdout captured into
``<item>/log.txt`` (with the traceback on failure), then ``item.json`` (status, hash, params,
error, timings, flattened metrics, links) and an atomic rename into ``<run>/<item>/``. A failing
item is recorded and the others go on.

Backends:

* ``workers == 1``: in this process, one item after another;
* otherwise a ``concurrent.futures.ProcessPoolExecutor`` (``spawn`` context) with
  ``OPENBLAS_NUM_THREADS``/``OMP_NUM_THREADS``/``MKL_NUM_THREADS`` = 1 in the workers, so N
  workers use N cores and do not oversubscribe them;
* ``scheduler``: a Dask distributed cluster at that address (``tcp://host:8786``;
  ``local`` starts a ``LocalCluster`` of ``workers`` single-threaded processes): items are
  submitted as tasks and gathered as they complete. The workers need this package installed
  and must see the same paths (inputs and the output folder) as this machine — a shared file
  system. Dask's nanny already sets the BLAS thread variables to 1 in its workers.

This module imports only the standard library at import time (a pool worker imports it before
numpy, so that the thread limits take effect).
"""

from __future__ import annotations

import json
import os
import platform
import sys
import threading
import time
import traceback
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from ..errors import UserError

THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


@dataclass
class Outcome:
    run_dir: Path
    ran: list[str] = field(default_factory=list)        # items computed in this run
    skipped: list[str] = field(default_factory=list)    # finished before, hash unchanged
    failed: list[str] = field(default_factory=list)     # failed now, or kept from before
    records: dict[str, dict] = field(default_factory=dict)
    summary: tuple[Path, Path] | None = None
    backend: str = ""

    @property
    def ok(self) -> bool:
        return not self.failed


# ------------------------------------------------------------------------ output capture


class _ThreadStream:
    """``sys.stdout``/``sys.stderr`` stand-in that writes to a per-thread stream when one is
    set (the running item's log) and to the original stream otherwise (so Dask's threads and
    the progress bar are unaffected)."""

    def __init__(self, default):
        self._default = default
        self._local = threading.local()

    def _target(self):
        return getattr(self._local, "stream", None) or self._default

    def write(self, text):
        return self._target().write(text)

    def flush(self):
        return self._target().flush()

    def isatty(self):
        return False if getattr(self._local, "stream", None) else self._default.isatty()

    def __getattr__(self, name):
        return getattr(self._target(), name)


_capture_lock = threading.Lock()
_capture_users = 0


@contextmanager
def capture_output(stream):
    """Send this thread's ``sys.stdout`` and ``sys.stderr`` writes to ``stream``."""
    global _capture_users
    with _capture_lock:
        if _capture_users == 0:
            sys.stdout, sys.stderr = _ThreadStream(sys.stdout), _ThreadStream(sys.stderr)
        _capture_users += 1
        proxies = (sys.stdout, sys.stderr)
    for p in proxies:
        p._local.stream = stream
    try:
        yield
    finally:
        for p in proxies:
            p._local.stream = None
        with _capture_lock:
            _capture_users -= 1
            if _capture_users == 0 and isinstance(sys.stderr, _ThreadStream):
                sys.stdout, sys.stderr = sys.stdout._default, sys.stderr._default


# ------------------------------------------------------------------------------ one item


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _one_line(exc: BaseException, limit: int = 500) -> str:
    text = " ".join(str(exc).split())
    if not isinstance(exc, UserError):
        text = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return text if len(text) <= limit else text[:limit - 1] + "…"


def run_item(payload: dict) -> dict:
    """Run one item into its atomic folder and return its record (never raises for a failing
    item; only an interruption propagates, leaving a ``.partial-*`` folder to clean)."""
    from ..config import Config, check_input_files
    from ..runner import write_run
    from .cache import RECORD, new_staging, publish
    from .summary import collect_metrics
    from ..io.artifacts import write_json

    item_id, run_dir, base = payload["id"], Path(payload["run_dir"]), Path(payload["base"])
    staging, item_dir = new_staging(run_dir, item_id)
    record = {"id": item_id, "status": "running", "hash": payload["hash"],
              "params": payload.get("params", {}), "error": None, "error_type": None,
              "started": _now(), "host": platform.node(), "pid": os.getpid(),
              "backend": payload.get("backend", "")}
    t0 = time.perf_counter()
    with open(item_dir / "log.txt", "w", encoding="utf-8", buffering=1) as log:
        threads = " ".join(f"{v}={os.environ.get(v)}" for v in THREAD_VARS)
        if os.environ.get("MALLOC_TRIM_THRESHOLD_"):
            threads += (f"; MALLOC_TRIM_THRESHOLD_={os.environ['MALLOC_TRIM_THRESHOLD_']}: "
                        f"slows SEM ~1.5x, start Dask workers with DASK_DISTRIBUTED__NANNY__"
                        f"PRE_SPAWN_ENVIRON__MALLOC_TRIM_THRESHOLD_=None")
        print(f"item {item_id}\nhash {payload['hash']}\nstarted {record['started']} on "
              f"{record['host']} (pid {record['pid']}, {record['backend']}; {threads})\n",
              file=log)
        with capture_output(log):
            try:
                config = Config.model_validate(payload["data"])
                _write_yaml(item_dir / "config.yaml", payload["data"])
                check_input_files(config, base, f"item '{item_id}'")
                write_run(config, base, item_dir)
                record["status"] = "ok"
            except Exception as exc:           # recorded; the other items go on
                record.update(status="failed", error=_one_line(exc),
                              error_type=type(exc).__name__)
                traceback.print_exc(file=log)
        record["seconds"] = {"total": time.perf_counter() - t0}
        record["finished"] = _now()
        print(f"\n{record['status']} after {record['seconds']['total']:.2f} s"
              + (f": {record['error']}" if record["error"] else ""), file=log)
    record["metrics"], record["links"] = collect_metrics(item_dir)
    write_json(item_dir / RECORD, record)
    publish(staging, item_dir, run_dir / item_id)
    return record


def _write_yaml(path: Path, data: dict) -> None:
    import yaml

    from ..io.artifacts import atomic_write_text

    atomic_write_text(path, "# This item's full single-run config: sem-pipeline run "
                            "config.yaml\n" + yaml.safe_dump(data, sort_keys=False))


def _lost_item(payload: dict, exc: BaseException) -> dict:
    """Record an item whose worker died (the pool broke, Dask lost the worker): retried on
    the next run, since it is not a ``UserError``."""
    from ..io.artifacts import write_json
    from .cache import RECORD, new_staging, publish

    run_dir = Path(payload["run_dir"])
    staging, item_dir = new_staging(run_dir, payload["id"])
    error = f"worker failed: {_one_line(exc)}; the item is retried on the next run"
    (item_dir / "log.txt").write_text(
        f"item {payload['id']}\n{error}\n\n"
        + "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)),
        encoding="utf-8")
    record = {"id": payload["id"], "status": "failed", "hash": payload["hash"],
              "params": payload.get("params", {}), "error": error,
              "error_type": type(exc).__name__, "finished": _now(),
              "backend": payload.get("backend", ""), "seconds": {}, "metrics": {}, "links": {}}
    write_json(item_dir / RECORD, record)
    publish(staging, item_dir, run_dir / payload["id"])
    return record


# ------------------------------------------------------------------------------ backends


def end_with_parent() -> None:
    """End this process when its parent dies: ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` on Linux,
    else a daemon thread that polls the parent's pid. A pool worker whose experiment was
    killed must not go on writing into the folder without its lock."""
    import multiprocessing
    import signal

    spawner = multiprocessing.parent_process()      # the pool's process, even if it died
    parent = spawner.pid if spawner is not None else os.getppid()
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(1, signal.SIGKILL, 0, 0, 0) != 0:       # 1 = PR_SET_PDEATHSIG
            raise OSError(ctypes.get_errno(), "prctl")
    except (OSError, AttributeError):
        def watch():
            while os.getppid() == parent:
                time.sleep(0.5)
            os._exit(137)

        threading.Thread(target=watch, name="end-with-parent", daemon=True).start()
    if os.getppid() != parent:                 # the parent died before this process got here
        os._exit(137)


def _init_worker() -> None:
    import signal

    end_with_parent()
    for var in THREAD_VARS:                 # before numpy is imported in this process
        os.environ[var] = "1"
    # Ctrl-C reaches the whole process group: a worker stops at once (its item's staging
    # folder is deleted by the next run) instead of starting the items already queued to it.
    signal.signal(signal.SIGINT, lambda *_: os._exit(130))
    import importlib

    importlib.import_module("pipeline.runner")   # imports paid here, not in the first item


def _serial(payloads, done):
    for p in payloads:
        done(p, run_item(p))


def _pool(payloads, workers: int, done):
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # spawn: a fresh interpreter per worker (no fork of a process holding BLAS threads or
    # locks); the initializer runs before numpy is imported there.
    pool = ProcessPoolExecutor(max_workers=workers, initializer=_init_worker,
                               mp_context=multiprocessing.get_context("spawn"))
    try:
        futures = {pool.submit(run_item, p): p for p in payloads}
        for fut in as_completed(futures):
            p = futures[fut]
            try:
                record = fut.result()
            except Exception as exc:             # BrokenProcessPool: a worker died
                record = _lost_item(p, exc)
            done(p, record)
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def _dask(payloads, address: str, workers: int, done):
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise UserError("Dask is not installed; pip install 'dask[distributed]' (or drop "
                        "--scheduler to use the local process pool)") from None
    cluster = None
    try:
        if address == "local":
            import dask

            # Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in its workers, which turns off
            # glibc's adaptive mmap threshold: SEM's large temporary arrays then cost a page
            # fault storm (~1.5x slower items). Unset it for the cluster started here.
            with dask.config.set({"distributed.nanny.pre-spawn-environ."
                                  "MALLOC_TRIM_THRESHOLD_": None}):
                cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                       processes=True, dashboard_address=None)
            client = Client(cluster)
        else:
            client = Client(address, timeout="20s")
    except (OSError, TimeoutError, ValueError) as exc:
        if cluster is not None:
            cluster.close()
        raise UserError(f"cannot connect to the Dask scheduler at '{address}' "
                        f"({_one_line(exc)}); start one ('dask scheduler' and 'dask worker "
                        f"{address}') or drop --scheduler") from None
    try:
        futures = {}
        for p in payloads:
            futures[client.submit(run_item, p, pure=False,
                                  key=f"sem-item-{p['id']}-{os.urandom(4).hex()}")] = p
        for fut in as_completed(list(futures)):
            p = futures[fut]
            try:
                record = fut.result()
            except Exception as exc:             # KilledWorker, lost connection, …
                record = _lost_item(p, exc)
            done(p, record)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# ------------------------------------------------------------------------------ experiment


def run_experiment(experiment, out_root: str | Path | None = None, workers: int | None = None,
                   scheduler: str | None = None, retry_failed: bool = False,
                   progress: bool = True) -> Outcome:
    """Run the items of ``experiment`` (:class:`~.spec.Experiment`) that are not finished.

    ``workers`` (default: the config's ``experiment.workers``, else the machine's cores) and
    ``scheduler`` (default: the config's ``experiment.scheduler``; a Dask address or
    ``local``) choose the backend. The experiment's folder is checked and locked like a run's
    (:mod:`pipeline.io.outputs`; it is not replaced: its finished items are the cache), and
    the summary is written also when the run is interrupted (unfinished items: ``missing``).
    Returns which items ran, were skipped and failed.
    """
    from ..io.artifacts import atomic_write_text
    from ..io.outputs import check_output_folder, output_lock
    from .cache import FileHashes, clean_partials, item_hash, needs_run, read_record
    from .summary import write_summary

    settings = experiment.settings.experiment
    workers = workers or settings.workers or os.cpu_count() or 1
    scheduler = scheduler or settings.scheduler
    run_dir = check_output_folder(experiment.run_dir(out_root), 1 << 20, flag="experiment folder",
                                  replace=False)
    outcome = Outcome(run_dir)
    with output_lock(run_dir):
        run_dir.mkdir(parents=True, exist_ok=True)
        clean_partials(run_dir)
        hashes = FileHashes(run_dir / ".file_hashes.json")
        todo, listing = [], []
        for item in experiment.items:
            digest = item_hash(item, experiment.base, hashes)
            listing.append({"id": item.id, "hash": digest, "params": item.params})
            record = read_record(run_dir / item.id)
            if needs_run(record, digest, retry_failed):
                todo.append({"id": item.id, "data": item.data(), "params": item.params,
                             "hash": digest, "base": str(experiment.base),
                             "run_dir": str(run_dir)})
            else:
                outcome.skipped.append(item.id)
                outcome.records[item.id] = record
        hashes.save()
        workers = min(workers, len(todo)) if not scheduler else workers
        if scheduler:
            backend = f"dask {scheduler}"
        else:
            backend = "serial" if workers <= 1 else f"process pool x{workers}"
        for p in todo:
            p["backend"] = backend
        atomic_write_text(run_dir / "experiment.json", json.dumps(
            {"config": str(experiment.source), "items": listing}, indent=1, default=str) + "\n")

        from tqdm import tqdm

        stream = sys.stderr                # not an item's log: captured only in item threads
        bar = tqdm(total=len(experiment.items), initial=len(outcome.skipped), unit="item",
                   desc=experiment.name, file=stream, disable=not progress, dynamic_ncols=True,
                   mininterval=0.5)

        def done(payload, record):
            outcome.ran.append(payload["id"])
            outcome.records[payload["id"]] = record
            if record.get("status") != "ok":
                bar.write(f"{payload['id']}: failed: {record.get('error')} "
                          f"(log: {run_dir / payload['id'] / 'log.txt'})", file=stream)
            bar.update(1)

        outcome.backend = backend if todo else "none"
        try:
            if todo and scheduler:
                _dask(todo, scheduler, workers, done)
            elif todo and backend == "serial":
                _serial(todo, done)
            elif todo:
                _pool(todo, workers, done)
        finally:
            # also when interrupted: the summary lists the finished items, the rest 'missing'
            bar.close()
            outcome.failed = [i.id for i in experiment.items
                              if outcome.records.get(i.id, {}).get("status") != "ok"]
            outcome.summary = write_summary(run_dir, experiment.items, outcome.records,
                                            title=experiment.name)
    return outcome
