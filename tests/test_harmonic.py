"""The harmonic start of SEM, ``pipeline/geometry/harmonic.py``: the arc-length boundary on the
unit circle and the discrete harmonic map with cotangent weights (eq. 5–6), on planar disks whose
identity map is harmonic (linear precision) and on real meshes.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import as_complex, boundary_loop, load_mesh
from pipeline.geometry import metrics
from pipeline.geometry.harmonic import arc_length_circle, clamp_positive, harmonic_map
from pipeline.geometry.laplacian import (corner_dot_over_area, edge_weights, face_double_areas,
                                         laplacian_blocks, laplacian_pattern)


def test_arc_length_circle_equal_spacing_and_real_loop(ddisk):
    P, F, b = ddisk
    z = arc_length_circle(np.column_stack([P, np.zeros(len(P))]), b)
    np.testing.assert_allclose(z, np.exp(2j * np.pi * np.arange(len(b)) / len(b)), atol=1e-14)
    np.testing.assert_allclose(z, as_complex(P[b]), atol=1e-14)


def test_arc_length_circle_on_real_boundary():
    V, F = load_mesh("igl_lion")
    b = boundary_loop(F, V)
    z = arc_length_circle(V, b)
    np.testing.assert_allclose(np.abs(z), 1, atol=1e-15)
    assert z[0] == 1
    theta = np.unwrap(np.angle(z))
    seg = np.linalg.norm(V[np.roll(b, -1)] - V[b], axis=1)
    np.testing.assert_allclose(np.diff(theta), 2 * np.pi * seg[:-1] / seg.sum(), atol=1e-13)


@pytest.mark.parametrize("mesh", ["delaunay", "polar"])
def test_harmonic_map_of_planar_disk_is_identity(mesh, ddisk, pdisk):
    """Cotangent weights have linear precision: with the boundary already equally spaced on the
    unit circle starting at angle 0, the arc-length boundary is V_B and the harmonic map is the
    identity."""
    P, F, b = ddisk if mesh == "delaunay" else pdisk
    V = np.column_stack([P, np.zeros(len(P))])
    h = harmonic_map(V, F, laplacian_pattern(F, len(P), b))
    assert h.weights == "cotangent"
    assert h.flipped_faces == 0
    np.testing.assert_allclose(np.column_stack([h.f.real, h.f.imag]), P, rtol=0, atol=1e-10)


@pytest.mark.parametrize("name", ["igl_lion", "gpp_bunny"])
def test_harmonic_map_of_real_disk_is_flip_free_on_the_unit_circle(name):
    V, F = load_mesh(name)
    b = boundary_loop(F, V)
    pattern = laplacian_pattern(F, len(V), b)
    h = harmonic_map(V, F, pattern)
    uv = np.column_stack([h.f.real, h.f.imag])
    assert len(metrics.flipped_faces(uv, F)) == 0 and h.flipped_faces == 0
    np.testing.assert_allclose(h.f[b], arc_length_circle(V, b), atol=1e-15)
    assert np.abs(h.f[pattern.interior]).max() < 1
    # it is the discrete harmonic map of the weights it reports (eq. 5–6: L_II f_I = −L_IB f_B)
    w = edge_weights(pattern, corner_dot_over_area(V, F, face_double_areas(V, F)))
    assert h.negative_weights == int(np.count_nonzero(w <= 0))
    if h.weights != "cotangent":
        assert h.weights == "cotangent, clamped positive"
        w = clamp_positive(w)
    L_II, L_IB, _ = laplacian_blocks(pattern, w)
    res = L_II @ h.f[pattern.interior] + L_IB @ h.f[b]
    assert np.abs(res).max() < 1e-9 * np.abs(L_IB @ h.f[b]).max()


def test_harmonic_map_falls_back_to_tutte_when_the_clamped_map_still_folds(monkeypatch):
    """If the clamped weights still leave a flipped face, the start is Tutte's embedding (all
    weights 1): flip-free, and equal to its own harmonic system's solution. Forced here by
    strongly negative weights on every fifth edge of igl_lion (so the first map folds) and a
    clamp that keeps them."""
    import pipeline.geometry.harmonic as harmonic

    V, F = load_mesh("igl_lion")
    b = boundary_loop(F, V)
    pattern = laplacian_pattern(F, len(V), b)

    def folding_weights(pattern, corner_values):
        w = edge_weights(pattern, corner_values)
        w[::5] = -10 * np.abs(w).mean()
        return w

    monkeypatch.setattr(harmonic, "edge_weights", folding_weights)
    monkeypatch.setattr(harmonic, "clamp_positive", lambda w: w)
    h = harmonic.harmonic_map(V, F, pattern)
    assert h.weights == "uniform (Tutte)" and h.flipped_faces == 0
    uv = np.column_stack([h.f.real, h.f.imag])
    assert len(metrics.flipped_faces(uv, F)) == 0
    L_II, L_IB, _ = laplacian_blocks(pattern, np.ones(len(pattern.edges)))
    np.testing.assert_allclose(L_II @ h.f[pattern.interior], -(L_IB @ h.f[b]), atol=1e-12)
