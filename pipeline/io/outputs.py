"""Output folders: checked before any computation, written by one run at a time, replaced whole.

* :func:`check_output_folder` — one-line :class:`~pipeline.errors.UserError` when a folder cannot
  be the output: an empty path, a name too long for the build beside it, a file (or
  ``/dev/null``) in the way or above it, a mount point,
  no write permission, less free space than the outputs need, files in it that sem-pipeline did
  not write, or an input file inside it (the folder is replaced, so the input would be lost).
* :func:`output_lock` — an exclusive ``flock`` on ``<parent>/.<name>.lock`` beside the folder
  (released by the OS when the process dies); a second writer gets a one-line error naming the
  holder (pid, host, start time).
* :func:`replaced_folder` — the run is built in ``<parent>/.<name>.partial-XXXX`` beside the
  folder and swapped in when it is complete (``renameat2(RENAME_EXCHANGE)`` where the kernel has
  it, else two renames), so the folder holds the previous run or the new one, never a mix. The
  build gets a marker file (:data:`MARKER`) listing what the run wrote.
* :func:`clean_leftovers` — what killed runs left beside the folder: builds are deleted; a
  previous result renamed aside (``.<name>.old-XXXX``) is put back when the folder is missing.

:func:`output_folder` combines them in that order.
"""

from __future__ import annotations

import ctypes
import errno
import json
import os
import platform
import re
import shutil
import tempfile
import time
import uuid
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable

from ..errors import UserError, file_problem
from .artifacts import _umask

__all__ = ["MARKER", "check_output_folder", "output_lock", "replaced_folder", "clean_leftovers",
           "output_folder", "format_bytes"]

MARKER = ".sem-pipeline.json"
_BUILD_SUFFIX = 8           # the characters tempfile.mkdtemp appends to a build's prefix
_RENAME_EXCHANGE = 2


def format_bytes(n: float) -> str:
    """``1536`` → ``"1.5 KiB"`` (powers of 1024, up to EiB)."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.3g} EiB"


def _kind(path: Path) -> str:
    """What stands at ``path``, an existing non-folder: ``"a file"``, ``"a device"`` …"""
    return (file_problem(path) or "is a file").removeprefix("is ")


def _nearest_existing(path: Path) -> Path:
    """The path itself or its closest ancestor that exists; a non-folder on the way is an
    error (nothing can be created below a file)."""
    p = path
    while not os.path.lexists(p):
        p = p.parent
    if p != path and not p.is_dir():
        raise UserError(f"cannot create output folder '{path}': '{p}' is {_kind(p)}, not a "
                        f"folder; choose another output folder")
    return p


def owned_entries(folder: Path) -> set[str]:
    """Top-level names that the run recorded in ``folder``'s marker (empty without one)."""
    try:
        data = json.loads((Path(folder) / MARKER).read_text(encoding="utf-8"))
        return {MARKER, *map(str, data.get("entries", []))}
    except (OSError, ValueError, AttributeError, TypeError):
        return set()


def _foreign(folder: Path) -> list[str]:
    owned = owned_entries(folder)
    return sorted(n for n in os.listdir(folder) if n not in owned)


