"""``<run>/index.html``: one page that links every stage's report and files of a run."""

from __future__ import annotations

import os
from pathlib import Path

from . import html as h

__all__ = ["write_run_index"]

STYLE = """
section.stage { border-top: 1px solid #ddd; margin-top: 1.5em; }
p.report a { font-weight: bold; } span.missing { color: #a00; }
"""


def _relative(path: Path, run_dir: Path) -> str:
    """``path`` relative to ``run_dir`` (paths given relative are taken as relative to it)."""
    path = Path(path)
    if not path.is_absolute():
        return path.as_posix()
    return Path(os.path.relpath(path, run_dir)).as_posix()


def write_run_index(run_dir, stages: dict[str, dict[str, Path]], title: str = "",
                    meta: dict | None = None) -> Path:
    """Write ``<run_dir>/index.html`` and return its path.

    Parameters
    ----------
    run_dir : the run folder.
    stages : stage name → ``{key: path}`` of the files the stage wrote (as its ``write_*``
        function returns them), in the order the stages ran; the file named ``report.html``
        (or the ``report`` key) is linked first, a path that does not exist is marked missing.
    title : the page title (default: the folder's name).
    meta : shown as a table above the stages (config, times, versions …).
    """
    run_dir = Path(run_dir)
    parts = []
    if meta:
        parts.append(h.kv_table(list(meta.items()), ".4g"))
    for stage, files in stages.items():
        files = {k: Path(p) for k, p in (files or {}).items()}
        full = {k: (p if p.is_absolute() else run_dir / p) for k, p in files.items()}
        report = next((k for k, p in files.items() if k == "report" or p.name == "report.html"),
                      None)
        out = [f'<section class="stage"><h2>{h.esc(stage)}</h2>']
        if report is not None and full[report].exists():
            out.append(f'<p class="report">{h.link(_relative(files[report], run_dir), "report")}'
                       f"</p>")
        rows = []
        for k, p in files.items():
            rel = _relative(p, run_dir)
            cell = (h.link(rel, rel) if full[k].exists()
                    else f'{h.esc(rel)} <span class="missing">(missing)</span>')
            rows.append([h.esc(k), cell])
        out.append(h.table(["file", "path"], rows) if rows else "<p>no files</p>")
        out.append("</section>")
        parts.append("\n".join(out))
    if not stages:
        parts.append("<p>No stage has written files yet.</p>")
    return h.write_page(run_dir / "index.html", title or run_dir.name, "\n".join(parts),
                        style=STYLE)
