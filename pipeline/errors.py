"""Errors that are the user's to fix.

Any :class:`UserError` raised anywhere in the pipeline reaches the command line as exactly one
line on stderr (``error: <message>``) and exit code 2. The message names the problem *and* the
fix, e.g. ``mesh 'a.obj' is closed (no boundary loop); cut it open or pass a disk-like patch``.
Programming errors are never wrapped in it.
"""


class UserError(Exception):
    """Bad input or configuration: one-line message, exit code 2, no traceback."""

    exit_code = 2

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))
