"""Writing files and a stage's output folder all-or-nothing — the one writer every file goes
through (meshes, arrays, JSON, PNG, GIF, HTML, the experiment cache and summary).

* :func:`atomic_write` — one file: written under a temporary name in the destination folder,
  flushed and ``fsync``-ed, then moved over the destination with ``os.replace`` (atomic on one
  file system), so a reader sees the old file or the new one, never a half-written one. The
  file gets the permissions of a normal new file (``0o666`` minus the umask), not the
  temporary file's ``0o600``.
* :func:`staged_output` — a folder: its files are written into a hidden temporary folder
  inside the destination and moved into place (``os.replace`` per file) only after every file
  was written, so a failure or an interruption never leaves a half-written result next to
  earlier good ones.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO, Callable

import numpy as np

__all__ = ["atomic_write", "atomic_write_text", "save_npz", "staged_output", "write_json"]


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write(path: str | Path, data: bytes | str | Callable[[BinaryIO], object]) -> Path:
    """Write ``path`` atomically and return it.

    Parameters
    ----------
    path : destination; missing parent folders are created.
    data : the content — ``bytes``, ``str`` (written as UTF-8, ``\\n`` line ends kept as
        they are), or a callable that writes into the binary file object it is given (e.g.
        ``lambda f: fig.savefig(f, format="png")``).
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    folder.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            if callable(data):
                data(fh)
            else:
                fh.write(data.encode("utf-8") if isinstance(data, str) else data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path: str | Path, text: str) -> Path:
    """:func:`atomic_write` of a UTF-8 text."""
    return atomic_write(path, text)


def save_npz(path: str | Path, **arrays) -> Path:
    """``numpy.savez_compressed`` of ``arrays`` into ``path``, atomically."""
    return atomic_write(path, lambda fh: np.savez_compressed(fh, **arrays))


@contextmanager
def staged_output(out_dir: str | Path):
    """Yield a temporary folder; on success move its files into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".partial-", dir=out_dir))
    try:
        yield tmp
        for src in sorted(tmp.rglob("*")):
            if src.is_file():
                dst = out_dir / src.relative_to(tmp)
                dst.parent.mkdir(parents=True, exist_ok=True)
                os.replace(src, dst)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _plain(obj):
    """JSON-serialisable copy: numpy scalars and arrays become Python numbers and lists."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_json(path: str | Path, data: dict) -> Path:
    """``data`` (numpy values and paths made plain) as indented JSON, atomically."""
    return atomic_write(path, json.dumps(_plain(data), indent=2, allow_nan=True) + "\n")
