"""The HTML pages the pipeline writes, opened in a real (headless) browser.

One Chromium for the module (``browser.chrome``); every output is built once per module, small
(800-vertex meshes, 30 SEM iterations, 4 morph frames). ``check_page`` fails on console errors,
images that do not load or show, dead local links and anchors, and links leaving the run folder;
the constructed pages at the end show that it does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from browser import chrome, check_page  # noqa: F401  (chrome: module-scoped fixture)
from conftest import REPO, run_cli


def _ok(result, what):
    code, out, err = result
    assert code == 0, f"{what} exited {code}\n--- stdout\n{out[-3000:]}\n--- stderr\n{err[-3000:]}"


@pytest.fixture(scope="module")
def sample_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("sample")
    _ok(run_cli("sample", "-o", out, "--vertices", "1500"), "pipeline sample")
    return out


@pytest.fixture(scope="module")
def remesh_out(sample_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("remesh") / "out"
    _ok(run_cli("remesh", sample_dir / "sample_face_neutral.obj", "--vertices", "800",
                "--max-iter", "30", "-o", out), "pipeline remesh")
    return out


@pytest.fixture(scope="module")
def register_run(tmp_path_factory):
    """configs/sample.yaml (the whole chain), small: the run folder with input/, parameterize/,
    remesh/, register/, morph/ and index.html."""
    root = tmp_path_factory.mktemp("runs")
    config = root / "chain_small.yaml"
    config.write_text(
        "run: {name: chain_small}\n"
        "input: {sample: {vertices: 1500}}\n"
        "parameterize: {mode: converged, max_iter: 30}\n"
        "remesh: {vertices: 800}\n"
        "register: {sample: true, sample_vertices: 800, sample_expression: smile}\n"
        "morph: {frames: 4, easing: ease-in-out}\n")
    _ok(run_cli("run", config, "--out", root / "out"), "pipeline run")
    return root / "out" / "chain_small"


@pytest.fixture(scope="module")
def sphere_run(tmp_path_factory):
    """A run of a closed genus-0 mesh (an ellipsoid icosphere, 642 vertices) with only input
    and parameterize: the spherical map's report and the run's index.html."""
    from pipeline.io.meshio import write_obj
    from test_parameterize_sphere import ellipsoid

    root = tmp_path_factory.mktemp("sphere")
    write_obj(root / "ellipsoid.obj", *ellipsoid(3))
    config = root / "sphere_small.yaml"
    config.write_text("run: {name: sphere_small}\n"
                      "input: {mesh: ellipsoid.obj}\n"
                      "parameterize: {mode: paper}\n")
    _ok(run_cli("run", config, "--out", root / "out"), "pipeline run (sphere)")
    return root / "out" / "sphere_small"


@pytest.fixture(scope="module")
def experiment_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("experiment")
    _ok(run_cli("experiment", REPO / "configs" / "experiment_sample.yaml", "--out", root,
                "--workers", "1"), "pipeline experiment")
    return root / "experiment_sample"


# ------------------------------------------------------------------ the pipeline's pages

def test_remesh_report_shows_every_figure(chrome, remesh_out):
    page = remesh_out / "report.html"
    seen = check_page(chrome, page)
    figures = sorted(p.resolve() for p in remesh_out.glob("*.png"))
    assert len(figures) >= 4, f"remesh wrote only {[f.name for f in figures]}"
    assert seen["images"] >= len(figures)
    assert set(figures) <= set(seen["image_paths"]), (
        f"{page}: figures written but not shown: "
        f"{sorted(f.name for f in set(figures) - set(seen['image_paths']))}")


def test_register_report_shows_every_figure(chrome, register_run):
    page = register_run / "register" / "report.html"
    seen = check_page(chrome, page, root=register_run)
    figures = sorted(p.resolve() for p in (register_run / "register").glob("*.png"))
    assert len(figures) >= 3, f"register wrote only {[f.name for f in figures]}"
    assert set(figures) <= set(seen["image_paths"]), (
        f"{page}: figures written but not shown: "
        f"{sorted(f.name for f in set(figures) - set(seen['image_paths']))}")


@pytest.mark.parametrize("stage", ["parameterize", "remesh", "morph"])
def test_stage_reports_of_a_run_show_every_figure(chrome, register_run, stage):
    folder = register_run / stage
    seen = check_page(chrome, folder / "report.html", root=register_run)
    figures = sorted(p.resolve() for p in folder.glob("*.png")) + \
        sorted(p.resolve() for p in folder.glob("*.gif"))
    assert figures, f"{stage} wrote no figure"
    assert set(figures) <= set(seen["image_paths"]), (
        f"{stage}/report.html: figures written but not shown: "
        f"{sorted(f.name for f in set(figures) - set(seen['image_paths']))}")


def test_sphere_report_and_run_index_show_every_figure_and_file(chrome, sphere_run):
    import json

    folder = sphere_run / "parameterize"
    seen = check_page(chrome, folder / "report.html", root=sphere_run)
    figures = sorted(p.resolve() for p in folder.glob("*.png"))
    assert {p.name for p in figures} == {"sphere_area_ratio.png", "surface_and_sphere.png",
                                         "area_ratio_histogram.png", "convergence.png"}
    assert set(figures) <= set(seen["image_paths"])
    seen = check_page(chrome, sphere_run / "index.html")
    manifest = json.loads((sphere_run / "manifest.json").read_text())
    assert list(manifest["stages"]) == ["parameterize"]
    linked = {p.resolve() for p in seen["link_paths"]}
    for key, path in manifest["stages"]["parameterize"].items():
        assert Path(path).resolve() in linked, f"index.html: no link to parameterize {key}"
    assert {"npz", "obj", "sphere", "report"} <= set(manifest["stages"]["parameterize"])


def test_run_index_links_every_stage_report_and_file(chrome, register_run):
    import json

    page = register_run / "index.html"
    seen = check_page(chrome, page)
    manifest = json.loads((register_run / "manifest.json").read_text())
    assert list(manifest["stages"]) == ["input", "parameterize", "remesh", "register", "morph"]
    linked = {p.resolve() for p in seen["link_paths"]}
    for stage, files in manifest["stages"].items():
        for key, path in files.items():
            assert Path(path).resolve() in linked, f"index.html: no link to {stage} {key}"
        if stage != "input":
            assert (register_run / stage / "report.html").resolve() in linked, stage
    assert (register_run / "manifest.json").resolve() in linked
    shown = set(seen["image_paths"])
    for png in register_run.glob("*/*.png"):
        assert png.resolve() in shown, f"index.html: no thumbnail of {png}"


def test_experiment_summary_links_every_item(chrome, experiment_dir):
    page = experiment_dir / "summary.html"
    seen = check_page(chrome, page)
    items = sorted(p for p in experiment_dir.iterdir() if (p / "item.json").is_file())
    assert len(items) == 4  # 2 modes x 2 sample sizes
    linked = {p.resolve() for p in seen["link_paths"]}
    assert (experiment_dir / "summary.csv").resolve() in linked
    for item in items:
        assert item.resolve() in linked, f"{page}: no link to the item folder {item.name}"
        assert (item / "log.txt").resolve() in linked, f"{page}: no link to {item.name}/log.txt"
    assert seen["local_links"] >= 1 + 2 * len(items)


def test_experiment_summary_sorts_by_a_clicked_header(chrome, experiment_dir):
    """The summary's only script: a click on a header sorts the rows (ascending, then descending)."""
    from selenium.webdriver.common.by import By

    check_page(chrome, experiment_dir / "summary.html")
    headers = [th.text.strip() for th in chrome.find_elements(By.CSS_SELECTOR, "thead th")]
    assert "seconds" in headers, headers
    column = headers.index("seconds")
    th = chrome.find_elements(By.CSS_SELECTOR, "thead th")[column]

    def seconds():
        return [float(tr.find_elements(By.TAG_NAME, "td")[column].get_attribute("data-v"))
                for tr in chrome.find_elements(By.CSS_SELECTOR, "#items tbody tr")]

    th.click()
    assert seconds() == sorted(seconds())
    th.click()
    assert seconds() == sorted(seconds(), reverse=True)
    assert [e for e in chrome.get_log("browser") if e["level"] == "SEVERE"] == []