def _name_max(folder: Path) -> int:
    """The longest file name (bytes) that the file system of ``folder`` (or of its closest
    existing ancestor) takes."""
    p = folder
    while not os.path.isdir(p) and p.parent != p:
        p = p.parent
    try:
        return os.pathconf(p, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def _check_name_length(path: Path, given, flag: str) -> None:
    """One-line error when the folder's name, or the build and lock names made beside it
    (:func:`_prefixes`, :func:`output_lock`), are longer than its file system takes."""
    name_max = _name_max(path.parent)
    longest = len(os.fsencode(f"{_prefixes(path)[0]}{'x' * _BUILD_SUFFIX}"))
    extra = longest - len(os.fsencode(path.name))
    if longest > name_max:
        raise UserError(f"{flag} '{given}': the folder name is {len(os.fsencode(path.name))} "
                        f"bytes, but at most {name_max - extra} fit (the run is built beside "
                        f"it as '.NAME.partial-XXXXXXXX' in names of at most {name_max} "
                        f"bytes); choose a shorter name")


def _is_mount_point(path: Path) -> bool:
    """``os.path.ismount``, or a mount point that ``/proc/self/mountinfo`` lists (a folder
    bind-mounted from the same file system, which ``ismount`` does not see)."""
    if os.path.ismount(path):
        return True
    try:
        with open("/proc/self/mountinfo", encoding="utf-8", errors="surrogateescape") as fh:
            points = [line.split()[4] for line in fh if len(line.split()) > 4]
    except OSError:
        return False
    octal = re.compile(r"\\([0-7]{3})")           # a space is written \040, and so on
    return str(path) in {octal.sub(lambda m: chr(int(m.group(1), 8)), p) for p in points}


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.relative_to(folder)
        return True
    except ValueError:
        return False


def check_output_folder(dest: str | Path, need_bytes: int = 0,
                        inputs: Iterable[str | Path] = (), flag: str = "output folder",
                        replace: bool = True) -> Path:
    """Check that ``dest`` can be the output folder (module docstring); returns it resolved.

    ``need_bytes``: the estimated size of the outputs (checked against the free space);
    ``inputs``: files and folders the run reads; ``flag``: how the command names the folder;
    ``replace``: the folder is replaced as a whole (not for an experiment's folder, which
    keeps its finished items), so a mount point or files of others in it are errors.
    """
    if not str(dest).strip():
        raise UserError(f"{flag}: empty path; give a folder name (e.g. '-o out')")
    if "\0" in str(dest):
        raise UserError(f"{flag}: the path contains a NUL character; give a plain folder name")
    given = Path(dest).expanduser()
    path = Path(os.path.abspath(given))
    if os.path.lexists(path) and path.is_dir():
        path = path.resolve()               # a symlink to a folder: the folder it names
    if path.parent == path:
        raise UserError(f"{flag} '{given}' is the file system root; choose a folder below it")
    _check_name_length(path, given, flag)
    if os.path.lexists(path):
        if not path.is_dir():
            raise UserError(f"{flag} '{given}' is {_kind(path)}, not a folder; remove it or "
                            f"choose another output folder")
        if replace and _is_mount_point(path):
            raise UserError(f"{flag} '{given}' is a mount point, which cannot be replaced; "
                            f"choose a folder inside it")
        foreign = _foreign(path) if replace else []
        if foreign:
            shown = ", ".join(f"'{n}'" for n in foreign[:3]) + (" …" if len(foreign) > 3 else "")
            raise UserError(f"{flag} '{given}' holds files that sem-pipeline did not write "
                            f"({shown}); choose a new or empty folder (the output folder is "
                            f"replaced as a whole)")
    base = _nearest_existing(path.parent)
    if not base.is_dir():
        raise UserError(f"cannot create output folder '{given}': '{base}' is {_kind(base)}, not "
                        f"a folder; choose another output folder")
    if not os.access(base, os.W_OK | os.X_OK):
        raise UserError(f"cannot write in '{base}' (permission denied or read-only); choose a "
                        f"writable output folder")
    free = shutil.disk_usage(base).free
    if free < need_bytes:
        raise UserError(f"only {format_bytes(free)} free on the file system of '{base}', but the "
                        f"outputs need about {format_bytes(need_bytes)}; free some space or "
                        f"choose another output folder")
    for p in inputs:
        q = Path(os.path.realpath(Path(p).expanduser()))   # a symlink loop stays as given
        if q == path or _inside(q, path):
            raise UserError(f"input '{p}' is inside the {flag} '{given}', which the run "
                            f"replaces; write to another folder or move the input out of it")
    return path


def _holder(fd: int) -> str:
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        text = os.read(fd, 512).decode("utf-8", "replace").strip()
    except OSError:
        text = ""
    return text or "a process that is just starting"


@contextmanager
def output_lock(dest: Path):
    """Hold the exclusive lock of the output folder ``dest`` (module docstring)."""
    import fcntl

    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(dest.parent / f".{dest.name}.lock", os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise UserError(f"output folder '{dest}' is being written by another sem-pipeline "
                            f"run ({_holder(fd)}); wait for it to finish or choose another "
                            f"output folder") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, (f"pid {os.getpid()} on {platform.node()}, started "
                       f"{time.strftime('%Y-%m-%d %H:%M:%S')}\n").encode(), 0)
        yield
    finally:
        os.close(fd)                     # closing releases the lock


def _prefixes(dest: Path) -> tuple[str, str]:
    return f".{dest.name}.partial-", f".{dest.name}.old-"


def clean_leftovers(dest: Path) -> list[Path]:
    """Delete the builds that killed runs left beside ``dest``, and put a previous result that
    was renamed aside back when ``dest`` is missing (call it holding the lock). Returns what
    was deleted."""
    dest = Path(dest)
    partial, old = _prefixes(dest)
    gone = []
    if not dest.parent.is_dir():
        return gone
    for name in sorted(os.listdir(dest.parent)):
        p = dest.parent / name
        if name.startswith(old) and not os.path.lexists(dest):
            os.rename(p, dest)
        elif name.startswith((partial, old)):
            shutil.rmtree(p, ignore_errors=True)
            gone.append(p)
    return gone


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2``); ``False`` where that is not available."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd = -100
    if renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _publish(build: Path, dest: Path) -> None:
    """Move the complete ``build`` to ``dest``; an earlier ``dest`` is deleted afterwards."""
    if not os.path.lexists(dest):
        os.rename(build, dest)
        return
    if _exchange(build, dest):
        old = build
    else:
        old = dest.parent / f"{_prefixes(dest)[1]}{uuid.uuid4().hex[:8]}"
        os.rename(dest, old)
        os.rename(build, dest)
    shutil.rmtree(old, ignore_errors=True)


