"""The one atomic writer (pipeline/io/artifacts.py): whole files or nothing, normal permissions,
no temporary file left, and the staged output folder."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from pipeline.io.artifacts import (atomic_write, atomic_write_text, save_npz, staged_output,
                                   write_json)


def test_bytes_text_and_callable(tmp_path):
    assert atomic_write(tmp_path / "a.bin", b"\x00\x01").read_bytes() == b"\x00\x01"
    assert atomic_write_text(tmp_path / "sub" / "b.txt", "é\nz\n").read_bytes() == \
        "é\nz\n".encode("utf-8")                              # folders made, \n kept
    atomic_write(tmp_path / "c.bin", lambda fh: fh.write(b"xyz"))
    assert (tmp_path / "c.bin").read_bytes() == b"xyz"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bin", "c.bin", "sub"]


def test_permissions_follow_the_umask(tmp_path):
    mask = os.umask(0o022)
    os.umask(mask)
    path = atomic_write_text(tmp_path / "t.txt", "x")
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask


def test_failure_keeps_the_old_file_and_leaves_no_temp(tmp_path):
    path = atomic_write_text(tmp_path / "keep.txt", "old")

    def boom(fh):
        fh.write(b"half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        atomic_write(path, boom)
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]


def test_json_and_npz(tmp_path):
    write_json(tmp_path / "m.json", {"a": np.float64(1.5), "b": np.arange(3), 3: tmp_path})
    assert json.loads((tmp_path / "m.json").read_text()) == {"a": 1.5, "b": [0, 1, 2],
                                                              "3": str(tmp_path)}
    save_npz(tmp_path / "x.npz", u=np.eye(2), f=np.arange(4))
    with np.load(tmp_path / "x.npz") as z:
        assert np.array_equal(z["u"], np.eye(2)) and np.array_equal(z["f"], np.arange(4))
    np.savez_compressed(tmp_path / "y.npz", u=np.eye(2), f=np.arange(4))
    assert (tmp_path / "x.npz").read_bytes() == (tmp_path / "y.npz").read_bytes()


def test_staged_output_is_all_or_nothing(tmp_path):
    out = tmp_path / "stage"
    with staged_output(out) as tmp:
        atomic_write_text(tmp / "a.txt", "a")
        atomic_write_text(tmp / "frames" / "f0.txt", "f")
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == \
        ["a.txt", "frames", "frames/f0.txt"]
    with pytest.raises(RuntimeError):
        with staged_output(out) as tmp:
            atomic_write_text(tmp / "a.txt", "new")
            raise RuntimeError("interrupted")
    assert (out / "a.txt").read_text() == "a"
    assert not [p for p in out.iterdir() if p.name.startswith(".partial-")]
