"""YAML run configuration: schema, safe loading, and one-line errors.

A config has one section per stage (each stage module declares its model; the registry in
:mod:`pipeline.stages.registry` lists them), plus ``run`` (name and output folder) and ``report``.
It is read with a safe YAML loader that refuses a duplicated key, and validated by those models
(``extra="forbid"``, no NaN or infinite numbers), so an unknown key, a wrong type or a missing
file is one line naming the key, e.g.
``config.yaml: parameterize.max_iters: unknown key; did you mean 'max_iter'?``. Input paths are
relative to the config file's folder; ``run.out_dir`` to the working directory. Every key is
documented in ``configs/<stage>.yaml``.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Optional

from pydantic import (BaseModel, ConfigDict, Field, ValidationError, create_model,
                      field_validator, model_validator)

from .errors import UserError, file_problem
from .stages.registry import STAGES, input_file_keys, mesh_file_keys, plan
from .stages.stage import Section, Stage


class RunConfig(Section):
    name: str = Field("run", description="outputs go to <out_dir>/<name>/")
    out_dir: str = "outputs"          # relative to the working directory

    @field_validator("name")
    @classmethod
    def _plain_name(cls, name: str) -> str:
        """A folder name inside ``out_dir``: no separators, no ``.``/``..``, not empty."""
        if not name.strip() or name in (".", "..") or any(c in name for c in "/\\\0") \
                or name != name.strip():
            raise ValueError("must be a plain folder name (no '/', '\\', '..', surrounding "
                             "spaces or empty name); put folders into run.out_dir or --out")
        return name

    @field_validator("out_dir")
    @classmethod
    def _some_folder(cls, out_dir: str) -> str:
        """Not empty or blank (``.`` is the working directory)."""
        if not out_dir.strip():
            raise ValueError("empty folder; give one ('.' for the working directory) or "
                             "leave the key out (default 'outputs')")
        return out_dir


class ReportConfig(Section):
    figures: bool = Field(True, description="figures and report pages (false: numbers only)")


def config_model(stages: tuple[Stage, ...] = STAGES) -> type[BaseModel]:
    """The run config's model: ``run``, every stage's section (``None`` unless given, or its
    defaults for a default-on stage) and the sections it owns besides, and ``report``. Its
    validator checks that every given stage gets what it needs (:func:`plan`)."""
    fields: dict = {"run": (RunConfig, RunConfig())}
    for s in stages:
        for name, model in s.extra_sections.items():
            fields[name] = (finite(model), finite(model)())
        section = finite(s.section)
        fields[s.name] = (section, section()) if s.default_on else (Optional[section], None)
    fields["report"] = (ReportConfig, ReportConfig())

    def check_stages(self):
        plan(self, stages)           # raises ValueError naming the missing section
        return self

    with warnings.catch_warnings():
        # The YAML key 'register' shadows only ABCMeta.register, never called on a config.
        warnings.filterwarnings("ignore", message='Field name "register"', category=UserWarning)
        return create_model("Config", __base__=Section, __doc__="A run config: every section.",
                            __validators__={"_stages": model_validator(mode="after")(
                                check_stages)}, **fields)


def finite(model: type[BaseModel]) -> type[BaseModel]:
    """``model``, or a subclass of it that refuses NaN and infinite numbers when ``model``
    allows them (a kernel's options model such as ``SEMOptions``: in a config, ``tol: .inf``
    is a mistake like ``tol: -1``). Instances are instances of ``model``."""
    if model.model_config.get("allow_inf_nan") is False:
        return model
    return type(model.__name__, (model,), {
        "model_config": ConfigDict(**{**model.model_config, "allow_inf_nan": False}),
        "__module__": model.__module__, "__doc__": model.__doc__,
        "__qualname__": model.__qualname__})


Config = config_model()


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
                            model: type[BaseModel] | None = None,
                            names: dict[tuple, str] | None = None) -> str:
    """The first error of a pydantic validation as one line naming the key and the fix
    (``model``: the validated model, for the 'did you mean' hint; default :class:`Config`;
    ``names``: how a command line spells a key, ``('remesh', 'vertices')`` → ``--vertices``,
    a nested section's ``('remesh', 'improve', 'flips')`` → ``--flips``)."""
    err = exc.errors()[0]
    loc = tuple(err["loc"])
    names = names or {}
    where = names.get(loc[:3]) or names.get(loc[:2]) or ".".join(str(p) for p in loc) \
        or "(top level)"
    if err["type"] == "extra_forbidden":
        import difflib

        valid = _model_fields(model or Config, loc)
        close = difflib.get_close_matches(str(loc[-1]), valid, n=1)
        hint = f"did you mean '{close[0]}'?" if close else f"valid keys: {', '.join(valid)}"
        return f"{source}: {where}: unknown key; {hint}"
    if err["type"] == "missing":
        return f"{source}: {where}: required key is missing"
    given = err.get("input")
    given = "" if isinstance(given, dict) else f" (got {given!r})"
    msg = err["msg"].removeprefix("Value error, ")
    return f"{source}: {where}: {msg}{given}"


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


def _strict_loader():
    """``yaml.SafeLoader`` that refuses a key given twice in one mapping (the safe loader
    keeps the last silently). Made on first use: a subcommand reads no YAML and does not
    import PyYAML."""
    import yaml

    class StrictLoader(yaml.SafeLoader):
        def construct_mapping(self, node, deep=False):
            seen = set()
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=True)
                try:
                    duplicate = key in seen
                except TypeError:            # an unhashable key: the base class reports it
                    break
                if duplicate:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"key '{key}' is given twice in one mapping",
                        key_node.start_mark)
                seen.add(key)
            return super().construct_mapping(node, deep)

    return StrictLoader