# ------------------------------------------------------------------ check_page itself

@pytest.fixture
def run_folder(tmp_path):
    """A run folder with a figure, a data file and a sub-folder, and a file beside (outside) it."""
    import matplotlib.image

    run = tmp_path / "run"
    (run / "item 1").mkdir(parents=True)
    matplotlib.image.imsave(run / "figure.png", np.linspace(0, 1, 40 * 60).reshape(40, 60))
    (run / "data.json").write_text("{}")
    (run / "other.html").write_text("<html><body><h2 id='top'>other</h2></body></html>")
    matplotlib.image.imsave(tmp_path / "outside.png", np.zeros((8, 8)))
    (tmp_path / "outside.txt").write_text("not in the run")
    return run


def _page(run, body, name="page.html"):
    path = run / name
    path.write_text(f"<!doctype html><html><head><meta charset='utf-8'><title>t</title></head>"
                    f"<body>{body}</body></html>")
    return path


GOOD = ("<h1 id='top'>report</h1><img src='figure.png' alt='f'>"
        "<a href='data.json'>data</a> <a href='item%201/'>item</a> <a href='#top'>top</a>"
        " <a href='other.html#top'>other</a> <a href='https://example.org/'>web</a>")


def test_check_page_counts_what_it_checked(chrome, run_folder):
    seen = check_page(chrome, _page(run_folder, GOOD))
    assert {k: seen[k] for k in ("images", "links", "local_links", "anchors", "external_links")} \
        == {"images": 1, "links": 5, "local_links": 3, "anchors": 2, "external_links": 1}
    assert seen["image_paths"] == [(run_folder / "figure.png").resolve()]


