"""Mesh reading/writing: every supported format, round trips, and one-line user errors."""

from __future__ import annotations

import os

import numpy as np
import pytest
import scipy.io
from conftest import require_data

from pipeline.errors import UserError
from pipeline.geometry.repair import repair_mesh
from pipeline.io.meshio import RawMesh, read_mesh, write_obj


def small_mesh():
    """2×2 squares grid (9 vertices, 8 counterclockwise faces) with non-trivial floats."""
    i, j = np.meshgrid(np.arange(3), np.arange(3), indexing="xy")
    V = np.stack([i.ravel() * 0.1, j.ravel() / 3.0, np.sqrt(i.ravel() + 2 * j.ravel())], axis=1)
    F = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 4], [2, 5, 4],
                  [3, 4, 6], [4, 7, 6], [4, 5, 8], [4, 8, 7]], dtype=np.int64)
    return V, F


def write_text(path, text):
    path.write_text(text)
    return path


# --------------------------------------------------------------------------------------------
# OBJ


def test_obj_round_trip_exact(tmp_path):
    V, F = small_mesh()
    p = write_obj(tmp_path / "m.obj", V, F, header=["made by a test", "second line"])
    m = read_mesh(p)
    assert isinstance(m, RawMesh) and m.all_triangles
    assert m.V.dtype == np.float64 and m.faces.dtype == np.int64
    assert np.array_equal(m.V, V) and np.array_equal(m.faces, F)
    assert m.colors is None
    text = p.read_text()
    assert text.startswith("# made by a test\n# second line\nv ")
    assert [q.name for q in tmp_path.iterdir()] == ["m.obj"]          # no temp file left
    umask = os.umask(0o022)
    os.umask(umask)
    assert p.stat().st_mode & 0o777 == 0o666 & ~umask          # not mkstemp's 0600


def test_obj_round_trip_with_uv_and_colors(tmp_path):
    V, F = small_mesh()
    uv = V[:, :2] * 2 - 0.25
    C = np.linspace(0, 1, 27).reshape(9, 3)
    p = write_obj(tmp_path / "m.obj", V, F, uv=uv, colors=C)
    lines = p.read_text().splitlines()
    assert sum(s.startswith("vt ") for s in lines) == 9
    assert "f 1/1 2/2 5/5" in lines
    m = read_mesh(p)
    assert np.array_equal(m.V, V) and np.array_equal(m.faces, F)
    assert np.array_equal(m.colors, C)


def test_obj_tokens_polygons_negative_indices_and_noise(tmp_path):
    text = "\n".join([
        "# comment", "mtllib x.mtl", "o thing",
        "v 0 0 0", "v 1 0 0", "v 1 1 0", "v 0 1 0",
        "vt 0 0", "vt 1 0", "vt 1 1", "vn 0 0 1",
        "g group", "usemtl m",
        "f 1/1/1 2/2/1 3/3/1 4/1/1",          # a quad with v/vt/vn tokens
        "v 2 0 0  # trailing comment",
        "f -4//1 -1//1 -3//1",                 # relative: vertices 2, 5, 3
        "  f 2/1 5/2 3/3\r",                    # v/vt, leading blanks, CR
        "s off", "",
    ])
    m = read_mesh(write_text(tmp_path / "t.obj", text))
    assert len(m.V) == 5 and not m.all_triangles
    assert [f.tolist() for f in m.faces] == [[0, 1, 2, 3], [1, 4, 2], [1, 4, 2]]
    r = repair_mesh(m.V, m.faces)
    assert r.report["non_triangle_faces_triangulated"] == 1
    assert r.report["duplicate_faces_removed"] == 1


def test_obj_vertex_colors_0_255_are_normalised(tmp_path):
    text = "v 0 0 0 255 0 0\nv 1 0 0 0 255 0\nv 0 1 0 0 0 255\nf 1 2 3\n"
    m = read_mesh(write_text(tmp_path / "c.obj", text))
    assert np.array_equal(m.colors, np.eye(3))


