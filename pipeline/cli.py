"""Command line: ``sem-pipeline run CONFIG.yaml``, one subcommand per stage, ``experiment`` and
``sample``.

Thin by design. A stage's subcommand (``parameterize``, ``remesh``, ``register``, ``morph``)
turns its arguments into the same config that a YAML file gives: its flags are derived from the
config sections of the stage and of the stages it needs (:mod:`pipeline.stages.registry`), so a
flag and its YAML key share one schema, one default and one error message. The runner then runs
that config and writes only the subcommand's stage, into ``-o DIR``.

Bad input or configuration → one line on stderr, exit code 2; a method that failed (flipped
faces remain) → one line, exit code 1.
"""

from __future__ import annotations

import argparse
import sys
import types
import typing
from contextlib import contextmanager
from pathlib import Path

from . import __version__
from .errors import UserError


class _OneLineParser(argparse.ArgumentParser):
    def error(self, message):  # argparse's default prints the whole usage block
        raise UserError(f"{message}; see '{self.prog} --help'")


# ----------------------------------------------------------------------- flags from the schema


def _chain(stage) -> list:
    """The stages a subcommand runs: ``stage`` after the makers of what it needs. A stage
    whose needs depend on its section (``morph``) reads its positional inputs instead."""
    from .stages.registry import maker

    if stage.needs_when is not None:
        return [stage]
    out = []
    for need in stage.needs:
        out += [s for s in _chain(maker(need)) if s not in out]
    return out + [stage]


def _sections(stage) -> list[tuple[str, type, tuple[str, ...]]]:
    """``(section name, model, positional keys)`` whose fields become the subcommand's flags."""
    from .stages.registry import STAGES

    chain = _chain(stage)
    names: list[str] = []
    for s in chain:
        for name in [*s.extra_sections, s.name, *s.uses]:
            if name not in names:
                names.append(name)
    models = {"report": _report_model()}
    for s in STAGES:
        models.update(s.extra_sections)
        models[s.name] = s.section
    positional = {s.name: s.positional for s in chain}
    return [(n, models[n], positional.get(n, ())) for n in names]


def _report_model():
    from .config import ReportConfig
    return ReportConfig


def _unwrap(annotation):
    """``Optional[X]`` → ``X``."""
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) in (typing.Union, types.UnionType) and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        return rest[0] if len(rest) == 1 else annotation
    return annotation


def _nested_model(field):
    """The model of a nested section (``remesh.improve``), or None for a plain key."""
    from pydantic import BaseModel

    ann = _unwrap(field.annotation)
    return ann if isinstance(ann, type) and issubclass(ann, BaseModel) else None


def _option(key: str, field, default) -> str:
    """How a subcommand spells the config key ``key`` whose value is ``default`` unless given:
    the field's own ``flag``, or ``--key``; a boolean not off by default its own ``flag`` or
    ``--no-key`` (the flag can only switch it off)."""
    flag = (field.json_schema_extra or {}).get("flag")
    if _unwrap(field.annotation) is bool and default is not False:
        return flag or f"--no-{key.replace('_', '-')}"
    return flag or "--" + key.replace("_", "-")


