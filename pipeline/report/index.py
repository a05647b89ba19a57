"""``<run>/index.html``: one page that links every stage's report and files of a run."""

from __future__ import annotations

import os
from pathlib import Path

from . import html as h

__all__ = ["write_run_index"]

STYLE = """
section.stage { border-top: 1px solid #ddd; margin-top: 1.5em; }
p.report a { font-weight: bold; } span.missing { color: #a00; }
div.thumbs img { height: 160px; margin: 0 6px 6px 0; border: 1px solid #ddd; }
"""


def _relative(path: Path, run_dir: Path) -> str:
    """``path`` relative to ``run_dir`` (paths given relative are taken as relative to it)."""
    path = Path(path)
    if not path.is_absolute():
        return path.as_posix()
    return Path(os.path.relpath(path, run_dir)).as_posix()


def write_run_index(run_dir, stages: dict[str, dict[str, Path]], title: str = "",
                    summaries: dict[str, str] | None = None,
                    seconds: dict[str, float] | None = None) -> Path:
    """Write ``<run_dir>/index.html`` and return its path.

    Parameters
    ----------
    run_dir : the run folder.
    stages : stage name → ``{key: path}`` of the files the stage wrote (as its ``write_*``
        function returns them), in the order the stages ran; the file named ``report.html``
        (or the ``report`` key) is linked first, a path that does not exist is marked missing.
    title : the page title (default: the folder's name).
    summaries, seconds : stage name → its one-line result and its time, for the overview table.
    """
    run_dir = Path(run_dir)
    summaries, seconds = summaries or {}, seconds or {}
    overview, parts = [], []
    for stage, files in stages.items():
        files = {k: Path(p) for k, p in (files or {}).items()}
        full = {k: (p if p.is_absolute() else run_dir / p) for k, p in files.items()}
        report = next((k for k, p in files.items() if k == "report" or p.name == "report.html"),
                      None)
        has_report = report is not None and full[report].exists()
        report_link = h.link(_relative(files[report], run_dir), "report") if has_report else "–"
        overview.append([f'<a href="#{h.esc(stage)}">{h.esc(stage)}</a>',
                         h.fmt(seconds[stage], ".2f") if stage in seconds else "–",
                         h.esc(summaries.get(stage, "")), report_link])
        out = [f'<section class="stage" id="{h.esc(stage)}"><h2>{h.esc(stage)}</h2>']
        if has_report:
            out.append(f'<p class="report">{report_link}</p>')
        thumbs = [_relative(p, run_dir) for k, p in files.items()
                  if p.suffix in (".png", ".gif") and full[k].exists()]
        if thumbs:
            out.append('<div class="thumbs">' + "".join(
                f'<a href="{h.href(t)}"><img src="{h.href(t)}" alt="{h.esc(t)}"></a>'
                for t in thumbs) + "</div>")
        rows = []
        for k, p in files.items():
            rel = _relative(p, run_dir)
            cell = (h.link(rel, rel) if full[k].exists()
                    else f'{h.esc(rel)} <span class="missing">(missing)</span>')
            rows.append([h.esc(k), cell])
        out.append(h.table(["file", "path"], rows) if rows else "<p>no files</p>")
        out.append("</section>")
        parts.append("\n".join(out))
    head = []
    if overview:
        head.append(h.table(["stage", "seconds", "result", "report"], overview))
    else:
        head.append("<p>No stage has written files yet.</p>")
    if (run_dir / "manifest.json").exists() or stages:
        head.append(f"<p>Config snapshot, versions and timings: "
                    f"{h.link('manifest.json', 'manifest.json')}</p>")
    return h.write_page(run_dir / "index.html", title or run_dir.name,
                        "\n".join(head + parts), style=STYLE)