def test_obj_large_file_is_fast(tmp_path):
    import time

    k = 200
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="xy")
    V = np.stack([i.ravel(), j.ravel(), np.zeros(k * k)], axis=1) * 0.37
    a = (j[:-1, :-1] * k + i[:-1, :-1]).ravel()
    F = np.r_[np.stack([a, a + 1, a + k + 1], 1), np.stack([a, a + k + 1, a + k], 1)]
    t = time.perf_counter()
    p = write_obj(tmp_path / "big.obj", V, F)
    m = read_mesh(p)
    assert time.perf_counter() - t < 5.0          # ~0.2 s normally; generous for busy CI
    assert np.array_equal(m.V, V) and np.array_equal(m.faces, F)


@pytest.mark.parametrize("text, match", [
    ("", "empty"),
    ("# nothing\n", "no vertices"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no faces"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "1-based"),
    ("v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n", "unparsable vertex line 2"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "unparsable face line 1"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "need ≥ 3"),
    ("v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "fewer than 3 coordinates"),
    ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "NaN"),
])
def test_obj_errors_are_one_line_user_errors(tmp_path, text, match):
    p = write_text(tmp_path / "bad.obj", text)
    with pytest.raises(UserError, match=match) as exc:
        read_mesh(p)
    assert "\n" not in str(exc.value)


def _read_general(path, monkeypatch):
    """``read_mesh`` with the compiled pass declining every file: the general parser's result
    (or its error)."""
    import pipeline.io._obj as compiled

    with monkeypatch.context() as m:
        m.setattr(compiled, "obj_numbers", lambda raw: None)
        return read_mesh(path)


def _same_raw_mesh(a: RawMesh, b: RawMesh) -> bool:
    same_faces = (np.array_equal(a.faces, b.faces) and a.faces.dtype == b.faces.dtype
                  if a.all_triangles and b.all_triangles else
                  not a.all_triangles and not b.all_triangles and len(a.faces) == len(b.faces)
                  and all(np.array_equal(x, y) for x, y in zip(a.faces, b.faces)))
    colors = (a.colors is None and b.colors is None) or (
        a.colors is not None and b.colors is not None and np.array_equal(a.colors, b.colors))
    return (a.V.dtype == b.V.dtype and np.array_equal(a.V.view(np.int64), b.V.view(np.int64))
            and same_faces and colors)


# every number form the compiled pass reads, with the double float() makes of it
_NUMBERS = ["0", "-0", "+0.0", "1.", ".5", "-.5", "+1.5", "007.25", "1e5", "1E-30", "-2.5e+3",
            "0.1", "0.3", "1e22", "1e23", "9007199254740993", "9007199254740992.5",
            "123456789012345678901234", "0.000000000000000000000000123", "4.9e-324",
            "2.2250738585072011e-308", "1.7976931348623157e308", "3.14159265358979323846",
            "-0.03506127", "11.77162916", "1e-22", "1.5e-23", "8.98846567431158e307"]


def _number_texts(k: int, seed: int) -> list[str]:
    """``_NUMBERS`` and ``k`` random doubles in the forms files hold: shortest repr, fixed
    decimals (6, 8 and 12 digits), %.17g and %.6e."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(k) * 10.0 ** rng.integers(-12, 12, k)
    forms = [repr, lambda v: f"{v:.6f}", lambda v: f"{v:.8f}", lambda v: f"{v:.12f}",
             lambda v: f"{v:.17g}", lambda v: f"{v:.6e}"]
    return _NUMBERS + [forms[i % len(forms)](float(v)) for i, v in enumerate(x)]


def test_obj_compiled_numbers_are_float_of_each_token():
    """Every vertex number the compiled pass reads is bit for bit ``float()`` of its token:
    the short decimals (exact integer and power of ten) and the others alike."""
    from pipeline.io._obj import obj_numbers

    tokens = _number_texts(3000, 1)
    tokens += ["1"] * (-len(tokens) % 3)
    lines = [" ".join(tokens[i:i + 3]) for i in range(0, len(tokens), 3)]
    out = obj_numbers(("".join(f"v {s}\n" for s in lines) + "f 1 2 3\n").encode())
    assert out is not None
    expected = np.array([float(t) for t in tokens])
    assert np.array_equal(out[0].view(np.int64), expected.view(np.int64))
    assert out[1].tolist() == [3] * len(lines)


def test_obj_compiled_pass_reads_every_form_as_the_general_parser(tmp_path, monkeypatch):
    """An OBJ with every form the compiled pass reads — comments (whole-line and trailing),
    other statements (vt, vn, g, o, usemtl, s, mtllib), tabs and leading blanks, ``\r\n`` and
    lone ``\r`` line ends, a UTF-8 comment, vertex lines with a w coordinate and with
    colours, polygons, ``v/vt``, ``v/vt/vn``, ``v//vn`` and relative tokens, leading-zero
    indices, no final newline — gives the general parser's arrays exactly."""
    from pipeline.io._obj import obj_numbers

    nums = [t for t in _number_texts(600, 2) if abs(float(t)) <= 1e60]   # read_mesh's limit
    nums += ["1"] * (-len(nums) % 3)
    vlines = [f"v {a} {b} {c}" for a, b, c in zip(nums[::3], nums[1::3], nums[2::3])]
    n = len(vlines)
    lines = ["# comment ü", "mtllib x.mtl", "o thing", "\tg group", "usemtl m", "s off"]
    for i, v in enumerate(vlines):
        lines.append(v + ("  # trailing" if i % 7 == 0 else "") + (" 1.0" if i % 11 == 0 else ""))
        if i % 5 == 0:
            lines.append(f"vt {i * 0.01} 0.5\r")
        if i >= 3 and i % 3 == 0:
            j = i + 1                                   # the vertex just read
            lines += [f"f {j - 2} {j - 1} {j}",
                      f"  f\t{j - 3}/1/1 {j - 2}/2/1\t{j - 1}/3/1 {j}/1/1",   # a quad
                      "f -1//1 -2//1 -3//1 # relative",
                      f"f 00{j - 2}/1 {j - 1}/2 {j}/3\r"]
    text = "\n".join(lines).replace("o thing\n", "o thing\r")   # one lone CR line end
    p = write_text(tmp_path / "forms.obj", text)
    assert obj_numbers(p.read_bytes()) is not None              # the compiled pass reads it
    fast, general = read_mesh(p), _read_general(p, monkeypatch)
    assert len(fast.V) == n and not fast.all_triangles
    assert _same_raw_mesh(fast, general)
    rgb = "".join(f"v {i} {i % 3} 0.5 {i / 9:.3f} 0.25 1\n" for i in range(9)) + "f 1 2 3\n"
    p = write_text(tmp_path / "rgb.obj", rgb)
    fast, general = read_mesh(p), _read_general(p, monkeypatch)
    assert fast.colors is not None and fast.all_triangles and _same_raw_mesh(fast, general)


@pytest.mark.parametrize("text, compiled", [
    ("# nothing\n", True),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", True),
    ("f 1 2 3\n", True),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", True),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", True),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", True),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n", True),
    ("v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", True),
    ("v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", False),   # two errors: the first one's message
    ("v\t\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 2 3 4\n", True),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf # no indices\n", True),
    ("v 0 0 1e999\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", False),
    ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", False),
    ("v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n", False),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", False),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 +3\n", False),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3-\n", False),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n", False),
    ("v 0 0 0\nv 1\x000 0\nv 0 1 0\nf 1 2 3\n", False),
    ("v 0 0 0\nv 1 0\xa00\nv 0 1 0\nf 1 2 3\n", False),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\x0b4\n", False),
    ("v 1.2.3 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", False),
])
def test_obj_errors_and_results_are_the_general_parsers(tmp_path, monkeypatch, text, compiled):
    """Files the compiled pass reads (``compiled``) and files it leaves to the general
    parser give that parser's result or its error message, word for word."""
    from pipeline.io._obj import obj_numbers

    p = tmp_path / "bad.obj"
    p.write_bytes(text.encode("utf-8"))
    assert (obj_numbers(p.read_bytes()) is not None) == compiled
    results = []
    for read in (read_mesh, lambda q: _read_general(q, monkeypatch)):
        try:
            results.append(read(p))
        except UserError as exc:
            results.append(str(exc))
    if isinstance(results[0], str):
        assert results[0] == results[1] and "\n" not in results[0]
    else:
        assert _same_raw_mesh(*results)


