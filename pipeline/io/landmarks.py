"""Landmark files: reading, pairing source with target, and mapping onto the repaired mesh.

Accepted files (indices are 0-based vertex indices of the *input* mesh file):

* ``.json`` — ``{"landmarks": {name: index, ...}}`` (as ``ict_landmarks.json``),
  ``{"landmarks": [index, ...]}``, a top-level list ``[index, ...]`` or a top-level mapping
  ``{name: index}``. With ``key`` another entry of the top-level mapping is used instead of
  ``"landmarks"``, e.g. ``key="ibug68_0based_vertex_indices"``; ``key="ibug68"`` is a short name
  for it (the 68-point iBUG set of ``ict_landmarks.json``). A value may also be a 3D point
  ``[x, y, z]`` instead of an index.
* ``.csv`` / ``.txt`` — one landmark per line: ``index``, ``x y z`` (a 3D point), or either of
  them preceded by a name (``nose_tip, 4857``). Separators are commas, semicolons, tabs or
  spaces; ``#`` starts a comment; a first line without numbers is a header and is skipped.

Both may start with a UTF-8 byte order mark (as Windows editors save them); it is skipped.

3D points are snapped to the nearest vertex of the mesh (:func:`repaired_indices`), and the
snapping distance is reported; a point more than :data:`MAX_SNAP` bounding-box diagonals away
is an error. A name given twice (in a JSON object or a table) is an error. Every problem is a one-line :class:`~pipeline.errors.UserError`.

Pairing (:func:`pair_landmarks`): by name when both sets are named, else by order.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import UserError, file_problem

__all__ = ["LandmarkSet", "KEY_ALIASES", "MAX_SNAP", "parse_json", "read_landmarks",
           "landmarks_from_dict", "pair_landmarks", "repaired_indices", "resolve_landmarks"]

# A point landmark farther from the mesh than this many bounding-box diagonals is an error
# (points of another mesh or in other units), not a landmark to snap.
MAX_SNAP = 1.0

# Largest vertex index read: it is stored as int64.
_MAX_INDEX = np.iinfo(np.int64).max

KEY_ALIASES = {"ibug68": "ibug68_0based_vertex_indices", "ibug": "ibug68_0based_vertex_indices",
               "named": "landmarks"}


@dataclass
class LandmarkSet:
    """Landmarks as given: each one a vertex index of the input mesh *or* a 3D point.

    ``indices[k]`` is −1 where landmark ``k`` is a point (``points[k]`` then holds it).
    ``names`` is ``None`` for an unnamed (ordered) set.
    """

    indices: np.ndarray                 # int64 k, −1 for a point landmark
    points: np.ndarray                  # float64 k×3, NaN rows for index landmarks
    names: list[str] | None
    source: str = ""
    messages: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.indices)

    def label(self, k: int) -> str:
        return f"'{self.names[k]}'" if self.names else f"#{k}"

    def subset(self, order) -> "LandmarkSet":
        order = np.asarray(order, dtype=np.int64)
        names = [self.names[i] for i in order] if self.names else None
        return LandmarkSet(self.indices[order], self.points[order], names, self.source,
                           list(self.messages))


def _is_point(v) -> bool:
    return (isinstance(v, (list, tuple)) and len(v) == 3
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v))


def _entries(values, names, where: str) -> LandmarkSet:
    idx, pts = [], []
    for k, v in enumerate(values):
        what = f"landmark '{names[k]}'" if names else f"landmark #{k}"
        if isinstance(v, bool):
            v = None
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        if isinstance(v, int):
            if v < 0:
                raise UserError(f"{where}: {what} has a negative vertex index {v}; "
                                f"use 0-based vertex indices")
            if v > _MAX_INDEX:
                raise UserError(f"{where}: {what} has the vertex index {v}, beyond any mesh; "
                                f"use 0-based vertex indices")
            idx.append(v)
            pts.append([np.nan] * 3)
        elif _is_point(v):
            if not np.all(np.isfinite(v)):
                raise UserError(f"{where}: {what} has a NaN/inf coordinate; fix the file")
            idx.append(-1)
            pts.append([float(x) for x in v])
        else:
            raise UserError(f"{where}: {what} is {v!r}; give a 0-based vertex index or an "
                            f"[x, y, z] point")
    if not idx:
        raise UserError(f"{where}: no landmarks found; give at least 3")
    return LandmarkSet(np.asarray(idx, dtype=np.int64), np.asarray(pts, dtype=np.float64)
                       .reshape(-1, 3), names, where)


def landmarks_from_dict(data, where: str = "landmarks", key: str | None = None) -> LandmarkSet:
    """Landmarks from already-parsed JSON data (see the module docstring for the layouts)."""
    if key is not None:
        if not isinstance(data, dict):
            raise UserError(f"{where}: landmark set '{key}' requested but the file holds a "
                            f"list, not a mapping; drop the landmark-set option")
        real = KEY_ALIASES.get(key, key)
        if real not in data:
            sets = [k for k, v in data.items() if isinstance(v, (list, dict)) and v
                    and (all(isinstance(x, int) for x in v) if isinstance(v, list)
                         else all(isinstance(x, int) or _is_point(x) for x in v.values()))]
            raise UserError(f"{where}: no landmark set '{key}'; available: "
                            f"{', '.join(sets) or 'none'}")
        data = data[real]
    elif isinstance(data, dict) and "landmarks" in data:
        data = data["landmarks"]
    if isinstance(data, dict):
        if not data:
            raise UserError(f"{where}: the landmark mapping is empty; give at least 3")
        bad = [k for k, v in data.items() if not (isinstance(v, int) or _is_point(v))]
        if bad:
            raise UserError(f"{where}: entry '{bad[0]}' is not a vertex index or an [x, y, z] "
                            f"point; put landmarks under a 'landmarks' key or pass a landmark "
                            f"set name")
        return _entries(list(data.values()), [str(k) for k in data], where)
    if isinstance(data, list):
        return _entries(data, None, where)
    raise UserError(f"{where}: expected a list of vertex indices or a mapping name → index, "
                    f"got {type(data).__name__}")


class _DuplicateKey(ValueError):
    pass


def _unique_pairs(pairs: list) -> dict:
    seen = set()
    for key, _ in pairs:
        if key in seen:
            raise _DuplicateKey(key)
        seen.add(key)
    return dict(pairs)


def parse_json(text: str, where: str) -> object:
    """JSON of a landmark file; a key given twice in one object (``json`` keeps the last
    silently) and a syntax error are one-line errors."""
    try:
        return json.loads(text.removeprefix("\ufeff"), object_pairs_hook=_unique_pairs)
    except _DuplicateKey as exc:
        raise UserError(f"{where}: name '{exc}' appears twice; landmark names must be "
                        f"unique") from None
    except json.JSONDecodeError as exc:
        raise UserError(f"{where}: not valid JSON (line {exc.lineno}: {exc.msg}); "
                        f"fix the file") from None
    except RecursionError:
        raise UserError(f"{where}: nested too deeply to read (lists or objects inside each "
                        f"other thousands of levels down); fix the file") from None


_SPLIT = re.compile(r"[,;\t ]+")


def _number(tok: str):
    try:
        x = float(tok)
    except ValueError:
        return None
    return x if np.isfinite(x) else None


def _read_table(path: Path) -> LandmarkSet:
    where = str(path)
    names, values = [], []
    lines = path.read_text(encoding="utf-8-sig").splitlines()
    for lineno, line in enumerate(lines, 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        toks = [t.strip().strip('"\'') for t in _SPLIT.split(line) if t.strip()]
        nums = [_number(t) for t in toks]
        if all(x is None for x in nums) and not values:
            continue                                            # header line
        name = None
        if nums and nums[0] is None:
            name, toks, nums = toks[0], toks[1:], nums[1:]
        if any(x is None for x in nums) or len(nums) not in (1, 3):
            raise UserError(f"{where}:{lineno}: expected 'index', 'x y z' or a name followed by "
                            f"one of them, got '{line}'")
        if len(nums) == 1:
            if not float(nums[0]).is_integer():
                raise UserError(f"{where}:{lineno}: vertex index {toks[0]} is not an integer")
            values.append(int(nums[0]))
        else:
            values.append([float(x) for x in nums])
        names.append(name)
    if not values:
        raise UserError(f"{where}: no landmarks found; one index or 'x y z' per line")
    named = [n is not None for n in names]
    if any(named) and not all(named):
        raise UserError(f"{where}: some lines are named and some are not; name all or none")
    return _entries(values, names if all(named) else None, where)


def read_landmarks(path, key: str | None = None) -> LandmarkSet:
    """Read a landmark file (``.json``, ``.csv``, ``.txt``); see the module docstring."""
    path = Path(path)
    problem = file_problem(path, missing="not found")
    if problem:
        raise UserError(f"landmark file '{path}' {problem}; check the path")
    ext = path.suffix.lower()
    try:
        if ext == ".json":
            lms = landmarks_from_dict(parse_json(path.read_text(encoding="utf-8"), str(path)),
                                      str(path), key)
        elif ext in (".csv", ".txt"):
            if key is not None:
                raise UserError(f"{path}: a landmark set name ('{key}') only applies to JSON "
                                f"files; drop it")
            lms = _read_table(path)
        else:
            raise UserError(f"unsupported landmark file '{path.name}'; use .json, .csv or .txt")
    except UnicodeDecodeError:
        raise UserError(f"{path}: not a UTF-8 text file; pass a JSON, CSV or TXT file") from None
    if lms.names is not None and len(set(lms.names)) != len(lms.names):
        dup = next(n for n in lms.names if lms.names.count(n) > 1)
        raise UserError(f"{path}: landmark name '{dup}' appears twice; names must be unique")
    return lms


def pair_landmarks(source: LandmarkSet, target: LandmarkSet) -> tuple[LandmarkSet, LandmarkSet]:
    """The two sets in corresponding order: by name when both are named, else by order."""
    if source.names is not None and target.names is not None:
        s, t = set(source.names), set(target.names)
        if s != t:
            only_s, only_t = sorted(s - t), sorted(t - s)
            parts = []
            if only_s:
                parts.append(f"only in the source: {', '.join(only_s[:5])}"
                             + (" …" if len(only_s) > 5 else ""))
            if only_t:
                parts.append(f"only in the target: {', '.join(only_t[:5])}"
                             + (" …" if len(only_t) > 5 else ""))
            raise UserError(f"landmark names differ ({'; '.join(parts)}); use sets with the "
                            f"same names")
        pos = {n: k for k, n in enumerate(target.names)}
        return source, target.subset([pos[n] for n in source.names])
    if len(source) != len(target):
        raise UserError(f"{len(source)} source landmarks but {len(target)} target landmarks; "
                        f"unnamed landmarks are paired by order, so give the same number")
    return source, target


def repaired_indices(lms: LandmarkSet, mesh, n_input: int, label: str = "landmarks"
                     ) -> tuple[np.ndarray, list[str]]:
    """Vertex indices of the landmarks in the *repaired* mesh, and report lines.

    ``mesh`` is a :class:`~pipeline.geometry.repair.RepairedMesh` (``source_index`` maps each
    repaired vertex to its input vertex, −1 for added ones); ``n_input`` is the input vertex
    count. Index landmarks are mapped through ``source_index``; point landmarks are snapped to
    the nearest repaired vertex. Refused with a :class:`UserError`: an index out of range, a
    vertex the repair removed, and a point more than :data:`MAX_SNAP` bounding-box diagonals
    from the mesh.

    Returns
    -------
    indices : (k,) int64
        The repaired vertex of each landmark, in the set's order.
    messages : list of str
        A line on the snapping when there are point landmarks.
    """
    from ..geometry.repair import repaired_vertex_of

    inverse = repaired_vertex_of(np.asarray(mesh.source_index, dtype=np.int64), n_input)
    out = np.empty(len(lms), dtype=np.int64)
    messages = []
    snapped = []
    for k in range(len(lms)):
        i = int(lms.indices[k])
        if i >= 0:
            if i >= n_input:
                raise UserError(f"{label}: landmark {lms.label(k)} is vertex {i} but the mesh has "
                                f"{n_input} vertices (0-based indices); check the file pairing")
            j = int(inverse[i])
            if j < 0:
                raise UserError(f"{label}: landmark {lms.label(k)} (vertex {i}) was removed by "
                                f"the mesh repair (welded, unreferenced or decimated); pick "
                                f"another vertex")
            out[k] = j
        else:
            d = np.linalg.norm(mesh.V - lms.points[k], axis=1)
            j = int(np.argmin(d))
            out[k] = j
            snapped.append(float(d[j]))
    if snapped:
        diag = float(np.linalg.norm(mesh.V.max(axis=0) - mesh.V.min(axis=0)))
        far = int(np.argmax(snapped))
        if snapped[far] > MAX_SNAP * diag:
            k = int(np.flatnonzero(lms.indices < 0)[far])
            raise UserError(f"{label}: point landmark {lms.label(k)} is {snapped[far]:.4g} from "
                            f"the mesh, {snapped[far] / diag:.3g} bounding-box diagonals (more "
                            f"than {MAX_SNAP:g}); check its units and the mesh it belongs to")
        messages.append(f"{label}: snapped {len(snapped)} point landmarks to the nearest vertex "
                        f"(distance max {max(snapped):.4g}, mean {np.mean(snapped):.4g}; "
                        f"{max(snapped) / diag:.2e} of the bounding-box diagonal)")
    return out, messages


def resolve_landmarks(lms: LandmarkSet, mesh, n_input: int, label: str = "landmarks"
                      ) -> tuple[np.ndarray, list[str]]:
    """Vertex indices of the landmarks in the *repaired* mesh, and report lines, for a
    registration: :func:`repaired_indices`, and every landmark an interior vertex of the input
    of its own. Refused with a :class:`UserError`, besides :func:`repaired_indices`' refusals:
    a vertex the repair added (hole centres, split midpoints), a vertex on the disk's boundary
    or on the rim of a closed hole, and two landmarks on one vertex.
    """
    out, messages = repaired_indices(lms, mesh, n_input, label)
    n = len(mesh.V)
    src = np.asarray(mesh.source_index, dtype=np.int64)
    added = np.zeros(n, bool)
    added[np.asarray(mesh.added_vertices, dtype=np.int64)] = True
    on_boundary = np.zeros(n, bool)
    on_boundary[np.asarray(mesh.boundary, dtype=np.int64)] = True
    on_hole = np.zeros(n, bool)
    for hole in mesh.closed_holes:
        on_hole[np.asarray(hole["loop"], dtype=np.int64)] = True
    for k, j in enumerate(out):
        what = f"{label}: landmark {lms.label(k)}"
        if added[j]:
            raise UserError(f"{what} is on vertex {j}, which the repair added (a hole centre or a "
                            f"split midpoint), not a vertex of the input; pick an input vertex")
        if on_hole[j]:
            raise UserError(f"{what} (input vertex {src[j]}) is on the rim of a hole that "
                            f"close_holes filled; landmarks must be interior vertices, move it "
                            f"off the rim")
        if on_boundary[j]:
            raise UserError(f"{what} (input vertex {src[j]}) is on the mesh boundary, which "
                            f"stays on the circle; landmarks must be interior vertices")
    uniq, counts = np.unique(out, return_counts=True)
    if (counts > 1).any():
        j = int(uniq[np.argmax(counts > 1)])
        ks = [lms.label(k) for k in np.flatnonzero(out == j)]
        raise UserError(f"{label}: landmarks {' and '.join(ks[:2])} are on the same vertex "
                        f"{src[j]}; every landmark needs its own vertex")
    return out, messages
