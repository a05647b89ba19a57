"""A scan's noise level (pipeline.geometry.noise) and the remesher's tolerances that follow it
(improve.noise_tolerances): measured on constructed grids with normal noise of known size;
a noisy input finer than the remesh is remeshed without chasing its noise."""

from __future__ import annotations

from statistics import NormalDist

import numpy as np
import pytest

from pipeline.geometry.noise import LEVEL_PER_SIGMA, noise_beyond, noise_level, umbrella_offsets
from pipeline.geometry.remesh.improve import NOISE_FOLLOW_SHARE, NOISE_SAG, noise_tolerances
from remesh_helpers import remesh_map


def grid(k: int, height) -> tuple[np.ndarray, np.ndarray]:
    """A k×k grid of unit spacing, two faces per cell, lifted by ``height(x, y)``."""
    x, y = (a.ravel().astype(float) for a in np.meshgrid(np.arange(k), np.arange(k)))
    i = (np.arange(k - 1)[:, None] * k + np.arange(k - 1)[None, :]).ravel()
    F = np.vstack([np.column_stack([i, i + 1, i + k + 1]), np.column_stack([i, i + k + 1, i + k])])
    return np.column_stack([x, y, height(x, y)]), F


def noisy_paraboloid(k: int, sigma: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The paraboloid ``z = 0.004 ((x − k/2)² + 0.6 (y − k/2)²)`` on a k×k unit grid, each
    vertex moved along the surface's normal by N(0, sigma²) (seeded)."""
    V, F = grid(k, lambda x, y: 0.004 * ((x - k / 2) ** 2 + 0.6 * (y - k / 2) ** 2))
    normal = np.column_stack([-0.008 * (V[:, 0] - k / 2), -0.0048 * (V[:, 1] - k / 2),
                              np.ones(len(V))])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    noise = np.random.default_rng(seed).normal(0.0, sigma, len(V))
    return V + normal * noise[:, None], F


def test_a_flat_grid_has_no_umbrella_offset_and_no_noise():
    V, F = grid(20, lambda x, y: np.zeros_like(x))
    assert np.abs(umbrella_offsets(V, F)).max() == 0.0
    assert noise_level(V, F) == 0.0


def test_a_smooth_paraboloid_has_a_noise_level_near_zero():
    """Its umbrella offsets are about 0.004 (curvature × spacing² / 4) and the same at
    neighbours: what is left is rounding and the grid's two diagonals."""
    V, F = noisy_paraboloid(60, 0.0, seed=0)
    assert np.median(np.abs(umbrella_offsets(V, F))) > 1e-3
    assert noise_level(V, F) < 1e-6


@pytest.mark.parametrize("sigma", [0.01, 0.3])
def test_the_noise_level_of_normal_noise_is_its_share_of_sigma(sigma):
    """Normal noise on a 120×120 grid: the level is LEVEL_PER_SIGMA × sigma within 5 %."""
    V, F = noisy_paraboloid(120, sigma, seed=1)
    assert noise_level(V, F) / sigma == pytest.approx(LEVEL_PER_SIGMA, rel=0.05)


def test_noise_beyond_is_the_normal_quantile():
    """One σ is exceeded (either side) by 31.7 % of the points, two by 4.55 %."""
    one, two = (2 * (1 - NormalDist().cdf(z)) for z in (1.0, 2.0))
    assert noise_beyond(LEVEL_PER_SIGMA, one) == pytest.approx(1.0, abs=1e-9)
    assert noise_beyond(2 * LEVEL_PER_SIGMA, two) == pytest.approx(4.0, abs=1e-9)
    assert noise_beyond(0.0, 0.1) == 0.0


def test_the_noise_floors_only_where_the_input_is_finer_than_the_remesh():
    """Noise 0.3 on a 100×100 grid: remeshed at 10,000 vertices or more, no floor; at 2,500,
    NOISE_SAG × the level and the size NOISE_FOLLOW_SHARE × 2,500 of its ~60,000 points
    exceed (about 3.7 σ)."""
    V, F = noisy_paraboloid(100, 0.3, seed=2)
    assert noise_tolerances(V, F, len(V)) == (0.0, 0.0)
    level = noise_level(V, F)
    sag, follow = noise_tolerances(V, F, 2500)
    assert sag == NOISE_SAG * level
    share = NOISE_FOLLOW_SHARE * 2500 / (6 * len(V))
    assert follow == noise_beyond(level, share)
    assert 3.5 < follow / (level / LEVEL_PER_SIGMA) < 3.9


@pytest.mark.timeout(120)
def test_a_noisy_scan_finer_than_the_remesh_is_remeshed_without_chasing_its_noise():
    """The noisy paraboloid (160×160 unit grid, noise 0.3 along the normals) remeshed at 6,000
    vertices (an edge about 2 input edges, the noise about 0.15 of it) through its 2-step
    map: the follow step finds at most 1 % of the count in input points farther than its
    tolerance (chasing the noise, 1,212: 20 % of the count), and the faces stay round: mean
    smallest angle above 49°, under 1.5 % of the faces with an angle below 30°, none below
    20° (47.2° and 2.8 % with the noise chased)."""
    from pipeline.geometry.remesh_quality import is_disk, mesh_facts, triangle_quality
    from pipeline.geometry.repair import repair_mesh
    from pipeline.stages.remesh import RemeshConfig, remesh_stage

    V, F = noisy_paraboloid(160, 0.3, seed=3)
    mesh = repair_mesh(V, F)
    uv = remesh_map(mesh)
    r = remesh_stage(mesh, uv, RemeshConfig(vertices=6000))
    assert is_disk(mesh_facts(r.V, r.F))
    assert abs(len(r.V) - 6000) <= 0.02 * 6000
    assert r.info["improve"]["far_input_points"] <= 60
    q = triangle_quality(r.V, r.F)
    assert q["mean_min_angle_deg"] > 49.0
    assert q["fraction_min_angle_below_30"] < 0.015
    assert r.info["improve"]["below_min_angle"]["faces"] == 0
