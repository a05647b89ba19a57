"""YAML run configuration: schema, safe loading, and one-line errors.

A config names an input (a mesh file or the embedded synthetic sample) and configures each
stage. It is read with ``yaml.safe_load`` and validated by the pydantic models below
(``extra="forbid"``), so an unknown key, a wrong type or a missing file is one line naming the
key, e.g. ``config.yaml: parameterize.max_iters: unknown key; did you mean 'max_iter'?``.
Input paths are relative to the config file's folder; ``run.out_dir`` to the working directory. The documented example of every key is
``configs/parameterize.yaml``.
"""

from __future__ import annotations

import difflib
import warnings
from pathlib import Path
from typing import Literal, Optional

import yaml
from pydantic import (BaseModel, ConfigDict, Field, ValidationError, field_validator,
                      model_validator)

from .errors import UserError


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class RunConfig(_Strict):
    name: str = Field("run", description="outputs go to <out_dir>/<name>/")
    out_dir: str = "outputs"          # relative to the working directory


class SampleInput(_Strict):
    vertices: int = Field(6000, ge=300, le=1_000_000)
    expression: Literal["neutral", "smile", "jawopen"] = "neutral"
    identity: int = 0


class InputConfig(_Strict):
    mesh: Optional[str] = None
    sample: Optional[SampleInput] = None

    @model_validator(mode="after")
    def _one_source(self):
        if (self.mesh is None) == (self.sample is None):
            raise ValueError("give exactly one of 'mesh' (a file) or 'sample' (the embedded face)")
        return self


class RepairConfig(_Strict):
    weld: bool = True
    weld_tolerance: float = Field(1e-9, ge=0.0)
    keep_largest_component: bool = False
    close_holes: bool = False
    split_leaf_faces: bool = True
    decimate_to_faces: Optional[int] = Field(None, ge=4)


class ParameterizeConfig(_Strict):
    mode: Literal["paper", "converged"] = "converged"
    max_iter: Optional[int] = Field(None, ge=0)
    tol: float = Field(1e-7, gt=0.0)
    patience: int = Field(20, ge=1)
    inversion: bool = False
    solver: Literal["auto", "cholmod", "scipy"] = "auto"


class ReportConfig(_Strict):
    figures: bool = True


class ImproveConfig(_Strict):
    """Quality pass after lifting (``pipeline.geometry.remesh_improve``); ``improve: false``
    turns it off (the paper's plain lift), ``improve: true`` means these defaults."""

    flips: bool = True                       # Delaunay flips on the lifted surface
    relax_iterations: int = Field(2, ge=0, le=50)     # tangential relaxation steps
    relax_step: float = Field(0.5, gt=0.0, le=1.0)
    max_dihedral_deg: float = Field(20.0, ge=0.0, le=90.0)   # flip only flatter quads
    refine_sag: float = Field(0.2, ge=0.0)   # split edges farther than this × spacing from
    refine_budget: float = Field(0.3, ge=0.0, le=1.0)   # the surface (≤ this × vertices)
    corner_angle_deg: float = Field(30.0, ge=0.0)   # keep input corners sharper than this


class RemeshConfig(_Strict):
    """Uniform remeshing through the SEM map (``sem-pipeline remesh``); see
    ``configs/remesh.yaml``. Give ``vertices`` or ``spacing`` (target edge length in the mesh's
    units)."""

    vertices: Optional[int] = Field(None, ge=100, le=5_000_000)
    spacing: Optional[float] = Field(None, gt=0.0)
    pattern: Literal["hexagonal", "blue_noise", "concentric"] = "hexagonal"
    rim_relax: int = Field(3, ge=0, le=50)   # ODT sweeps of the lattice band along the rim
    seed: int = 0                            # blue noise
    improve: Optional[ImproveConfig] = ImproveConfig()
    compare: bool = True                     # pymeshlab + decimation at the same vertex count
    report: bool = True                      # report.html + figures
    landmarks: Optional[str] = None          # JSON {name: input vertex index}, relative path
    distance_samples: int = Field(200_000, ge=1000)   # random samples per surface (distances)

    @field_validator("improve", mode="before")
    @classmethod
    def _improve_flag(cls, v):
        if v is True:
            return {}
        if v is False:
            return None
        return v

    @model_validator(mode="after")
    def _count_or_spacing(self):
        if (self.vertices is None) == (self.spacing is None):
            raise ValueError("give exactly one of 'vertices' (a count) or 'spacing' (a target "
                             "edge length in the mesh's units)")
        return self


class RegisterConfig(_Strict):
    """Landmark registration of a source face onto a target face (``sem-pipeline register``).

    Either ``sample: true`` (the embedded synthetic face, neutral → ``sample_expression``; the
    target is also the ground truth) or the four files. Paths are relative to the config file.
    The meshes go through the ``repair`` section (``close_holes`` for eye/mouth openings) and
    the ``parameterize`` section's SEM options."""

    sample: bool = False
    sample_vertices: int = Field(3000, ge=300, le=200_000)
    sample_expression: Literal["smile", "jawopen"] = "smile"
    source: Optional[str] = None
    target: Optional[str] = None
    source_landmarks: Optional[str] = None
    target_landmarks: Optional[str] = None   # default: source_landmarks (one file for both)
    landmark_set: Optional[str] = None       # JSON key, e.g. ibug68
    truth: Optional[str] = None              # ground truth with the source's connectivity
    mobius: bool = False
    energy: Literal["biharmonic", "harmonic"] = "biharmonic"
    baseline: bool = False

    @model_validator(mode="after")
    def _inputs(self):
        files = (self.source, self.target, self.source_landmarks)
        if self.sample and any(f is not None for f in files + (self.truth,)):
            raise ValueError("give either 'sample: true' or the files (source, target, "
                             "source_landmarks), not both")
        if not self.sample and any(f is None for f in files):
            raise ValueError("give 'source', 'target' and 'source_landmarks' (and "
                             "'target_landmarks' if they differ), or 'sample: true'")
        return self


