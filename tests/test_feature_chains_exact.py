"""The feature chains, their weights and their points (pipeline.geometry.remesh.features)
against the per-edge Python walk they are computed without: the same chains in the same order,
the same weights and points bit for bit, on constructed edge sets (open runs, closed loops,
branches, turns, a run back to its start) and on the creases of real meshes."""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import pytest

from conftest import require_data
from pipeline.geometry.remesh.features import (blas_dots, chain_points, chain_steps, chain_sums,
                                               chain_weights, feature_chains, feature_edges)
from pipeline.geometry.rows import norms
from pipeline.io.meshio import read_mesh


def walked_chains(V: np.ndarray, E: np.ndarray, turn_deg: float) -> list:
    """The chains as an edge-by-edge walk finds them (the rule of :func:`feature_chains`)."""
    nbr = defaultdict(list)
    for i, (a, b) in enumerate(E.tolist()):
        nbr[a].append((b, i))
        nbr[b].append((a, i))
    cos_turn = math.cos(math.radians(turn_deg))

    def passes(v) -> bool:
        if len(nbr[v]) != 2:
            return False
        d1, d2 = V[v] - V[nbr[v][0][0]], V[nbr[v][1][0]] - V[v]
        return float(d1 @ d2) >= cos_turn * np.linalg.norm(d1) * np.linalg.norm(d2)

    through = {v: passes(v) for v in nbr}
    used = np.zeros(len(E), bool)

    def walk(v, i) -> np.ndarray:
        chain = [v]
        while i is not None:
            used[i] = True
            v = int(E[i, 1] if E[i, 0] == v else E[i, 0])
            chain.append(v)
            i = next((j for _, j in nbr[v] if not used[j]), None) if through[v] else None
        return np.asarray(chain, np.int64)

    chains = [walk(v, i) for v in nbr if not through[v] for _, i in nbr[v] if not used[i]]
    for i in range(len(E)):
        if not used[i]:
            chains.append(walk(int(E[i, 0]), i))
    return chains


def summed_weights(V, E, angle, chains) -> np.ndarray:
    """Per chain, the sum of length × angle² over its edges, edge by edge in Python."""
    key = {(min(a, b), max(a, b)): w for (a, b), w in
           zip(E.tolist(), (norms(V[E[:, 0]] - V[E[:, 1]]) * angle ** 2).tolist())}
    return np.array([sum(key[(min(a, b), max(a, b))] for a, b in zip(c[:-1].tolist(),
                                                                     c[1:].tolist()))
                     for c in chains])


def assert_same_chains(V, E, turn_deg=60.0, angle=None):
    want = walked_chains(V, E, turn_deg)
    got = feature_chains(V, E, turn_deg)
    assert len(got) == len(want)
    for g, w in zip(got, want):
        assert g.dtype == w.dtype and np.array_equal(g, w)
    angle = np.linspace(0.5, 2.0, len(E)) if angle is None else angle
    assert np.array_equal(chain_weights(V, E, angle, got), summed_weights(V, E, angle, want))
    return got


def test_constructed_edge_sets_give_the_walks_chains():
    """A closed square loop (edges listed out of order), a path with a sharp turn in it, a
    star (a vertex where three meet), a path that comes back to its non-through start, a
    vertex with two edges at a turn too sharp, and random sparse edge sets on a jittered
    grid (branches, loops, turns of every angle)."""
    rng = np.random.default_rng(0)
    V = rng.normal(size=(60, 3))
    grid = np.array([[x, y, 0.0] for y in range(4) for x in range(4)], float)
    V[:16] = grid
    loop = np.array([[5, 6], [10, 9], [6, 10], [9, 5]])
    path = np.array([[0, 1], [1, 2], [2, 3], [3, 7]])             # a right angle at 3
    star = np.array([[20, 21], [20, 22], [23, 20]])
    back = np.array([[30, 31], [31, 32], [32, 30], [30, 33]])     # 30 meets three
    for E in (loop, path, star, back, np.vstack([loop, path, star, back])):
        assert_same_chains(V, E)
        assert_same_chains(V, E, turn_deg=100.0)
    chains = assert_same_chains(grid, loop, turn_deg=100.0)      # every corner turns 90°
    assert [c.tolist() for c in chains] == [[5, 6, 10, 9, 5]]
    P = rng.normal(size=(400, 3)) * 0.05 + np.repeat(np.arange(400)[:, None] * 0.0, 3, 1)
    P[:, :2] += np.array([[i % 20, i // 20] for i in range(400)], float)
    for seed in range(20):
        r = np.random.default_rng(seed)
        right = np.array([[i, i + 1] for i in range(400) if i % 20 != 19])
        up = np.array([[i, i + 20] for i in range(380)])
        pick = np.vstack([right, up])
        E = pick[r.random(len(pick)) < r.uniform(0.2, 0.9)]
        E = E[r.permutation(len(E))]
        E = np.where(r.random((len(E), 1)) < 0.5, E, E[:, ::-1])
        for turn in (10.0, 60.0, 120.0):
            assert_same_chains(P, E, turn_deg=turn)


@pytest.mark.parametrize("name", ["meshes/igl_lion.obj", "meshes/igl_camel_b.obj",
                                  "faces/ict/ict_A_smile_disk.obj"])
def test_real_creases_give_the_walks_chains_weights_and_points(name):
    """The creases of real meshes at 10°, 30° and 90°: chains, weights and chain points
    (at three spacings) those of the walk."""
    mesh = read_mesh(require_data(*name.split("/")))
    V, F = mesh.V, np.asarray(mesh.faces)
    uv = V[:, :2] * 0.37
    counts = []
    for angle_deg in (10.0, 30.0, 90.0):
        E, angle = feature_edges(V, F, angle_deg)
        chains = assert_same_chains(V, E, angle=angle)
        counts.append(len(chains))
        want = walked_chains(V, E, 60.0)
        for L in (0.002, 0.02, 0.2):
            L = L * np.ptp(V, axis=0).max()
            for g, w in zip(chain_points(V, uv, chains, L), chain_points(V, uv, want, L)):
                assert np.array_equal(g, w)
    assert max(counts) > 100


def test_chain_steps_and_sums_are_the_per_chain_cumsum():
    """Chain lengths by :func:`chain_sums` of :func:`chain_steps`: the last entry of each
    chain's ``np.cumsum`` of its own edge lengths, bit for bit (chains of 1 to 300 edges)."""
    rng = np.random.default_rng(4)
    V = rng.normal(size=(5000, 3)) * rng.choice([1e-3, 1.0, 1e3], (5000, 1))
    chains = [rng.integers(0, 5000, rng.integers(2, 302)) for _ in range(300)]
    total = chain_sums(chain_steps(V, chains), [len(c) - 1 for c in chains])
    want = [np.cumsum(norms(V[c[1:]] - V[c[:-1]]))[-1] for c in chains]
    assert np.array_equal(total, np.array(want))
    assert chain_sums(np.zeros(0), []).shape == (0,)


def test_blas_dots_are_numpys_vector_dot():
    """Row by row the dot product of ``a[i] @ b[i]`` (and ``np.linalg.norm``'s square), which
    the written-out sums do not always give."""
    rng = np.random.default_rng(7)
    a = rng.normal(size=(20000, 3)) * rng.choice([1e-3, 1.0, 1e3], (20000, 1))
    b = rng.normal(size=(20000, 3))
    want = np.array([float(x @ y) for x, y in zip(a, b)])
    assert np.array_equal(blas_dots(a, b), want)
    assert np.array_equal(np.sqrt(blas_dots(a, a)), [np.linalg.norm(x) for x in a])
