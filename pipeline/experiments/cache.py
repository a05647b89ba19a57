"""Content hashes, atomic item folders and the record (``item.json``) that lets a re-run skip.

* **Content hash of an item** — SHA-256 of canonical JSON (sorted keys, no spaces) of the
  package name and version and the item's whole config (defaults included; absent sections and
  ``run``, which only names folders, left out), with every input file replaced by the SHA-256
  of its bytes. So moving the data
  folder keeps the cache; editing a mesh, a landmark file, a setting (or a new default that
  the schema adds) or bumping the version re-runs the item. A missing input is hashed as
  ``missing:<path>``, so the item is retried once the file appears.
* **File hashes** are read in 1 MiB chunks and remembered by ``(path, size, mtime_ns)`` in
  ``<run>/.file_hashes.json``, so a re-run does not reread unchanged files.
* **Atomic item folders** — an item is written into ``<run>/.partial-<id>-XXXX/<id>/`` and
  renamed to ``<run>/<id>/`` when complete (an old folder is first renamed aside to
  ``.trash-…`` and deleted after). An interrupted run leaves only ``.partial-*``/``.trash-*``
  folders, which the next run deletes before it starts; ``<run>/<id>/`` is always complete.
* **Decision** (:func:`needs_run`) — skip an item whose ``item.json`` has the same hash and
  status ``ok``; re-run the rest. A failure from bad input (``UserError``: the same bytes give
  the same one-line error) is kept without re-running until its hash changes or
  ``retry_failed``; any other failure (a crash, a method failure, a lost worker) is retried.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import uuid
from pathlib import Path

from .. import __version__
from ..config import resolve_path
from ..io.artifacts import atomic_write_text
from .spec import INPUT_FILE_KEYS, Item

PARTIAL_PREFIX = ".partial-"
TRASH_PREFIX = ".trash-"
RECORD = "item.json"
CHUNK = 1 << 20


def file_sha256(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(CHUNK), b""):
            h.update(block)
    return h.hexdigest()


class FileHashes:
    """SHA-256 of files, cached by ``(path, size, mtime_ns)`` in a JSON file."""

    def __init__(self, path: str | Path | None = None):
        self.path = Path(path) if path else None
        self.entries: dict[str, dict] = {}
        self.reads = 0                         # files actually read (for tests and the log)
        if self.path and self.path.is_file():
            try:
                self.entries = json.loads(self.path.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                self.entries = {}

    def digest(self, path: str | Path) -> str | None:
        """The file's SHA-256, or ``None`` if it is not a readable file."""
        path = Path(os.path.realpath(path))          # a symlink loop: no stat below
        try:
            st = path.stat()
        except OSError:
            return None
        if not path.is_file():
            return None
        key = str(path)
        hit = self.entries.get(key)
        if hit and hit.get("size") == st.st_size and hit.get("mtime_ns") == st.st_mtime_ns:
            return hit["sha256"]
        try:
            digest = file_sha256(path)
        except OSError:
            return None
        self.reads += 1
        self.entries[key] = {"size": st.st_size, "mtime_ns": st.st_mtime_ns, "sha256": digest}
        return digest

    def save(self) -> None:
        if self.path:
            atomic_write_text(self.path, json.dumps(self.entries, indent=0, sort_keys=True))


def canonical_json(data) -> str:
    return json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                      allow_nan=True, default=str)


def item_hash(item: Item, base: Path, hashes: FileHashes) -> str:
    """The item's content hash (see the module docstring)."""
    data = item.config.model_dump(mode="json", exclude={"run"})
    # Absent sections are left out, so a section that the schema gains later (unused by this
    # item) keeps the hash; a new default inside a section the item uses changes it.
    data = {k: v for k, v in data.items() if v is not None}
    known = {tuple(k.split(".")) for k in INPUT_FILE_KEYS}

    def walk(node, where: tuple):
        if isinstance(node, dict):
            return {k: walk(v, where + (k,)) for k, v in node.items()}
        if isinstance(node, list):
            return [walk(v, where) for v in node]
        if isinstance(node, str) and (where in known or _names_file(node, base)):
            digest = hashes.digest(resolve_path(node, base))
            return f"sha256:{digest}" if digest else f"missing:{node}"
        return node

    payload = {"package": "sem-pipeline", "version": __version__, "config": walk(data, ())}
    return hashlib.sha256(canonical_json(payload).encode("utf-8")).hexdigest()


def _names_file(value: str, base: Path) -> bool:
    """A string setting outside the known keys that names an existing file (e.g. a path key
    a new stage adds) is hashed by content too."""
    if not value or len(value) > 4096 or "\n" in value:
        return False
    try:
        return resolve_path(value, base).is_file()
    except (OSError, ValueError):
        return False


# ------------------------------------------------------------------------------- records


def read_record(item_dir: Path) -> dict | None:
    """``item.json`` of a finished item folder, or ``None``."""
    try:
        record = json.loads((Path(item_dir) / RECORD).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def needs_run(record: dict | None, digest: str, retry_failed: bool = False) -> bool:
    if record is None or record.get("hash") != digest:
        return True
    if record.get("status") == "ok":
        return False
    return retry_failed or record.get("error_type") != "UserError"


# ------------------------------------------------------------------------------- folders


def new_staging(run_dir: Path, item_id: str) -> tuple[Path, Path]:
    """``(staging folder, item folder inside it)`` for one attempt at an item."""
    staging = Path(tempfile.mkdtemp(prefix=f"{PARTIAL_PREFIX}{item_id}-", dir=run_dir))
    item_dir = staging / item_id
    item_dir.mkdir()
    return staging, item_dir


def publish(staging: Path, item_dir: Path, final: Path) -> None:
    """Move the complete ``item_dir`` to ``final`` (rename; an old ``final`` goes aside first)."""
    trash = None
    if final.exists():
        trash = final.parent / f"{TRASH_PREFIX}{final.name}-{uuid.uuid4().hex[:8]}"
        os.rename(final, trash)
    os.rename(item_dir, final)
    shutil.rmtree(staging, ignore_errors=True)
    if trash is not None:
        shutil.rmtree(trash, ignore_errors=True)


def clean_partials(run_dir: Path) -> list[Path]:
    """Delete what interrupted runs left (``.partial-*``, ``.trash-*``); returns them."""
    gone = []
    for p in sorted(Path(run_dir).iterdir()) if Path(run_dir).is_dir() else []:
        if p.is_dir() and p.name.startswith((PARTIAL_PREFIX, TRASH_PREFIX)):
            shutil.rmtree(p, ignore_errors=True)
            gone.append(p)
    return gone
