"""Resource bounds: a request whose estimated memory exceeds the limit is refused before
anything is allocated.

The limit is the machine's physical memory, or ``SEM_PIPELINE_MEMORY_LIMIT`` (bytes, or a
number with K, M, G or T, e.g. ``64G``). A stage estimates its own request (``Stage.check``)
and calls :func:`check_memory`, whose one-line error gives the estimate, the limit and how to
raise it.
"""

from __future__ import annotations

import os
import re

from .errors import UserError
from .io.outputs import format_bytes

__all__ = ["MEMORY_ENV", "memory_limit", "parse_size", "check_memory"]

MEMORY_ENV = "SEM_PIPELINE_MEMORY_LIMIT"
_UNITS = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


def parse_size(text: str) -> int:
    """``"64G"`` → bytes (K, M, G, T are powers of 1024; an optional trailing ``B``/``iB``)."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([kKmMgGtT]?)(?:i?[bB])?\s*", text)
    if not m:
        raise UserError(f"{MEMORY_ENV}={text!r} is not a size; give bytes or a number with K, "
                        f"M, G or T (e.g. 64G)")
    return int(float(m.group(1)) * _UNITS[m.group(2).lower()])


def physical_memory() -> int:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 1 << 34                      # 16 GiB where the system does not say


def memory_limit() -> int:
    text = os.environ.get(MEMORY_ENV)
    return parse_size(text) if text else physical_memory()


def check_memory(need: float, what: str, fix: str) -> None:
    """Refuse ``what`` (e.g. ``"remesh: about 3e12 vertices"``) when ``need`` bytes exceed the
    limit; ``fix`` says how to ask for less."""
    limit = memory_limit()
    if need > limit:
        raise UserError(f"{what} need about {format_bytes(need)} of memory, more than the limit "
                        f"of {format_bytes(limit)}; {fix}, or raise the limit with "
                        f"{MEMORY_ENV}=SIZE (e.g. 64G)")