@pytest.mark.parametrize("text, line", [
    ("v 0 0 0\nv 1 0\x00 0\nv 0 1 0\nf 1 2 3\n", 2),           # inside a number's gap
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n\x00v 0 0 1\nf 1 2 4\n", 4),  # before a statement
    ("v 0 0 0\r\nv\x001 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n", 2),  # after its keyword
    ("v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2\x003\r", 4),               # lone CR line ends
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n# a\x00b\nf 1 2 3\n", 4),       # in a comment
    ("\ufeffv 0 0 0\nv 1 0 0\x00\x00\x00\nv 0 1 0\nf 1 2 3\n", 2),
])
def test_obj_nul_byte_is_named_with_its_line(tmp_path, monkeypatch, text, line):
    """A NUL byte (binary data in an OBJ) is one line naming it and its line, from the
    compiled pass's reader and from the general parser alike."""
    p = tmp_path / "nul.obj"
    p.write_bytes(text.encode("utf-8"))
    for read in (read_mesh, lambda q: _read_general(q, monkeypatch)):
        with pytest.raises(UserError) as exc:
            read(p)
        assert str(exc.value) == (f"{p}: line {line}: NUL byte, not a text OBJ (binary or "
                                  f"UTF-16 data); re-export the file as text")


def test_obj_utf8_byte_order_mark_is_skipped(tmp_path, monkeypatch):
    """A UTF-8 byte order mark before the first ``v`` line: the mesh read without it, by the
    compiled pass and by the general parser (a lone ``\r`` line end sends a file there)."""
    for text in ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
                 "v 0 0 0\rv 1 0.5e0 0\nv 0 1 0\nf 1 2 3\nf -3 -2 -1\n"):
        plain = write_text(tmp_path / "plain.obj", text)
        marked = tmp_path / "marked.obj"
        marked.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
        expected = read_mesh(plain)
        assert len(expected.V) == 3
        assert _same_raw_mesh(read_mesh(marked), expected)
        assert _same_raw_mesh(_read_general(marked, monkeypatch), expected)