class MorphConfig(_Strict):
    """Morph from the source to its registered image (needs a ``register`` section)."""

    frames: int = Field(24, ge=2, le=2000)
    easing: Literal["linear", "ease-in-out", "cosine"] = "ease-in-out"
    frame_ms: int = Field(80, ge=10, le=10_000)   # GIF frame duration
    size: int = Field(480, ge=64, le=2048)        # GIF frame size, pixels


with warnings.catch_warnings():
    # The YAML key 'register' shadows only ABCMeta.register, which is never called on Config.
    warnings.filterwarnings("ignore", message='Field name "register"', category=UserWarning)

    class Config(_Strict):
        run: RunConfig = RunConfig()
        input: Optional[InputConfig] = None       # required unless 'register' is given
        repair: RepairConfig = RepairConfig()
        parameterize: ParameterizeConfig = ParameterizeConfig()
        report: ReportConfig = ReportConfig()
        register: Optional[RegisterConfig] = None
        morph: Optional[MorphConfig] = None
        remesh: Optional[RemeshConfig] = None     # runs after parameterize (needs 'input')

        @model_validator(mode="after")
        def _stages(self):
            if self.input is None and self.register is None:
                raise ValueError("give an 'input' (mesh or sample) or a 'register' section")
            if self.remesh is not None and self.input is None:
                raise ValueError("'remesh' needs an 'input' (mesh or sample) to remesh")
            if self.morph is not None and self.register is None:
                raise ValueError("'morph' needs a 'register' section (it morphs the source into "
                                 "its registered image)")
            return self


def _model_fields(model: type[BaseModel], loc: tuple) -> list[str]:
    """Valid key names at the location of an error (for 'did you mean')."""
    for part in loc[:-1]:
        field = model.model_fields.get(part) if isinstance(part, str) else None
        if field is None:
            return []
        ann = field.annotation
        ann = next((a for a in getattr(ann, "__args__", ()) if isinstance(a, type)
                    and issubclass(a, BaseModel)), ann)
        if not (isinstance(ann, type) and issubclass(ann, BaseModel)):
            return []
        model = ann
    return list(model.model_fields)


def format_validation_error(exc: ValidationError, source: str,
                            model: type[BaseModel] | None = None) -> str:
    """The first error of a pydantic validation as one line naming the key and the fix
    (``model``: the validated model, for the 'did you mean' hint; default :class:`Config`)."""
    err = exc.errors()[0]
    loc = tuple(err["loc"])
    where = ".".join(str(p) for p in loc) or "(top level)"
    if err["type"] == "extra_forbidden":
        valid = _model_fields(model or Config, loc)
        close = difflib.get_close_matches(str(loc[-1]), valid, n=1)
        hint = f"did you mean '{close[0]}'?" if close else f"valid keys: {', '.join(valid)}"
        return f"{source}: {where}: unknown key; {hint}"
    if err["type"] == "missing":
        return f"{source}: {where}: required key is missing"
    given = err.get("input")
    given = "" if isinstance(given, dict) else f" (got {given!r})"
    return f"{source}: {where}: {err['msg']}{given}"


def load_config(path: str | Path) -> tuple[Config, Path]:
    """Read and validate a YAML config; returns it with the folder that relative paths use."""
    path = Path(path)
    data = read_yaml_mapping(path)
    try:
        config = Config.model_validate(data)
    except ValidationError as exc:
        raise UserError(format_validation_error(exc, str(path))) from None
    base = path.resolve().parent
    check_input_files(config, base, str(path))
    return config, base


def read_yaml_mapping(path: Path) -> dict:
    """The top-level mapping of a YAML file (``yaml.safe_load``); one-line errors."""
    if not path.is_file():
        raise UserError(f"config file '{path}' not found; pass the path to a YAML file "
                        f"(examples in configs/)")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or "not valid YAML"
        raise UserError(f"{path}: malformed YAML{at}: {problem}; fix the syntax") from None
    except UnicodeDecodeError:
        raise UserError(f"{path}: not a UTF-8 text file; pass a YAML config") from None
    if not isinstance(data, dict):
        raise UserError(f"{path}: expected a mapping of stage names to settings at the top level, "
                        f"got {type(data).__name__}; see configs/parameterize.yaml")
    return data


def check_input_files(config: Config, base: Path, source: str) -> None:
    """One-line error for the first input file of ``config`` that does not exist."""
    if config.input is not None and config.input.mesh is not None:
        mesh = resolve_path(config.input.mesh, base)
        if not mesh.is_file():
            raise UserError(f"{source}: input.mesh: file '{mesh}' not found; "
                            f"paths are relative to the config's folder")
    if config.register is not None:
        for key in ("source", "target", "source_landmarks", "target_landmarks", "truth"):
            value = getattr(config.register, key)
            if value is not None and not resolve_path(value, base).is_file():
                raise UserError(f"{source}: register.{key}: file '{resolve_path(value, base)}' "
                                f"not found; paths are relative to the config's folder")


def resolve_path(value: str, base: Path) -> Path:
    p = Path(value).expanduser()
    return p if p.is_absolute() else (base / p)