def _add_field(parser, section: str, key: str, field, default=None) -> None:
    """The flag of the config key ``section.key`` (a dotted path); the keys of a nested
    section marked ``nested_flags`` get flags of their own (``remesh.improve.min_angle_deg``
    → ``--min-angle-deg``)."""
    ann = _unwrap(field.annotation)
    extra = field.json_schema_extra or {}
    dest = f"{section}.{key}"
    default = field.get_default(call_default_factory=True) if default is None else default
    help_text = field.description or ""
    if _nested_model(field) is not None:
        if default is not None:          # a nested section that can be switched off
            parser.add_argument(f"--no-{key.replace('_', '-')}", dest=dest,
                                action="store_const", const=None, default=argparse.SUPPRESS,
                                help=f"{help_text} (config: {dest}: false)".strip())
        if extra.get("nested_flags"):      # its keys as flags too (none of them taken)
            for sub, sub_field in _nested_model(field).model_fields.items():
                _add_field(parser, dest, sub, sub_field)
        return
    if ann is bool:
        parser.add_argument(_option(key, field, default), dest=dest, action="store_const",
                            const=not default,
                            default=argparse.SUPPRESS,
                            help=f"{help_text} (config: {dest}: {str(not default).lower()})")
        return
    kwargs = dict(dest=dest, default=argparse.SUPPRESS,
                  help=f"{help_text} (default {default}; config: {dest})".lstrip())
    if typing.get_origin(ann) is typing.Literal:
        kwargs["choices"] = list(typing.get_args(ann))
    elif ann in (int, float, str):
        kwargs["type"] = ann
    parser.add_argument(_option(key, field, default),
                        metavar=key.upper() if "choices" not in kwargs else None,
                        **kwargs)


def add_stage_parser(sub, stage) -> None:
    """The subcommand of ``stage``: positional inputs, ``-o DIR``, one flag per config key."""
    p = sub.add_parser(stage.name, help=stage.help)
    for section, model, positional in _sections(stage):
        for key in positional:
            ann = model.model_fields[key].annotation
            many = typing.get_origin(_unwrap(ann)) is list
            p.add_argument(key, metavar=key.upper(), nargs="+" if many else None,
                           help=model.model_fields[key].description)
    p.add_argument("-o", "--out", required=True, help="output folder")
    for section, model, positional in _sections(stage):
        for key, field in model.model_fields.items():
            if key not in positional:
                _add_field(p, section, key, field,
                           stage.command_defaults.get(f"{section}.{key}"))
    p.set_defaults(func=cmd_stage, stage=stage.name)


def stage_config(stage_name: str, args) -> dict:
    """The config data a subcommand's arguments stand for: what was given, and the stage's
    ``command_defaults`` for what was not."""
    from .stages.registry import stage as find

    stage = find(stage_name)
    data: dict = {}
    given = {**stage.command_defaults, **vars(args)}
    names = _flag_names(stage)
    for section, model, positional in _sections(stage):
        node = {key: given[key] for key in positional}
        try:
            node.update(_given_keys(given, (section,), model, names))
        except UserError as exc:
            raise UserError(f"sem-pipeline {stage_name}: {exc}") from None
        if node or section == stage.name:
            data[section] = node
    return data


def _given_keys(given: dict, path: tuple, model, names: dict) -> dict:
    """The keys of the section at ``path`` (of ``model``) that the arguments ``given`` set,
    nested sections as dicts of theirs; a nested section switched off (``--no-improve``) with
    some of its keys given is a user error."""
    node = {}
    for key, field in model.model_fields.items():
        dest = ".".join((*path, key))
        sub = _nested_model(field)
        inner = _given_keys(given, (*path, key), sub, names) if sub is not None else {}
        if dest in given and inner:
            spelled = ", ".join(names[(*path, key, k)] for k in inner)
            raise UserError(f"--no-{key.replace('_', '-')} switches {dest} off, and {spelled} "
                            f"set{'s' if len(inner) == 1 else ''} part of it: give one or the "
                            "other")
        if dest in given:
            node[key] = given[dest]
        elif inner:
            node[key] = inner
    return node


def _flag_names(stage) -> dict[tuple, str]:
    """Config key → how the subcommand spells it (``('remesh', 'vertices')`` → ``--vertices``,
    ``('remesh', 'improve', 'flips')`` → ``--flips``)."""
    out = {}

    def spell(path, model, positional=()):
        for key, field in model.model_fields.items():
            out[(*path, key)] = key.upper() if key in positional else \
                _option(key, field, field.get_default(call_default_factory=True))
            if _nested_model(field) is not None:
                spell((*path, key), _nested_model(field))

    for section, model, positional in _sections(stage):
        spell((section,), model, positional)
    return out


