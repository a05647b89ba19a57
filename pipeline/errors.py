"""Errors that are the user's to fix, and :func:`file_problem`, which names what stands where
an input file was expected.

Any :class:`UserError` raised anywhere in the pipeline reaches the command line as exactly one
line on stderr (``error: <message>``) and exit code 2. The message names the problem *and* the
fix, e.g. ``mesh 'a.obj' is closed (no boundary loop); cut it open or pass a disk-like patch``.
Programming errors are never wrapped in it.
"""

import errno
import os
import stat


class UserError(Exception):
    """Bad input or configuration: one-line message, exit code 2, no traceback."""

    exit_code = 2

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


def file_problem(path, missing: str = "does not exist") -> str | None:
    """Why ``path`` cannot be read as a file, as the end of a sentence naming it: ``missing``
    when nothing is there, ``"is a folder"``, ``"is a device"``, ``"is a pipe"``,
    ``"is a socket"``, ``"is a symbolic link to a missing file or a loop"``, ``"cannot be
    reached (file name too long)"`` (the system's reason); ``None`` for a regular file (or a
    symbolic link to one)."""
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        if os.path.islink(path):
            return "is a symbolic link to a missing file or a loop"
        if exc.errno in (errno.ENOENT, errno.ENOTDIR):
            return missing
        return f"cannot be reached ({(exc.strerror or str(exc)).lower()})"
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "is a folder"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "is a device"
    return "is a pipe" if stat.S_ISFIFO(mode) else "is a socket"
