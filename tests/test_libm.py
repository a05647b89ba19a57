"""The C library's arccos, cos and sin on arrays (pipeline.geometry.libm)."""

import math

import numpy as np
import pytest

from pipeline.geometry import libm


@pytest.mark.parametrize("name, scalar", [("arccos", math.acos), ("cos", math.cos),
                                          ("sin", math.sin)])
def test_each_value_is_the_c_library_s_to_the_bit(name, scalar):
    """Every value is ``math``'s (the C library's) function of it, bit for bit, in the array's
    shape: random values, both ends of [−1, 1], ±0, and values a SIMD loop might treat apart
    (tiny, near π/2, large angles)."""
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.uniform(-1.0, 1.0, 997), [-1.0, 1.0, 0.0, -0.0, 1e-300, 0.5]])
    if name != "arccos":
        x = np.concatenate([x * 7.0, [np.pi / 2, -np.pi, 1e6 + 0.25, 123456.789]])
    got = getattr(libm, name)(x.reshape(-1, 1) if len(x) % 2 else x.reshape(-1, 2))
    assert got.shape == (x.reshape(-1, 1) if len(x) % 2 else x.reshape(-1, 2)).shape
    want = np.array([scalar(v) for v in x])
    assert got.reshape(-1).tobytes() == want.tobytes()


def test_nan_stays_nan_and_a_scalar_gives_a_0_d_array():
    assert np.isnan(libm.arccos(np.array([np.nan, 0.5]))[0])
    out = libm.cos(np.float64(0.0))
    assert out.shape == () and out == 1.0
