"""The meshes a remesh report compares: each one's key, label and colour, and :class:`Method`
(a mesh with its measures), shared by the tables (:mod:`.remesh`) and the figures
(:mod:`.remesh_figures`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

LABELS = {
    "input": "input mesh",
    "sem_lifted": "SEM remesh, lifted only (paper §8)",
    "sem": "SEM remesh (ours, improved)",
    "pymeshlab_isotropic": "pymeshlab isotropic remeshing",
    "fast_simplification": "fast-simplification decimation",
}
COLORS = {"input": "0.45", "sem_lifted": "tab:cyan", "sem": "tab:blue",
          "pymeshlab_isotropic": "tab:orange", "fast_simplification": "tab:green"}


@dataclass
class Method:
    key: str
    V: np.ndarray | None
    F: np.ndarray | None
    seconds: float | None = None
    quality: dict = field(default_factory=dict)
    note: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.V is not None