def test_missing_file_and_unknown_extension(tmp_path):
    with pytest.raises(UserError, match="does not exist"):
        read_mesh(tmp_path / "nope.obj")
    with pytest.raises(UserError, match=r"unsupported mesh format '\.xyz'.*\.obj, \.off"):
        read_mesh(write_text(tmp_path / "m.xyz", "1 2 3\n"))
    (tmp_path / "dir.obj").mkdir()
    with pytest.raises(UserError, match="dir.obj. is a folder"):
        read_mesh(tmp_path / "dir.obj")


# --------------------------------------------------------------------------------------------
# OFF


def test_off_plain_and_polygons(tmp_path):
    text = ("OFF\n# a comment\n5 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n"
            "4 0 1 2 3\n3 1 4 2\n3 0 1 3 255 0 0\n")
    m = read_mesh(write_text(tmp_path / "m.off", text))
    assert np.array_equal(m.V[4], [2, 0, 0]) and m.colors is None
    assert [f.tolist() for f in m.faces] == [[0, 1, 2, 3], [1, 4, 2], [0, 1, 3]]


def test_coff_colors_and_header_counts_on_one_line(tmp_path):
    text = "COFF 3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n3 0 1 2\n"
    m = read_mesh(write_text(tmp_path / "m.off", text))
    assert m.all_triangles and m.faces.tolist() == [[0, 1, 2]]
    assert np.array_equal(m.colors, np.c_[np.eye(3), np.ones(3)])


@pytest.mark.parametrize("text, match", [
    ("OFF\n3 1 0\n0 0 0\n1 0 0\n", "ends early"),
    ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "out of range"),
    ("PLY\n3 1 0\n", "unsupported OFF header"),
    ("OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n", "no faces"),
])
def test_off_errors(tmp_path, text, match):
    with pytest.raises(UserError, match=match):
        read_mesh(write_text(tmp_path / "bad.off", text))


# --------------------------------------------------------------------------------------------
# MATLAB


def test_mat_one_based_faces_and_colors(tmp_path):
    V, F = small_mesh()
    C = np.linspace(0, 1, 27).reshape(9, 3)
    scipy.io.savemat(tmp_path / "m.mat", {"V": V, "F": (F + 1).astype(float), "C": C})
    m = read_mesh(tmp_path / "m.mat")
    assert np.array_equal(m.V, V) and np.array_equal(m.faces, F)
    assert np.allclose(m.colors, C)
    # lower-case names and transposed (3×n) arrays
    scipy.io.savemat(tmp_path / "t.mat", {"v": V.T, "f": (F + 1).T.astype(np.int32)})
    m = read_mesh(tmp_path / "t.mat")
    assert np.array_equal(m.V, V) and np.array_equal(m.faces, F)