def cmd_stage(args) -> int:
    from pydantic import ValidationError

    from .config import Config, format_validation_error
    from .runner import run_command
    from .stages.registry import stage as find

    stage = find(args.stage)
    prog = f"sem-pipeline {stage.name}"
    try:
        config = Config.model_validate(stage_config(stage.name, args))
    except ValidationError as exc:
        raise UserError(format_validation_error(exc, prog, names=_flag_names(stage))) from None
    positional = [getattr(args, k) for _, _, keys in _sections(stage) for k in keys]
    label = Path(str(positional[0][0] if isinstance(positional[0], list) else positional[0])).name
    ctx, files = run_command(config, stage.name, args.out, label)
    print(f"{args.out}: {stage.summary(ctx, files)}")
    return 0


# ------------------------------------------------------------------------ the other commands


def _check_out(value: str | None) -> None:
    if value is not None and not value.strip():
        raise UserError("--out: empty path; give a folder name or leave --out out")


def cmd_run(args) -> int:
    from .config import load_config
    from .runner import run_config

    _check_out(args.out)
    config, base = load_config(args.config)
    run_dir = run_config(config, base, args.out, config_file=args.config)
    print(f"{run_dir}: done (open {run_dir / 'index.html'}; manifest {run_dir / 'manifest.json'})")
    return 0


def cmd_experiment(args) -> int:
    from .experiments.execute import run_experiment
    from .experiments.spec import load_experiment

    _check_out(args.out)
    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be at least 1 (got {args.workers})")
    exp = load_experiment(args.config)
    out = run_experiment(exp, args.out, workers=args.workers, scheduler=args.scheduler,
                         retry_failed=args.retry_failed)
    print(f"{out.run_dir}: {len(exp.items)} items: {len(out.ran)} ran ({out.backend}), "
          f"{len(out.skipped)} skipped, {len(out.failed)} failed; summary "
          f"{out.summary[1] if out.summary else '-'}")
    for item_id in out.failed:
        print(f"failed: {item_id}: {out.records.get(item_id, {}).get('error')}")
    return 1 if out.failed else 0


def cmd_sample(args) -> int:
    from pydantic import ValidationError

    from .config import format_validation_error
    from .io.outputs import check_output_folder
    from .sample import write_sample
    from .stages.load import SampleInput

    try:
        SampleInput(vertices=args.vertices)
    except ValidationError as exc:
        raise UserError(format_validation_error(exc, "sem-pipeline sample", SampleInput,
                                                {("vertices",): "--vertices"})) from None
    check_output_folder(args.out, 1 << 20, flag="-o", replace=False)
    paths = write_sample(args.out, n_vertices=args.vertices)
    print("\n".join(str(p) for p in paths.values()))
    return 0


def build_parser() -> argparse.ArgumentParser:
    from .stages.registry import STAGES

    parser = _OneLineParser(prog="sem-pipeline", description=(
        "Equiareal disk parameterizations by Stretch Energy Minimization, and the stages "
        "built on them."))
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_OneLineParser)

    run = sub.add_parser("run", help="run the stages a YAML config names")
    run.add_argument("config", help="YAML config (see configs/)")
    run.add_argument("--out", help="output root instead of the config's run.out_dir")
    run.set_defaults(func=cmd_run)

    for stage in STAGES:
        if stage.command:
            add_stage_parser(sub, stage)

    exp = sub.add_parser("experiment", help="run a config over a dataset and a parameter sweep "
                                            "(cached, resumable; process pool or Dask)")
    exp.add_argument("config", help="experiment YAML (see configs/experiment_*.yaml)")
    exp.add_argument("--out", help="output root instead of the config's run.out_dir")
    exp.add_argument("--workers", type=int, default=None,
                     help="local worker processes (default: experiment.workers, else cores); "
                          "1 runs the items in this process")
    exp.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="run on the Dask cluster at ADDRESS (tcp://host:8786), or 'local' "
                          "for a Dask LocalCluster of --workers processes")
    exp.add_argument("--retry-failed", action="store_true",
                     help="also re-run items that failed on bad input with unchanged inputs")
    exp.set_defaults(func=cmd_experiment)

    smp = sub.add_parser("sample", help="write the embedded synthetic face meshes")
    smp.add_argument("-o", "--out", required=True)
    smp.add_argument("--vertices", type=int, default=6000)
    smp.set_defaults(func=cmd_sample)
    return parser


