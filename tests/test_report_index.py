"""The run index (pipeline/report/index.py): one page linking every stage's report and files."""

from pathlib import Path

from pipeline.report.index import write_run_index


def _fake_run(root: Path) -> dict:
    for name in ("parameterize/report.html", "parameterize/metrics.json",
                 "parameterize/disk_area_ratio.png", "register/report.html",
                 "register/registration.npz", "morph/morph.gif", "morph/frames/frame_000.obj"):
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_bytes(b"x")
    return {
        "parameterize": {"report": root / "parameterize" / "report.html",
                         "metrics": root / "parameterize" / "metrics.json",
                         "disk_area_ratio": root / "parameterize" / "disk_area_ratio.png"},
        "register": {"report": root / "register" / "report.html",
                     "npz": Path("register/registration.npz"),           # relative to the run
                     "obj": root / "register" / "registered.obj"},        # not written
        "morph": {"gif": root / "morph" / "morph.gif", "frames": root / "morph" / "frames"},
    }


def test_index_links_every_stage_report_and_file(tmp_path):
    stages = _fake_run(tmp_path)
    out = write_run_index(tmp_path, stages, title="sample run <1>",
                          summaries={"register": "16 landmarks, flipped faces = 0"},
                          seconds={"parameterize": 12.5})
    assert out == tmp_path / "index.html"
    text = out.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>") and "<title>sample run &lt;1&gt;</title>" in text
    for stage in stages:
        assert f'<section class="stage" id="{stage}"><h2>{stage}</h2>' in text
        assert f'href="#{stage}"' in text                      # in the overview table
    assert text.count('>report</a>') == 4          # parameterize and register, overview + section
    for rel in ("parameterize/report.html", "parameterize/metrics.json",
                "parameterize/disk_area_ratio.png", "register/registration.npz",
                "morph/morph.gif", "morph/frames"):
        assert f'href="{rel}"' in text, rel
    assert "register/registered.obj" in text and "(missing)" in text
    assert 'href="register/registered.obj"' not in text
    assert "16 landmarks, flipped faces = 0" in text and "12.50" in text
    assert '<img src="parameterize/disk_area_ratio.png"' in text     # thumbnails of the figures
    assert '<img src="morph/morph.gif"' in text
    assert str(tmp_path) not in text                           # every link is relative
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_file()) == ["index.html"]


def test_index_of_an_empty_run(tmp_path):
    text = write_run_index(tmp_path, {}, title="").read_text(encoding="utf-8")
    assert f"<title>{tmp_path.name}</title>" in text and "No stage" in text