def test_mat_errors(tmp_path):
    V, F = small_mesh()
    scipy.io.savemat(tmp_path / "a.mat", {"verts": V, "tris": F + 1})
    with pytest.raises(UserError, match="'V'.*'F'.*found variables: verts, tris"):
        read_mesh(tmp_path / "a.mat")
    scipy.io.savemat(tmp_path / "b.mat", {"V": V, "F": F})        # 0-based by mistake
    with pytest.raises(UserError, match="1-based"):
        read_mesh(tmp_path / "b.mat")
    write_text(tmp_path / "c.mat", "not a mat file at all")
    with pytest.raises(UserError, match="cannot read .mat"):
        read_mesh(tmp_path / "c.mat")


# --------------------------------------------------------------------------------------------
# PLY / STL via trimesh


def test_ply_keeps_vertex_order_and_colors(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    V, F = small_mesh()
    rgba = np.c_[np.arange(9) * 20, np.arange(9) * 10, 255 - np.arange(9) * 5, np.full(9, 255)]
    mesh = trimesh.Trimesh(V, F, vertex_colors=rgba.astype(np.uint8), process=False)
    (tmp_path / "m.ply").write_bytes(mesh.export(file_type="ply"))
    m = read_mesh(tmp_path / "m.ply")
    assert np.allclose(m.V, V) and np.array_equal(m.faces, F)
    assert m.colors.shape == (9, 3) and np.allclose(m.colors * 255, rgba[:, :3])


def test_stl_soup_is_welded_by_the_repair(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    V, F = small_mesh()
    mesh = trimesh.Trimesh(V, F, process=False)
    (tmp_path / "m.stl").write_bytes(mesh.export(file_type="stl"))
    m = read_mesh(tmp_path / "m.stl")
    assert len(m.V) == 3 * len(F) and len(m.faces) == len(F)
    r = repair_mesh(m.V, m.faces)
    assert r.report["vertices_welded"] == 3 * len(F) - len(V)
    assert len(r.V) == len(V) and len(r.F) == len(F)
    assert np.allclose(np.sort(r.V, axis=0), np.sort(V.astype(np.float32), axis=0))


def test_empty_and_corrupt_binary_formats(tmp_path):
    for ext in (".ply", ".stl", ".mat", ".off", ".obj"):
        with pytest.raises(UserError, match="empty"):
            read_mesh(write_text(tmp_path / f"e{ext}", ""))
    with pytest.raises(UserError):
        read_mesh(write_text(tmp_path / "bad.ply", "ply\nformat nonsense\n"))


# --------------------------------------------------------------------------------------------
# real data


def test_real_obj_reads_and_round_trips(tmp_path):
    path = require_data("meshes", "gpp_face.obj")
    m = read_mesh(path)
    assert m.V.shape == (1180, 3) and m.faces.shape == (2000, 3)
    out = write_obj(tmp_path / "copy.obj", m.V, m.faces)
    m2 = read_mesh(out)
    assert np.array_equal(m2.V, m.V) and np.array_equal(m2.faces, m.faces)
    assert os.path.getsize(out) > 0


def test_compiled_rows_are_the_percent_format_of_floats_and_integers():
    """The compiled row writer gives exactly what ``(fmt * k) % values`` gives: floats as
    ``repr`` (signed zero, exponents both ways, subnormal, largest, inf, nan, integers as
    floats) and integers in decimal (negative, zero, the int64 extremes)."""
    from pipeline.io.meshio import _format_rows

    x = np.array([0.0, -0.0, 0.1, 1 / 3, -1.5, 1e-5, 1e-4, 1e16, 123456789012345678.0,
                  5e-324, 1.7976931348623157e308, np.inf, -np.inf, np.nan, 2.0 ** 53])
    x = np.concatenate([x, np.random.default_rng(0).standard_normal(6) * 1e7])[:21]
    i = np.array([[-5, 0, 7], [np.iinfo(np.int64).min, np.iinfo(np.int64).max, 10 ** 12]])
    for fmt, arr in [("v %r %r %r\n", x.reshape(-1, 3)), ("vt %r %r %r\n", x.reshape(-1, 3)[:0]),
                     ("f %d/%d %d\n", i), ("f %d %d %d\n", i)]:
        expected = (fmt * len(arr)) % tuple(arr.ravel().tolist()) if len(arr) else ""
        assert _format_rows(fmt, arr) == expected