def _os_error(exc: OSError) -> str:
    """A file system error (a full disk, no permission, a read-only file system) as one line."""
    import errno

    where = f" '{exc.filename}'" if exc.filename else ""
    fix = {errno.ENOSPC: "free some space or choose another output folder",
           errno.EDQUOT: "free some space or choose another output folder",
           errno.EACCES: "check the permissions or choose another folder",
           errno.EPERM: "check the permissions or choose another folder",
           errno.EROFS: "choose a folder on a writable file system"}.get(
        exc.errno, "check the path and the file system")
    return f"cannot access{where}: {exc.strerror or exc}; {fix}"


class _Terminated(KeyboardInterrupt):
    """SIGTERM: unwinds like Ctrl-C, so the build folder is removed and the lock released."""


def _on_sigterm(signum, frame):
    raise _Terminated()


#: OpenBLAS threads of NumPy and SciPy in a command, unless ``OPENBLAS_NUM_THREADS`` is set:
#: their dense operations here are small (per-face 2×2 and 3×2 matrices), and OpenBLAS's idle
#: workers spin between them (0.2 s of CPU in a 5k remesh of a small mesh, for no gain in wall
#: time); the sparse solves thread through MKL (:mod:`.geometry.solvers`), which this leaves
#: alone. Processes the command starts (an experiment's workers) inherit the setting
OPENBLAS_THREADS = "1"

#: glibc ``malloc`` settings of a command (``mallopt``), unless a ``MALLOC_*`` variable sets
#: its own: blocks up to 32 MiB (the most glibc's own sliding limit reaches) from the heap,
#: not each from its own ``mmap``, and freed heap memory given back to the system only past
#: 256 MiB at its top. The arrays of a remesh are freed and made again step after step; with
#: glibc's defaults each came back from the system as fresh pages (a page fault per page)
MALLOC_OPTIONS = {-3: 32 << 20,          # M_MMAP_THRESHOLD
                  -1: 256 << 20}         # M_TRIM_THRESHOLD


def keep_freed_memory() -> bool:
    """Apply :data:`MALLOC_OPTIONS` through glibc's ``mallopt``; False where there is no
    glibc ``mallopt`` (another C library or system) or a ``MALLOC_*`` variable is set."""
    import ctypes
    import os

    if not sys.platform.startswith("linux") or any(k.startswith("MALLOC_") for k in os.environ):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    return all(mallopt(option, value) == 1 for option, value in MALLOC_OPTIONS.items())


#: NumPy submodules that NumPy itself imports only on first use (through its module
#: ``__getattr__``) and a remesh does not use, but that SciPy's array-API layer loads with
#: ``scipy.sparse`` (it copies NumPy's whole namespace, which looks each of them up):
#: ``numpy.f2py`` (and ``charset_normalizer`` with it), ``numpy.testing`` (``unittest``),
#: ``numpy.polynomial`` (the sample surface's quadrature); about 0.08 s of CPU in every
#: command. (``numpy.ma`` is not among them: SciPy's Delaunay triangulation uses it.)
DEFERRED_MODULES = ("numpy.f2py", "numpy.testing", "numpy.polynomial")


def _lazy_spec(spec):
    """``spec`` with its loader wrapped in :class:`importlib.util.LazyLoader`, or None for a
    spec without a loader that can run lazily."""
    import importlib.util

    if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
        return None
    spec.loader = importlib.util.LazyLoader(spec.loader)
    return spec