def _write_marker(build: Path, command: str) -> None:
    from .artifacts import _umask, write_json

    entries = sorted(os.listdir(build))
    write_json(build / MARKER, {"written_by": "sem-pipeline", "command": command,
                                "entries": entries, "pid": os.getpid(),
                                "host": platform.node(),
                                "finished": time.strftime("%Y-%m-%d %H:%M:%S")})


@contextmanager
def replaced_folder(dest: Path, command: str = "", keep_on=()):
    """Yield a build folder beside ``dest``; swap it in when the block ends.

    It is swapped in when the block finishes, or raises one of ``keep_on`` after writing
    something (a method that failed and wrote its diagnosis: the run's complete result); on
    any other
    exception (bad input, a full disk, an interruption) it is deleted and ``dest`` stays as it
    was.
    """
    dest = Path(dest)
    build = Path(tempfile.mkdtemp(prefix=_prefixes(dest)[0], dir=dest.parent))
    os.chmod(build, 0o777 & ~_umask())     # mkdtemp makes it private; the result is not
    try:
        try:
            yield build
        except keep_on:
            if any(build.iterdir()):
                _write_marker(build, command)
                _publish(build, dest)
            raise
        _write_marker(build, command)
        _publish(build, dest)
    finally:
        if build.exists():
            shutil.rmtree(build, ignore_errors=True)


@contextmanager
def output_folder(dest: str | Path, need_bytes: int = 0, inputs: Iterable = (),
                  command: str = "", flag: str = "output folder", keep_on=()):
    """Check ``dest``, lock it, clean leftovers and yield a build folder that replaces it whole
    (:func:`check_output_folder`, :func:`output_lock`, :func:`clean_leftovers`,
    :func:`replaced_folder`)."""
    path = check_output_folder(dest, need_bytes, inputs, flag)
    with output_lock(path):
        clean_leftovers(path)
        if os.path.lexists(path):                 # it may have changed while we waited
            check_output_folder(path, 0, (), flag)
        with replaced_folder(path, command, keep_on) as build:
            yield build
