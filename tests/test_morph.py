"""Morphing (pipeline.geometry.morph, pipeline.stages.morph) and the README's morph command."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
import pytest
from pydantic import ValidationError
from PIL import Image

from conftest import REPO
from pipeline.errors import UserError
from pipeline.geometry.morph import EASINGS, ease, frame_times, interpolate, morph_frames
from pipeline.stages.morph import MorphConfig, load_morph_inputs, morph_stage, write_morph


@pytest.mark.parametrize("easing", EASINGS)
def test_easings_start_at_0_end_at_1_and_increase(easing):
    s = np.linspace(0, 1, 101)
    t = ease(s, easing)
    assert t[0] == 0.0 and t[-1] == 1.0
    assert np.all(np.diff(t) > 0)
    times = frame_times(7, easing)
    assert len(times) == 7 and times[0] == 0.0 and times[-1] == 1.0


def test_easing_values():
    np.testing.assert_allclose(ease([0.25, 0.5], "ease-in-out"), [0.15625, 0.5])
    np.testing.assert_allclose(ease([0.5], "cosine"), [0.5])
    with pytest.raises(ValueError):
        ease(0.5, "bounce")


def test_frames_at_0_and_1_equal_source_and_registered():
    rng = np.random.default_rng(0)
    V0, V1 = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    for easing in EASINGS:
        times, frames = morph_frames(V0, V1, 5, easing)
        assert np.array_equal(frames[0], V0) and np.array_equal(frames[-1], V1)
    np.testing.assert_allclose(interpolate(V0, V1, 0.25), 0.75 * V0 + 0.25 * V1)


def test_gif_opens_with_k_frames(tmp_path, synthetic_face):
    a, b = synthetic_face(400, "neutral"), synthetic_face(400, "smile")
    m = morph_stage(a.V, b.V, a.F, MorphConfig(frames=5, easing="cosine", size=96))
    files = write_morph(m, tmp_path / "m")
    with Image.open(files["gif"]) as im:
        assert im.n_frames == 5 and im.size == (96, 96)
    assert len(list((tmp_path / "m" / "frames").glob("frame_*.obj"))) == 5
    with Image.open(files["filmstrip"]) as im:
        assert im.size[0] > im.size[1]
    V0, V1, F = load_morph_inputs([str(tmp_path / "m" / "frames" / "frame_000.obj"),
                                   str(tmp_path / "m" / "frames" / "frame_004.obj")])
    np.testing.assert_allclose(V0, a.V, atol=1e-12)
    np.testing.assert_allclose(V1, b.V, atol=1e-12)
    assert np.array_equal(F, a.F)


def test_bad_morph_input(tmp_path, synthetic_face):
    a = synthetic_face(400)
    with pytest.raises(ValidationError, match="greater than or equal to 2"):
        MorphConfig(frames=1)      # the section is the options: validated once, when made
    with pytest.raises(UserError, match="same connectivity"):
        morph_stage(a.V, a.V[:-1], a.F)
    with pytest.raises(UserError, match="not a registration folder"):
        load_morph_inputs([str(tmp_path)])


def test_readme_morph_command_runs_within_a_minute(tmp_path):
    readme = (REPO / "README.md").read_text()
    assert "sem-pipeline run configs/morph_sample.yaml" in readme
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "pipeline", "run", "configs/morph_sample.yaml",
                           "--out", str(tmp_path)], cwd=REPO, capture_output=True, text=True,
                          timeout=300, env=dict(os.environ, PYTHONPATH=str(REPO)))
    seconds = time.perf_counter() - t0
    assert proc.returncode == 0, proc.stderr
    assert seconds < 60, seconds
    run = tmp_path / "morph_sample"
    with Image.open(run / "morph" / "morph.gif") as im:
        assert im.n_frames == 16
        im.seek(15)
    assert len(list((run / "morph" / "frames").glob("*.obj"))) == 16
    assert (run / "register" / "registered.obj").is_file()
    assert (run / "manifest.json").is_file()