def defer_imports(names) -> list[str]:
    """Make each module of ``names`` (dotted names whose parent package can be imported) a
    lazy module (:class:`importlib.util.LazyLoader`): registered in ``sys.modules`` and on its
    parent package, its code run on the first access to one of its attributes, so a module
    only looked up costs nothing and one used works as usual. A module already imported, or
    one that does not exist, is left as it is. Returns the names made lazy."""
    import importlib.util

    out = []
    for name in names:
        if name in sys.modules:
            continue
        try:
            spec = _lazy_spec(importlib.util.find_spec(name))
        except (ImportError, ValueError):
            continue
        if spec is None:
            continue
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        parent, _, child = name.rpartition(".")
        if parent:
            setattr(sys.modules[parent], child, module)
        out.append(name)
    return out


#: Subpackages that SciPy's own packages import in their ``__init__`` and a command does not
#: use, made lazy when first imported (:func:`defer_submodules`): ``scipy.spatial.transform``
#: (rotations; ``scipy.spatial`` imports it beside the Delaunay triangulation and the KD-tree
#: the remesh uses), about 0.015 s of CPU in every command.
DEFERRED_SUBMODULES = ("scipy.spatial.transform",)


class _LazyWhenImported:
    """A finder on ``sys.meta_path`` (ahead of the others) that answers for each of ``names``
    once: the spec the other finders give, run lazily (:func:`_lazy_spec`). The import
    system registers the module in ``sys.modules`` and on its package as usual; its code
    runs on the first access to one of its attributes."""

    def __init__(self, names):
        self.names = set(names)

    def find_spec(self, name, path=None, target=None):
        import importlib.machinery

        if name not in self.names:
            return None
        self.names.discard(name)
        return _lazy_spec(importlib.machinery.PathFinder.find_spec(name, path, target))


def defer_submodules(names) -> list[str]:
    """Make each module of ``names`` (dotted names) not yet imported a lazy module when it is
    first imported (:class:`_LazyWhenImported`), without importing its package now (what
    :func:`defer_imports` does); for modules a package imports by name (``from . import x``)
    and does not use while it loads. Returns the names that will be lazy."""
    out = [name for name in names if name not in sys.modules]
    if out:
        sys.meta_path.insert(0, _LazyWhenImported(out))
    return out


#: The SciPy versions whose modules of :data:`_DOC_KEPT_MODULES` are known to use numpydoc's
#: ``FunctionDoc`` only as :class:`_DocKept` answers it.
_DOC_KEPT_SCIPY = ("1.17.",)

#: SciPy's modules whose decorators re-write the docstrings of the functions they mark while
#: SciPy loads: ``scipy._lib._array_api`` (``xp_capabilities``: a table of the array backends
#: appended to the notes) and ``scipy._lib._util`` (``_apply_over_batch``: a note on batched
#: arguments appended to the extended summary; ``_transition_to_rng``: the ``rng`` parameter's
#: entry re-worded).
_DOC_KEPT_MODULES = ("scipy._lib._array_api", "scipy._lib._util")


class _DocKept:
    """Stands in for numpydoc's ``FunctionDoc`` in the decorators of :data:`_DOC_KEPT_MODULES`,
    whose only uses of it are ``doc = FunctionDoc(f)``, a line appended to one of its
    sections (``doc[section].append(...)``), the names of its parameters read
    (``doc["Parameters"]``; none here, so the entry is left as it is) and ``str(doc)`` less
    its first line (the signature): gives back ``f``'s docstring as it is, unparsed."""

    def __init__(self, func, *args, **kwargs):
        self._doc = func.__doc__ or ""

    def __getitem__(self, section):
        return []

    def __str__(self):
        return "\n" + self._doc


