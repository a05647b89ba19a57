"""Landmark files (JSON / CSV / TXT), pairing by name or order, and mapping onto the repaired
mesh (pipeline.io.landmarks). Small constructed meshes only; no data files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pipeline.errors import UserError
from pipeline.geometry.repair import RepairOptions, repair_mesh
from pipeline.io.landmarks import (landmarks_from_dict, pair_landmarks, read_landmarks,
                                   resolve_landmarks)


def grid_with_hole(k=7, hole=True):
    """A k×k vertex grid triangulated as a disk; with ``hole`` the central square is removed."""
    V = np.array([[x, y, 0.1 * np.sin(x + y)] for y in range(k) for x in range(k)], float)
    F = []
    c = (k - 1) // 2
    for y in range(k - 1):
        for x in range(k - 1):
            if hole and x == c and y == c:
                continue
            a, b, d, e = y * k + x, y * k + x + 1, (y + 1) * k + x, (y + 1) * k + x + 1
            F += [[a, b, e], [a, e, d]]
    return V, np.array(F)


def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_json_named_list_mapping_and_key(tmp_path):
    a = read_landmarks(write(tmp_path, "a.json", json.dumps(
        {"source": "x", "landmarks": {"nose": 5, "chin": 7, "eye": 2}})))
    assert a.names == ["nose", "chin", "eye"]
    np.testing.assert_array_equal(a.indices, [5, 7, 2])
    b = read_landmarks(write(tmp_path, "b.json", "[3, 1, 4]"))
    assert b.names is None and b.indices.tolist() == [3, 1, 4]
    c = read_landmarks(write(tmp_path, "c.json", '{"a": 1, "b": 2, "c": 3}'))
    assert c.names == ["a", "b", "c"]
    d = {"landmarks": {"n": 1}, "ibug68_0based_vertex_indices": [9, 8, 7]}
    p = write(tmp_path, "d.json", json.dumps(d))
    assert read_landmarks(p, key="ibug68").indices.tolist() == [9, 8, 7]
    assert read_landmarks(p, key="ibug68_0based_vertex_indices").names is None
    with pytest.raises(UserError, match="no landmark set 'foo'.*ibug68_0based_vertex_indices"):
        read_landmarks(p, key="foo")
    e = read_landmarks(write(tmp_path, "e.json", '{"landmarks": {"p": [0.5, 1.0, 2.0]}}'))
    assert e.indices.tolist() == [-1] and e.points[0].tolist() == [0.5, 1.0, 2.0]


def test_csv_and_txt(tmp_path):
    a = read_landmarks(write(tmp_path, "a.csv", "name,index\nnose, 4\nchin, 9\n# c\n"))
    assert a.names == ["nose", "chin"] and a.indices.tolist() == [4, 9]
    b = read_landmarks(write(tmp_path, "b.txt", "1\n2\n3\n"))
    assert b.names is None and b.indices.tolist() == [1, 2, 3]
    c = read_landmarks(write(tmp_path, "c.txt", "x y z\n0 0 0\n1.5 2 0.25\n"))
    assert c.indices.tolist() == [-1, -1]
    np.testing.assert_array_equal(c.points[1], [1.5, 2, 0.25])


@pytest.mark.parametrize("name, text, words", [
    ("a.json", "{not json", ["not valid json"]),
    ("b.json", '{"landmarks": {"a": "x"}}', ["not a vertex index"]),
    ("c.json", '{"landmarks": [-1, 2]}', ["negative"]),
    ("d.csv", "1 2\n", ["expected"]),
    ("e.csv", "a, 1\n2\n", ["name all or none"]),
    ("f.csv", "a, 1\na, 2\n", ["appears twice"]),
    ("g.yaml", "[1]", ["unsupported"]),
    ("h.txt", "# nothing\n", ["no landmarks"]),
    ("i.json", "[" * 100_000 + "]" * 100_000, ["nested too deeply"]),
    ("j.json", "[1, 2, 1" + "0" * 30 + "]", ["beyond any mesh"]),
    ("k.csv", "1\n2\n1" + "0" * 30 + "\n", ["beyond any mesh"]),
])
def test_bad_files_are_one_line_errors(tmp_path, name, text, words):
    with pytest.raises(UserError) as exc:
        read_landmarks(write(tmp_path, name, text))
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w.lower() in msg.lower(), msg


@pytest.mark.parametrize("name, text", [
    ("a.json", '{"landmarks": {"nose": 5, "chin": 7, "eye": 2}}'),
    ("b.json", "[3, 1, 4]"),
    ("c.csv", "nose, 5\nchin, 7\neye, 2\n"),
    ("d.txt", "3\n1\n4\n2\n"),
    ("e.txt", "0.5 1 2\n3 4 5\n"),
])
def test_a_utf8_byte_order_mark_is_skipped(tmp_path, name, text):
    """A file saved with a UTF-8 byte order mark reads as the same file without it (its first
    line is a landmark, not a header to skip)."""
    plain = read_landmarks(write(tmp_path, name, text))
    marked = tmp_path / f"bom_{name}"
    marked.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    got = read_landmarks(marked)
    assert got.names == plain.names
    np.testing.assert_array_equal(got.indices, plain.indices)
    np.testing.assert_array_equal(got.points, plain.points)


def test_missing_file(tmp_path):
    with pytest.raises(UserError, match="not found"):
        read_landmarks(tmp_path / "nope.json")


def test_pair_by_name_reorders_target():
    s = landmarks_from_dict({"landmarks": {"a": 1, "b": 2, "c": 3}})
    t = landmarks_from_dict({"landmarks": {"c": 30, "a": 10, "b": 20}})
    s2, t2 = pair_landmarks(s, t)
    assert t2.names == ["a", "b", "c"]
    np.testing.assert_array_equal(t2.indices, [10, 20, 30])
    np.testing.assert_array_equal(s2.indices, [1, 2, 3])


def test_pair_by_order_when_one_side_is_unnamed():
    s = landmarks_from_dict({"landmarks": {"a": 1, "b": 2}})
    t = landmarks_from_dict([5, 6])
    s2, t2 = pair_landmarks(s, t)
    np.testing.assert_array_equal(t2.indices, [5, 6])


def test_pair_mismatches_are_one_line_errors():
    s = landmarks_from_dict({"landmarks": {"a": 1, "b": 2, "c": 3}})
    t = landmarks_from_dict({"landmarks": {"a": 1, "b": 2, "d": 4}})
    with pytest.raises(UserError, match=r"only in the source: c; only in the target: d"):
        pair_landmarks(s, t)
    with pytest.raises(UserError, match="3 source landmarks but 2 target landmarks"):
        pair_landmarks(landmarks_from_dict([1, 2, 3]), landmarks_from_dict([1, 2]))


def test_resolve_maps_input_indices_through_source_index():
    V, F = grid_with_hole(7, hole=False)
    V = np.vstack([[[50.0, 50.0, 50.0]], V])          # unreferenced vertex 0: removed by repair
    mesh = repair_mesh(V, F + 1, options=RepairOptions())
    lms = landmarks_from_dict({"landmarks": {"a": 1 + 8, "b": 1 + 24}})
    idx, msgs = resolve_landmarks(lms, mesh, len(V), "source")
    np.testing.assert_array_equal(mesh.source_index[idx], [9, 25])
    np.testing.assert_array_equal(mesh.V[idx], V[[9, 25]])
    with pytest.raises(UserError, match="removed by the mesh repair"):
        resolve_landmarks(landmarks_from_dict([0]), mesh, len(V), "source")
    with pytest.raises(UserError, match="has 50 vertices"):
        resolve_landmarks(landmarks_from_dict([60]), mesh, len(V), "source")


def test_resolve_snaps_points_and_reports():
    V, F = grid_with_hole(7, hole=False)
    mesh = repair_mesh(V, F)
    lms = landmarks_from_dict({"landmarks": {"p": [2.1, 2.95, 0.0], "q": [4.0, 1.0, 0.1]}})
    idx, msgs = resolve_landmarks(lms, mesh, len(V), "target")
    np.testing.assert_array_equal(idx, [3 * 7 + 2, 1 * 7 + 4])
    assert len(msgs) == 1 and "snapped 2 point landmarks" in msgs[0]


def test_resolve_rejects_boundary_hole_rim_added_and_duplicates():
    V, F = grid_with_hole(7, hole=True)
    mesh = repair_mesh(V, F, options=RepairOptions(close_holes=True))
    assert len(mesh.closed_holes) == 1
    n = len(V)
    with pytest.raises(UserError, match="on the mesh boundary"):
        resolve_landmarks(landmarks_from_dict([0]), mesh, n, "source")
    rim = mesh.closed_holes[0]["loop"][0]
    with pytest.raises(UserError, match="rim of a hole"):
        resolve_landmarks(landmarks_from_dict([int(mesh.source_index[rim])]), mesh, n, "source")
    centre = mesh.V[mesh.closed_holes[0]["centre_vertex"]]
    with pytest.raises(UserError, match="which the repair added"):
        resolve_landmarks(landmarks_from_dict({"landmarks": {"c": centre.tolist()}}), mesh, n,
                          "source")
    with pytest.raises(UserError, match="same vertex"):
        resolve_landmarks(landmarks_from_dict([8, 8]), mesh, n, "source")
    idx, _ = resolve_landmarks(landmarks_from_dict([8, 12]), mesh, n, "source")
    assert len(idx) == 2