@pytest.mark.parametrize("body, message", [
    ("<img src='missing.png' alt='m'>", "missing.png"),                       # image not found
    ("<img src='data.json' alt='j'>", "did not load"),                        # not an image
    ("<img src='figure.png' style='display:none' alt='h'>", "not rendered"),  # loaded, not shown
    ("<img src='figure.png' width='0' alt='z'>", "not rendered"),
    ("<a href='nope.html'>gone</a>", "nope.html"),                            # dead link
    ("<a href='item%202/'>gone</a>", "no such file or folder"),               # dead folder link
    ("<a href='#nowhere'>anchor</a>", "'nowhere'"),                           # dead anchor
    ("<a href='other.html#missing'>anchor</a>", "'missing'"),                 # dead anchor there
    ("<script>undefined_function()</script>", "undefined_function"),          # JS error
    ("<script>console.error('boom')</script>", "boom"),                       # console.error
    ("<a href='../outside.txt'>up</a>", "outside the run folder"),            # leaves the run
    ("<img src='../outside.png' alt='o'>", "outside the run folder"),
    ("<a href='ftp://example.org/x'>ftp</a>", "neither a local file nor http(s)"),
])
def test_check_page_fails_on_a_broken_page(chrome, run_folder, body, message):
    page = _page(run_folder, GOOD + body)
    with pytest.raises(AssertionError) as failure:
        check_page(chrome, page)
    text = str(failure.value)
    assert str(page) in text and message in text, text


def test_check_page_allows_the_run_folder_above_the_page(chrome, run_folder):
    """A stage's page (run/register/report.html) may link into its run folder, not above it."""
    (run_folder / "stage").mkdir()
    page = _page(run_folder / "stage", "<a href='../data.json'>run data</a>"
                 "<img src='../figure.png' alt='f'>")
    with pytest.raises(AssertionError, match="outside the run folder"):
        check_page(chrome, page)
    seen = check_page(chrome, page, root=run_folder)
    assert (seen["images"], seen["local_links"]) == (1, 1)