@contextmanager
def scipy_docstrings_kept():
    """While the block runs (the command's imports), SciPy's docstring-writing decorators
    (:data:`_DOC_KEPT_MODULES`) leave each function's docstring as it is (:class:`_DocKept`)
    instead of parsing it and adding their notes: about 230 docstrings parsed when
    ``scipy.sparse``, ``scipy.spatial`` and ``scipy.special`` load, 0.07 s of CPU in every
    command, for help texts a command never shows. Only with SciPy not yet imported and of a
    version in :data:`_DOC_KEPT_SCIPY`; anything else, and SciPy's own parser afterwards, as
    SciPy has it. (:func:`entry` imports again, with SciPy's parser, if the imports under the
    stand-in fail: the modules that failed are not kept, those done keep their docstrings.)"""
    import importlib

    patched = []
    if "scipy" not in sys.modules:
        try:
            import scipy

            if scipy.__version__.startswith(_DOC_KEPT_SCIPY):
                for name in _DOC_KEPT_MODULES:
                    module = importlib.import_module(name)
                    patched.append((module, module.FunctionDoc))
                    module.FunctionDoc = _DocKept
        except (ImportError, AttributeError):
            pass
    try:
        yield
    finally:
        for module, original in patched:
            module.FunctionDoc = original


def entry() -> None:
    """The console command (``sem-pipeline``, ``python -m pipeline``): OpenBLAS on
    :data:`OPENBLAS_THREADS` threads, ``malloc`` keeping freed memory
    (:func:`keep_freed_memory`), the unused NumPy submodules of :data:`DEFERRED_MODULES`
    lazy (:func:`defer_imports`), and the SciPy ones of :data:`DEFERRED_SUBMODULES`
    (:func:`defer_submodules`); the modules every command imports (:mod:`.runner`: NumPy,
    SciPy, pydantic, the stages) imported without SciPy's docstring notes
    (:func:`scipy_docstrings_kept`) and with the cyclic garbage collector paused,
    and what they made then frozen (``gc.freeze``: left out of every later collection);
    then :func:`main`, then :func:`exit_now` with its exit code. (Imports make objects that
    all stay alive: the collector's ~150 passes over them while they are made find nothing
    and cost about 0.03 s of CPU, and once it is back on, its first pass would go over all of
    them again, 0.03–0.05 s, for nothing as well.)"""
    import gc
    import os

    if "numpy" not in sys.modules:             # OpenBLAS reads it when NumPy loads it
        os.environ.setdefault("OPENBLAS_NUM_THREADS", OPENBLAS_THREADS)
    keep_freed_memory()
    gc.disable()
    try:
        defer_imports(DEFERRED_MODULES)
        defer_submodules(DEFERRED_SUBMODULES)
        try:
            with scipy_docstrings_kept():
                from . import runner  # noqa: F401
        except Exception:   # a SciPy whose decorators ask more of the stand-in: SciPy's own way
            from . import runner  # noqa: F401,F811
    finally:
        gc.freeze()
        gc.enable()
    exit_now(main())


def exit_now(code: int) -> None:
    """End the process with ``code`` once the work is done: the standard streams flushed and
    the ``atexit`` handlers run, as at a normal exit, but without the interpreter's teardown,
    which frees every module, array and library one by one (about 0.08 s of CPU after a
    remesh, where the process ends anyway). A normal exit with Python threads other than the
    main one still running (it waits for them) or under a profiler or tracer (``python -m
    cProfile``, coverage: they write their results at the normal exit)."""
    import atexit
    import os
    import threading

    if threading.active_count() > 1 or sys.getprofile() is not None \
            or sys.gettrace() is not None:
        sys.exit(code)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):       # a closed pipe or stream: nothing more to show
            pass
    atexit._run_exitfuncs()
    os._exit(code)


def main(argv=None) -> int:
    import signal
    import threading

    from .runner import METHOD_FAILURES

    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _on_sigterm) if main_thread else None
    try:
        args = build_parser().parse_args(argv)
        return args.func(args)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return UserError.exit_code
    except METHOD_FAILURES as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"error: {_os_error(exc)}", file=sys.stderr)
        return UserError.exit_code
    except MemoryError:
        print("error: out of memory; ask for less (fewer vertices, frames or a smaller "
              "input) or run on a machine with more memory", file=sys.stderr)
        return UserError.exit_code
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, previous)
