"""The stage registry: the config schema, its stage checks, the input-file keys and the
subcommands' flags all derive from the stages' declarations (pipeline/stages/registry.py)."""

from __future__ import annotations

import re

import pytest
import yaml
from pydantic import BaseModel, Field, ValidationError

from conftest import REPO, run_cli
from pipeline.config import Config, config_model, format_validation_error
from pipeline.experiments.spec import INPUT_FILE_KEYS
from pipeline.stages.registry import STAGES, input_file_keys, plan
from pipeline.stages.stage import Section, Stage

CONFIGS = REPO / "configs"


def _keys(model: type[BaseModel]) -> set[str]:
    """Every key of a section, nested sections included."""
    out = set()
    for name, field in model.model_fields.items():
        out.add(name)
        for arg in (field.annotation, *getattr(field.annotation, "__args__", ())):
            if isinstance(arg, type) and issubclass(arg, BaseModel):
                out |= _keys(arg)
    return out


@pytest.mark.parametrize("stage", STAGES, ids=lambda s: s.name)
def test_every_key_of_a_stage_is_documented_in_its_yaml(stage):
    path = CONFIGS / f"{stage.name}.yaml"
    assert path.is_file(), f"configs/{stage.name}.yaml documents the '{stage.name}' section"
    text = path.read_text(encoding="utf-8")
    for section in (stage.section, *stage.extra_sections.values()):
        for key in _keys(section):
            assert re.search(rf"\b{key}:", text), f"configs/{stage.name}.yaml: '{key}' missing"


def test_run_config_has_one_section_per_stage_in_pipeline_order():
    fields = list(Config.model_fields)
    assert fields[0] == "run" and fields[-1] == "report"
    stage_fields = [f for f in fields if f in {s.name for s in STAGES}]
    assert stage_fields == [s.name for s in STAGES]
    assert "repair" in fields                       # owned by the input stage


def test_input_file_keys_come_from_the_stages():
    assert INPUT_FILE_KEYS == input_file_keys()
    assert set(INPUT_FILE_KEYS) == {"input.mesh", "remesh.landmarks", "register.source",
                                    "register.target", "register.source_landmarks",
                                    "register.target_landmarks", "register.truth"}


@pytest.mark.parametrize("data, ran", [
    ({"input": {"sample": {}}}, ["input", "parameterize"]),
    ({"input": {"sample": {}}, "remesh": {"vertices": 500}}, ["input", "parameterize", "remesh"]),
    ({"register": {"sample": True}}, ["register"]),
    ({"register": {"sample": True}, "morph": {}}, ["register", "morph"]),
    ({"morph": {"inputs": ["x"]}}, ["morph"]),          # morph from files needs no register
])
def test_plan_runs_given_stages_and_default_on_ones_whose_needs_are_met(data, ran):
    assert [s.name for s in plan(Config.model_validate(data))] == ran


@pytest.mark.parametrize("data, words", [
    ({"run": {"name": "x"}}, "give an 'input' or a 'register' section"),
    ({"morph": {}}, "'morph' needs a 'register' section (for its registration)"),
    ({"remesh": {"vertices": 500}}, "'remesh' needs an 'input' section (for its intake)"),
])
def test_missing_stage_sections_are_named(data, words):
    with pytest.raises(ValidationError) as exc:
        Config.model_validate(data)
    assert words in format_validation_error(exc.value, "x.yaml")


class _SmoothConfig(Section):
    steps: int = Field(3, ge=1)
    field_file: str | None = None


def test_a_new_stage_is_one_declaration():
    """A stage declared once gets its config section, its stage check and its input keys."""
    smooth = Stage(name="smooth", section=_SmoothConfig, run=lambda ctx: {"smoothed": 1},
                   write=lambda ctx, folder: {}, needs=("parameterization",),
                   makes=("smoothed",), input_files=("field_file",))
    stages = (*STAGES, smooth)
    model = config_model(stages)
    cfg = model.model_validate({"input": {"sample": {}}, "smooth": {"steps": 5}})
    assert [s.name for s in plan(cfg, stages)][-1] == "smooth" and cfg.smooth.steps == 5
    with pytest.raises(ValidationError, match="'smooth' needs an 'input' section"):
        model.model_validate({"register": {"sample": True}, "smooth": {}})
    with pytest.raises(ValidationError, match="greater than or equal to 1"):
        model.model_validate({"input": {"sample": {}}, "smooth": {"steps": 0}})
    assert "smooth.field_file" in input_file_keys(stages)


@pytest.mark.parametrize("flag, value, key", [
    ("--max-iter", "-1", "parameterize.max_iter"),
    ("--tol", "-1.0", "parameterize.tol"),
    ("--decimate", "2", "repair.decimate_to_faces"),
])
def test_cli_flags_and_yaml_keys_share_one_validation(tmp_path, flag, value, key):
    section, name = key.split(".")
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({"input": {"sample": {}},
                                   section: {name: yaml.safe_load(value)}}))
    code_yaml, _, err_yaml = run_cli("run", cfg, "--out", tmp_path / "o")
    code_cli, _, err_cli = run_cli("parameterize", "no_such_mesh.obj", "-o", tmp_path / "p",
                                   flag, value)
    assert code_yaml == code_cli == 2
    message = err_yaml.strip().split(f"{key}: ", 1)[1]
    assert err_cli.strip().endswith(f"{flag}: {message}"), (err_yaml, err_cli)


def test_subcommand_flags_are_derived_from_the_sections():
    from pipeline.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices
    assert {s.name for s in STAGES if s.command} == set(sub) - {"run", "experiment", "sample"}
    flags = {o for a in sub["remesh"]._actions for o in a.option_strings}
    # every remesh (remesh.improve's too), parameterize and repair key has a flag (booleans
    # as --x / --no-x)
    remesh = Config.model_fields["remesh"].annotation.__args__[0]
    for model in (remesh, remesh.model_fields["improve"].annotation.__args__[0],
                  Config.model_fields["parameterize"].annotation,
                  Config.model_fields["repair"].annotation):
        for name, field in model.model_fields.items():
            spelled = (field.json_schema_extra or {}).get("flag") or \
                "--" + name.replace("_", "-")
            assert spelled in flags or "--no-" + name.replace("_", "-") in flags, name


def test_a_nested_sections_flags_set_its_keys_and_clash_with_switching_it_off(tmp_path, capsys):
    """``--feature-angle-deg 0 --no-flips`` is ``remesh: {improve: {feature_angle_deg: 0,
    flips: false}}``; a bad value is named by its flag; ``--no-improve`` with one of its keys
    is one line, exit 2, and nothing written."""
    from pipeline.cli import build_parser, main, stage_config

    args = build_parser().parse_args(["remesh", "m.obj", "-o", "x", "--feature-angle-deg", "0",
                                      "--no-flips", "--vertices", "900"])
    assert stage_config("remesh", args)["remesh"] == {
        "vertices": 900, "improve": {"flips": False, "feature_angle_deg": 0.0}}
    args = build_parser().parse_args(["remesh", "m.obj", "-o", "x"])
    assert "improve" not in stage_config("remesh", args)["remesh"]
    out = tmp_path / "out"
    for extra, words in ((["--min-angle-deg", "-1"], "--min-angle-deg: Input should be"),
                         (["--no-improve", "--no-flips", "--min-angle-deg", "10"],
                          "--no-improve switches remesh.improve off, and --no-flips, "
                          "--min-angle-deg set part of it")):
        assert main(["remesh", "no_such_mesh.obj", "-o", str(out), *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and words in err, err
        assert not out.exists()
