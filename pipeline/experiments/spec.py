"""Experiment configs: a single-run config plus a dataset and a parameter sweep → work items.

An experiment YAML is an ordinary ``sem-pipeline run`` config (``run``, ``input``, ``repair``,
``parameterize``, ``remesh``, ``register``, ``morph``, ``report``: the *base* of every item) with
three more top-level sections, all optional::

    experiment:                 # how to run (the CLI's --workers / --scheduler override it)
      workers: null             # local process pool size (default: the machine's cores)
      scheduler: null           # a Dask scheduler address, e.g. tcp://10.0.0.5:8786
    dataset:                    # exactly one of:
      meshes: data/*.obj        #   a glob or a list (of paths or globs) → input.mesh
      # pairs:                  #   source/target face pairs → register.*
      #   - {source: a.obj, target: b.obj, source_landmarks: a.json, target_landmarks: b.json}
      # faces:                  #   every ordered pair (A → B, A ≠ B) of these faces → register.*
      #   meshes: faces/*.obj
      #   landmarks: faces/landmarks.json      # one file for all, or "faces/{stem}.json"
      #   shared_connectivity: true            # vertex i ↔ i: the target is the truth
    sweep:                      # dotted config key → list of values (cartesian product)
      parameterize.max_iter: [10, 100]
      remesh.vertices: [5000, 20000]

Each item is the base with its dataset entry and one combination of sweep values applied,
validated with the single-run :class:`~pipeline.config.Config` (so every one-line error of
``sem-pipeline run`` applies to every item, prefixed with the item's id). Item ids are readable
and unique: ``<dataset entry>__<key>=<value>__…``, e.g. ``choi_human_face__remesh.vertices=5000``
(``base`` when there is neither a dataset nor a sweep). A dataset entry is the mesh's file stem,
or ``<source>-to-<target>`` for pairs (``name`` overrides it); for ``faces`` the words that all
face names share are dropped (``ict_A_neutral_holes`` → ``A_neutral``). Paths are relative to the experiment
file's folder and are made absolute in the items. ``run.name``/``run.out_dir`` name the
experiment's folder: ``<out_dir>/<name>/<item id>/``.
"""

from __future__ import annotations

import copy
import difflib
import glob
import hashlib
import itertools
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, \
    model_validator

from ..config import Config, RunConfig, format_validation_error, read_yaml_mapping, resolve_path
from ..errors import UserError
from ..stages.registry import input_file_keys

__all__ = ["ExperimentConfig", "Item", "Experiment", "load_experiment", "expand_experiment",
           "INPUT_FILE_KEYS"]

# Config keys that name input files (each stage's ``Stage.input_files``): made absolute in the
# items and hashed by content. (Any other string value that names an existing file is hashed by
# content too; see cache.py.)
INPUT_FILE_KEYS = input_file_keys()

EXPERIMENT_KEYS = ("experiment", "dataset", "sweep")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class ExecutionConfig(_Strict):
    workers: Optional[int] = Field(None, ge=1, le=1024)
    scheduler: Optional[str] = None     # Dask scheduler address; null: local process pool


class PairEntry(_Strict):
    source: str
    target: str
    source_landmarks: str
    target_landmarks: Optional[str] = None   # default: source_landmarks
    truth: Optional[str] = None
    name: Optional[str] = None                # item id prefix (default "<source>-to-<target>")


class FacesDataset(_Strict):
    meshes: Union[str, list[str]]
    landmarks: str                            # one file, or a "{stem}" template
    shared_connectivity: bool = False         # vertex i ↔ i in all faces: target = ground truth


