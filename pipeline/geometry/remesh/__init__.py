"""Uniform remeshing of a disk through its equiareal disk map (paper §8), with a quality pass.

Two entry points:

* :func:`uniform_remesh` — sample the map's image evenly, triangulate, locate, lift by
  eq. (1), improve; returns a :class:`RemeshResult`.
* :func:`improve_remesh` — the improvement pass alone, on a :class:`RemeshState` (a disk
  triangulation lifted onto the input surface).

Modules, one topic each: :mod:`.sampling` (disk samples and their triangulation),
:mod:`.state` (the lifted remesh), :mod:`.halfedge` (face and half-edge helpers),
:mod:`.sag` (how far an edge leaves the surface), :mod:`.flips`, :mod:`.relax`,
:mod:`.refine` (splits), :mod:`.collapse`, :mod:`.corners` (sharp input corners),
:mod:`.landmarks`, :mod:`.improve` (the schedule) and :mod:`.uniform` (the sequence).
"""

from .improve import improve_remesh
from .sampling import PATTERNS, DiskSamples
from .state import RemeshState
from .uniform import RemeshFailed, RemeshResult, uniform_remesh

__all__ = ["uniform_remesh", "improve_remesh", "RemeshFailed", "RemeshResult", "RemeshState", "DiskSamples",
           "PATTERNS"]