def read_yaml_mapping(path: Path) -> dict:
    """The top-level mapping of a YAML file (:func:`_strict_loader`: safe, no duplicated
    keys); one-line errors."""
    import yaml

    problem = file_problem(path, missing="not found")
    if problem:
        raise UserError(f"config file '{path}' {problem}; pass the path to a YAML file "
                        f"(examples in configs/)")
    try:
        data = yaml.load(path.read_text(encoding="utf-8"), Loader=_strict_loader())
    except OSError as exc:
        raise UserError(f"cannot read config '{path}': {exc.strerror}; check the path and "
                        f"permissions") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or "not valid YAML"
        raise UserError(f"{path}: malformed YAML{at}: {problem}; fix the syntax") from None
    except UnicodeDecodeError:
        raise UserError(f"{path}: not a UTF-8 text file; pass a YAML config") from None
    except RecursionError:
        raise UserError(f"{path}: nested too deeply to read (lists or mappings inside each "
                        f"other thousands of levels down); fix the syntax") from None
    if not isinstance(data, dict):
        raise UserError(f"{path}: expected a mapping of stage names to settings at the top level, "
                        f"got {type(data).__name__}; see configs/parameterize.yaml")
    return data


def check_input_files(config, base: Path, source: str) -> None:
    """One-line error for the first input file of ``config`` that does not exist (every key
    that a stage declares in ``Stage.input_files``) or, for a mesh file
    (``Stage.mesh_files``), whose suffix is not a supported mesh format."""
    from .io.meshio import format_problem

    meshes = mesh_file_keys()
    for dotted in input_file_keys():
        section, key = dotted.split(".")
        node = getattr(config, section)
        value = None if node is None else getattr(node, key)
        if value is None:
            continue
        path = resolve_path(value, base)
        unsupported = format_problem(path) if dotted in meshes else None
        if unsupported:
            raise UserError(f"{source}: {dotted}: {unsupported}")
        problem = file_problem(path, missing="not found")
        if problem:
            raise UserError(f"{source}: {dotted}: file '{path}' {problem}; paths are "
                            f"relative to the config's folder")


def resolve_path(value: str, base: Path) -> Path:
    p = Path(value).expanduser()
    return p if p.is_absolute() else (base / p)
