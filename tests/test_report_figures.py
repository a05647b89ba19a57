"""The figure toolkit (pipeline/report/figure.py) and the page writer (pipeline/report/html.py):
one camera, both shadings, atomic PNG save with nothing left open, escaped pages."""

from __future__ import annotations

import matplotlib.image as mpimg
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

from pipeline.report import html as h
from pipeline.report.figure import camera_for, draw_surface, new_figure, render_rgb, save_png
from pipeline.sample import make_face


@pytest.fixture(scope="module")
def face():
    s = make_face(600)
    return np.asarray(s.V, float), np.asarray(s.F)


def test_camera_looks_at_the_front_with_y_up(face):
    V, F = face
    cam = camera_for(V, F)
    frame = np.stack([cam.right, cam.up, cam.toward])
    assert np.allclose(frame @ frame.T, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(frame), 1.0)               # right-handed
    assert cam.up @ np.array([0.0, 1.0, 0.0]) > 0.9            # the face is stored y-up
    P, _ = cam.project(V)
    assert P[:, 0].min() >= cam.xlim[0] and P[:, 0].max() <= cam.xlim[1]
    assert P[:, 1].min() >= cam.ylim[0] and P[:, 1].max() <= cam.ylim[1]
    R = np.array([[0.0, -1.0], [1.0, 0.0]])
    turned = cam.rotated(R)
    assert np.allclose(turned.project(V)[0], P @ R)
    assert np.allclose(turned.light @ turned.toward, cam.light @ cam.toward)


def test_render_and_both_shadings(face, tmp_path):
    V, F = face
    cam = camera_for(V, F)
    rgb = render_rgb(V, F, cam, 128, label="t = 0")
    assert rgb.shape == (128, 128, 3) and rgb.dtype == np.uint8
    assert (rgb < 250).any() and (rgb == 255).all(axis=2).any()  # a surface on white
    fig = new_figure(4, 2, dpi=50)
    a, b = fig.subplots(1, 2)
    draw_surface(a, V, F, cam)
    win = (cam.xlim[0] / 4, cam.xlim[1] / 4), (cam.ylim[0] / 4, cam.ylim[1] / 4)
    draw_surface(b, V, F, cam, shading="flat", edges=True, window=win)
    assert b.get_xlim() == win[0]
    out = save_png(fig, tmp_path / "f.png", dpi=50)
    assert mpimg.imread(out).shape[:2] == (100, 200)
    assert [p.name for p in tmp_path.iterdir()] == ["f.png"] and plt.get_fignums() == []
    with pytest.raises(ValueError):
        draw_surface(new_figure(1, 1).add_subplot(), V, F, cam, shading="toon")


def test_failed_png_save_leaves_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr(Figure, "savefig", lambda *a, **k: (_ for _ in ()).throw(OSError()))
    with pytest.raises(OSError):
        save_png(new_figure(1, 1), tmp_path / "x.png")
    assert list(tmp_path.iterdir()) == []


def test_page_escapes_and_links_relatively(tmp_path):
    body = (h.kv_table([("a<b", 1.5e-7), ("none", None), ("n", float("nan"))])
            + h.figure("my fig.png") + h.link("sub dir/r.html", "r"))
    path = h.write_page(tmp_path / "p.html", "T & U", body, style="p{}")
    text = path.read_text(encoding="utf-8")
    assert "<title>T &amp; U</title>" in text and "<th>a&lt;b</th>" in text
    assert "1.500e-07" in text and text.count("<td>–</td>") == 2
    assert 'src="my%20fig.png"' in text and 'href="sub%20dir/r.html"' in text
    assert text.rstrip().endswith("</html>") and "p{}" in text