class DatasetConfig(_Strict):
    meshes: Union[str, list[str], None] = None
    pairs: Optional[list[PairEntry]] = None
    faces: Optional[FacesDataset] = None

    @model_validator(mode="after")
    def _one_kind(self):
        given = [k for k in ("meshes", "pairs", "faces") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of 'meshes' (a glob or list), 'pairs' (source/"
                             "target entries) or 'faces' (all ordered pairs)"
                             + (f"; got {', '.join(given)}" if given else ""))
        return self


class ExperimentConfig(_Strict):
    """The experiment-only sections (the rest of the file is the items' base config)."""

    experiment: ExecutionConfig = ExecutionConfig()
    dataset: Optional[DatasetConfig] = None
    sweep: dict[str, list[Any]] = Field(default_factory=dict)

    @field_validator("sweep")
    @classmethod
    def _sweep(cls, sweep):
        for key, values in sweep.items():
            if not re.fullmatch(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)+", key):
                raise ValueError(f"sweep key '{key}' must be a dotted config key such as "
                                 f"'parameterize.max_iter'")
            if key.split(".")[0] == "run":
                raise ValueError(f"sweep key '{key}': 'run' names the experiment's folder; "
                                 f"sweep a stage setting instead")
            if not values:
                raise ValueError(f"sweep key '{key}' has no values; give a non-empty list")
        return sweep


@dataclass
class Item:
    """One work item: a full single-run config and where its row comes from."""

    id: str
    config: Config
    params: dict[str, Any] = field(default_factory=dict)   # dataset names + sweep values

    def data(self) -> dict:
        """The config as plain JSON data (what the worker validates again and runs)."""
        return self.config.model_dump(mode="json")


@dataclass
class Experiment:
    source: Path               # the experiment YAML
    base: Path                 # folder that relative paths of the items use
    name: str
    out_dir: str
    settings: ExperimentConfig
    items: list[Item]

    def run_dir(self, out_root: str | Path | None = None) -> Path:
        return Path(out_root if out_root else self.out_dir) / self.name


# ------------------------------------------------------------------------------- loading


def load_experiment(path: str | Path) -> Experiment:
    """Read an experiment YAML and expand it into validated items (one-line errors)."""
    path = Path(path)
    return expand_experiment(read_yaml_mapping(path), path.resolve().parent, str(path))


def expand_experiment(data: dict, base: Path, source: str = "experiment") -> Experiment:
    """Expand parsed experiment data (paths relative to ``base``) into items."""
    valid = list(Config.model_fields) + list(EXPERIMENT_KEYS)
    for key in data:
        if key not in valid:
            close = difflib.get_close_matches(str(key), valid, n=1)
            hint = f"did you mean '{close[0]}'?" if close else f"valid keys: {', '.join(valid)}"
            raise UserError(f"{source}: {key}: unknown key; {hint}")
    try:
        settings = ExperimentConfig.model_validate({k: data[k] for k in EXPERIMENT_KEYS
                                                    if k in data and data[k] is not None})
    except ValidationError as exc:
        raise UserError(format_validation_error(exc, source, ExperimentConfig)) from None
    template = {k: copy.deepcopy(v) for k, v in data.items() if k not in EXPERIMENT_KEYS}
    try:
        run = RunConfig.model_validate(template.get("run") or {})
    except ValidationError as exc:
        raise UserError(format_validation_error(exc, f"{source}: run", RunConfig)) from None

    entries = _dataset_entries(settings.dataset, base, source)
    dataset_keys = {k for _, sets, _ in entries for k in sets}
    for key in settings.sweep:
        clash = next((d for d in dataset_keys if key == d or key.startswith(d + ".")), None)
        if clash:
            raise UserError(f"{source}: sweep.{key}: the dataset sets '{clash}' for every item; "
                            f"list the values in the dataset instead")
    keys = list(settings.sweep)
    combos = list(itertools.product(*(settings.sweep[k] for k in keys)))

    items, seen = [], set()
    for prefix, sets, names in entries:
        for combo in combos:
            item_data = copy.deepcopy(template)
            for dotted, value in sets.items():
                _set_key(item_data, dotted, value, source)
            for dotted, value in zip(keys, combo):
                _set_key(item_data, dotted, value, source)
            parts = ([prefix] if prefix else []) + [f"{k}={_fmt(v)}" for k, v in zip(keys, combo)]
            item_id = _unique(_sanitize("__".join(parts) or "base"), seen)
            item_data["run"] = {"name": item_id, "out_dir": str(Path(run.out_dir) / run.name)}
            _absolutize(item_data, base)
            try:
                config = Config.model_validate(item_data)
            except ValidationError as exc:
                raise UserError(format_validation_error(exc, f"{source}: item '{item_id}'")) \
                    from None
            items.append(Item(item_id, config, dict(names, **dict(zip(keys, combo)))))
    return Experiment(Path(source), base, run.name, run.out_dir, settings, items)


# ------------------------------------------------------------------------------- datasets


def _files(patterns: str | list[str], base: Path, where: str) -> list[Path]:
    """Paths of a glob or list (entries may be globs). A pattern that matches nothing is a
    config error, and so is an empty list; a literal path that does not exist is kept (its
    item fails, the rest run)."""
    if not patterns:
        raise UserError(f"{where}: no mesh given; give a glob or a list of paths")
    out: list[Path] = []
    for pattern in [patterns] if isinstance(patterns, str) else patterns:
        full = resolve_path(pattern, base)
        if glob.has_magic(str(full)):
            found = sorted(Path(p) for p in glob.glob(str(full)) if Path(p).is_file())
            if not found:
                raise UserError(f"{where}: pattern '{pattern}' matches no file (looked in "
                                f"'{full.parent}'); fix the pattern")
            out.extend(found)
        else:
            out.append(full)
    seen: set = set()
    return [p for p in out if not (p in seen or seen.add(p))]


def _names(paths: list[Path]) -> list[str]:
    """Short readable names: the file stem, with its folder when two stems are equal."""
    stems = [p.stem for p in paths]
    return [f"{p.parent.name}_{p.stem}" if stems.count(p.stem) > 1 else p.stem for p in paths]


def _trim_common(names: list[str]) -> list[str]:
    """Drop the prefix and suffix (whole ``_``/``-`` separated words) that all names share:
    ``ict_A_neutral_holes``, ``ict_B_smile_holes`` → ``A_neutral``, ``B_smile``."""
    if len(names) < 2:
        return names
    split = [re.split(r"(?<=[_-])", n) for n in names]       # words keep their separator
    pre = 0
    while all(len(w) > pre + 1 for w in split) and len({w[pre] for w in split}) == 1:
        pre += 1
    suf = 0
    while all(len(w) > pre + suf + 1 for w in split) and \
            len({"".join(w[len(w) - suf - 1:]) for w in split}) == 1 and \
            all(w[len(w) - suf - 2].endswith(("_", "-")) for w in split):
        suf += 1
    out = ["".join(w[pre:len(w) - suf]).rstrip("_-") for w in split]
    return out if all(out) and len(set(out)) == len(out) else names


def _dataset_entries(ds: DatasetConfig | None, base: Path, source: str):
    """``[(id prefix, {dotted key: value}, {summary column: name})]``, one per dataset entry."""
    if ds is None:
        return [("", {}, {})]
    if ds.meshes is not None:
        paths = _files(ds.meshes, base, f"{source}: dataset.meshes")
        return [(name, {"input": {"mesh": str(p)}}, {"mesh": name})
                for name, p in zip(_names(paths), paths)]
    if ds.pairs is not None:
        if not ds.pairs:
            raise UserError(f"{source}: dataset.pairs: no pair given; give a list of "
                            f"source/target entries")
        out = []
        for k, e in enumerate(ds.pairs):
            src, tgt = resolve_path(e.source, base), resolve_path(e.target, base)
            s_name, t_name = Path(e.source).stem, Path(e.target).stem
            out.append((e.name or f"{s_name}-to-{t_name}", _register_keys(
                src, tgt, resolve_path(e.source_landmarks, base),
                resolve_path(e.target_landmarks, base) if e.target_landmarks else None,
                resolve_path(e.truth, base) if e.truth else None),
                {"source": s_name, "target": t_name}))
        return out
    f = ds.faces
    paths = _files(f.meshes, base, f"{source}: dataset.faces.meshes")
    if len(paths) < 2:
        raise UserError(f"{source}: dataset.faces.meshes: {len(paths)} face(s) found; all "
                        f"ordered pairs need at least 2")
    names = _trim_common(_names(paths))

    def landmarks(p: Path) -> Path:
        try:
            return resolve_path(f.landmarks.format(stem=p.stem), base)
        except (KeyError, IndexError, ValueError):
            raise UserError(f"{source}: dataset.faces.landmarks: '{f.landmarks}' is neither a "
                            f"file nor a template with '{{stem}}'") from None

    out = []
    for (i, a), (j, b) in itertools.permutations(enumerate(paths), 2):
        la, lb = landmarks(a), landmarks(b)
        out.append((f"{names[i]}-to-{names[j]}",
                    _register_keys(a, b, la, lb if lb != la else None,
                                   b if f.shared_connectivity else None),
                    {"source": names[i], "target": names[j]}))
    return out


def _register_keys(src, tgt, src_lm, tgt_lm, truth) -> dict:
    values = {"source": src, "target": tgt, "source_landmarks": src_lm,
              "target_landmarks": tgt_lm, "truth": truth}
    return {f"register.{k}": None if v is None else str(v) for k, v in values.items()}


# ------------------------------------------------------------------------------- helpers


def _set_key(data: dict, dotted: str, value, source: str) -> None:
    """``data[a][b][c] = value`` for ``dotted = "a.b.c"`` (a whole mapping for one part)."""
    if "." not in dotted:
        data[dotted] = copy.deepcopy(value)
        return
    *parents, last = dotted.split(".")
    node = data
    for k, part in enumerate(parents):
        child = node.get(part)
        if child is None:
            child = node[part] = {}
        elif not isinstance(child, dict):
            raise UserError(f"{source}: {'.'.join(parents[:k + 1])}: expected a mapping of "
                            f"settings to set '{dotted}', got {type(child).__name__}")
        node = child
    node[last] = copy.deepcopy(value)


def _absolutize(data: dict, base: Path) -> None:
    """Make the known input-file keys absolute (the item config runs from anywhere)."""
    for dotted in INPUT_FILE_KEYS:
        section, key = dotted.split(".")
        node = data.get(section)
        if isinstance(node, dict) and isinstance(node.get(key), str):
            node[key] = os.path.realpath(resolve_path(node[key], base))


def _fmt(value) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return format(value, "g")
    if isinstance(value, (dict, list)):
        return json.dumps(value, separators=(",", ":"), sort_keys=True)
    return str(value)


def _sanitize(text: str, limit: int = 120) -> str:
    """A folder name: letters, digits and ``._=+-``; long ids keep a hash of the full text."""
    safe = re.sub(r"[^A-Za-z0-9._=+\-]+", "_", text).lstrip(".") or "item"
    if len(safe) > limit:
        safe = safe[:limit - 9] + "~" + hashlib.sha1(text.encode()).hexdigest()[:8]
    return safe


def _unique(item_id: str, seen: set) -> str:
    out, k = item_id, 2
    while out.lower() in seen:          # case-insensitive file systems
        out, k = f"{item_id}~{k}", k + 1
    seen.add(out.lower())
    return out
