"""The experiment's summary: ``summary.csv`` and a sortable ``summary.html``, one row per item.

Columns: ``item``, ``status``, ``error``, ``seconds`` (the item's wall time), ``hash`` (first 12
hex digits), the item's dataset names and sweep values (``mesh`` or ``source``/``target``, then
one column per swept key), then the metrics of every stage: each stage's ``metrics.json`` (or
``<stage>_metrics.json``) flattened to dotted keys prefixed with the stage folder, e.g.
``parameterize.distortion.face_area_distortion`` or ``parameterize.seconds.sem``. Lists (the
iteration history) and landmark tables are left out. The HTML sorts on a header click (inline
script, no network) and links each item's folder, log, ``item.json``, metrics and reports; it
is built on the shared page writer (:mod:`pipeline.report.html`). A measure with the same value
in every item (options, counts of the shared input, versions) is listed once below the table
instead of filling a column; ``summary.csv`` keeps every column.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from urllib.parse import quote

from ..io.artifacts import atomic_write_text
from ..report import html as h

SKIP_KEYS = {"history", "landmarks", "repair_messages", "messages"}
FIXED = ["item", "status", "error", "seconds", "hash"]


def flatten(data, prefix: str = "") -> dict:
    """Scalars of nested mappings under dotted keys (lists and ``SKIP_KEYS`` left out)."""
    out = {}
    if isinstance(data, dict):
        for k, v in data.items():
            if str(k) in SKIP_KEYS:
                continue
            out.update(flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    elif data is None or isinstance(data, (bool, int, float, str)):
        out[prefix] = data
    return out


def stage_files(item_dir: Path) -> list[tuple[str, str, Path]]:
    """``(stage, kind, path)`` of the metrics files and HTML reports of an item folder."""
    found = []
    for d in sorted(p for p in Path(item_dir).iterdir() if p.is_dir()):
        for f in sorted(d.glob("*.json")):
            if f.name == "metrics.json" or f.name.endswith("_metrics.json"):
                found.append((d.name, "metrics", f))
        for f in sorted(d.glob("*.html")):
            found.append((d.name, "report", f))
    return found


def collect_metrics(item_dir: Path) -> tuple[dict, dict]:
    """``(flat metrics, links)`` of a finished item folder (links relative to the folder)."""
    metrics, links = {}, {}
    for stage, kind, path in stage_files(item_dir):
        rel = path.relative_to(item_dir).as_posix()
        extra = "" if path.name in ("metrics.json", f"{stage}_metrics.json", "report.html") \
            else f" {path.stem}"
        links[f"{stage}{extra} {kind}"] = rel
        if kind == "metrics":
            try:
                data = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                continue
            key = stage if not extra else f"{stage}.{path.stem.removesuffix('_metrics')}"
            metrics.update(flatten(data, key))
    return metrics, links


def summary_rows(items, records: dict) -> tuple[list[str], list[dict]]:
    """Column names and one row (column → value) per item, in item order."""
    params, metrics, rows = [], [], []
    for item in items:
        rec = records.get(item.id) or {"status": "missing"}
        for k in item.params:
            if k not in params:
                params.append(k)
        taken = set(FIXED) | set(item.params)
        measured = {(f"{k} (measured)" if k in taken else k): v
                    for k, v in rec.get("metrics", {}).items()}   # never hide a sweep value
        for k in measured:
            if k not in metrics:
                metrics.append(k)
        rows.append({**measured, **item.params, "item": item.id, "status": rec.get("status"),
                     "error": rec.get("error"), "seconds": (rec.get("seconds") or {}).get("total"),
                     "hash": (rec.get("hash") or "")[:12], "_links": rec.get("links", {})})
    params = [p for p in params if p not in FIXED]
    metrics = [m for m in metrics if m not in FIXED and m not in params]
    # The input's echo (source, counts, repair report) after the stage's own measures.
    metrics.sort(key=lambda m: m.split(".")[1:2] == ["input"])
    return FIXED + params + metrics, rows


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (dict, list)):
        return json.dumps(value, separators=(",", ":"))
    return str(value)


def write_summary(run_dir: Path, items, records: dict, title: str = "") -> tuple[Path, Path]:
    run_dir = Path(run_dir)
    columns, rows = summary_rows(items, records)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for row in rows:
        w.writerow([_cell(row.get(c)) for c in columns])
    csv_path = atomic_write_text(run_dir / "summary.csv", buf.getvalue())
    html_path = atomic_write_text(run_dir / "summary.html",
                                  _html(columns, rows, title or run_dir.name))
    return csv_path, html_path


def _display(value) -> tuple[str, str]:
    """(text shown, sort key) of one cell."""
    if value is None:
        return "", ""
    if isinstance(value, bool):
        return str(value).lower(), str(int(value))
    if isinstance(value, (int, float)):
        if isinstance(value, float) and not math.isfinite(value):
            return str(value), str(value)
        text = f"{value:.6g}" if isinstance(value, float) else str(value)
        return text, repr(float(value))
    return _cell(value), _cell(value)


_SCRIPT = """
function sortBy(th) {
  const table = th.closest('table'), body = table.tBodies[0];
  const col = Array.from(th.parentNode.children).indexOf(th);
  const asc = th.dataset.order !== 'asc';
  table.querySelectorAll('th').forEach(h => { h.dataset.order = ''; });
  th.dataset.order = asc ? 'asc' : 'desc';
  const key = tr => tr.children[col].dataset.v;
  const rows = Array.from(body.rows);
  rows.sort((a, b) => {
    const x = key(a), y = key(b);
    if (x === '' || y === '') return (x === '') - (y === '');      // blanks last
    const nx = Number(x), ny = Number(y);
    const c = (!isNaN(nx) && !isNaN(ny)) ? nx - ny : x.localeCompare(y, undefined, {numeric: true});
    return asc ? c : -c;
  });
  rows.forEach(r => body.appendChild(r));
}
"""

_STYLE = """
body { font-size: 13px; margin: 1em; max-width: none; }
table { font-size: 1em; }
th, td { padding: 2px 6px; white-space: nowrap; }
th { background: #eee; cursor: pointer; position: sticky; top: 0; }
th[data-order=asc]::after { content: ' \\25B2'; } th[data-order=desc]::after { content: ' \\25BC'; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tr.failed td { background: #fde8e8; } tr.missing td { background: #eee; }
td.error { white-space: normal; max-width: 40em; }
"""


def constant_columns(columns: list[str], rows: list[dict], keep=()) -> list[str]:
    """Columns (other than ``keep``) whose value is the same in each of two or more rows."""
    if len(rows) < 2:
        return []
    return [c for c in columns if c not in keep
            and len({_cell(r.get(c)) for r in rows}) == 1]


def _html(columns: list[str], rows: list[dict], title: str) -> str:
    e = h.esc
    n_ok = sum(r["status"] == "ok" for r in rows)
    same = constant_columns(columns, rows, keep=set(FIXED))
    columns = [c for c in columns if c not in same]
    note = (f" {len(same)} measures with one value in every item are listed "
            f"<a href='#same'>below the table</a>." if same else "")
    out = [f"<p>{len(rows)} items: {n_ok} ok, {len(rows) - n_ok} failed or "
           f"missing. Click a header to sort.{note} Also: "
           f"<a href='summary.csv'>summary.csv</a> (every column).</p>",
           "<table id='items'><thead><tr><th onclick='sortBy(this)'>files</th>"]
    out += [f"<th onclick='sortBy(this)'>{e(c)}</th>" for c in columns]
    out.append("</tr></thead><tbody>")
    for row in rows:
        item = row["item"]
        links = [("folder", ""), ("log", "log.txt"), ("item.json", "item.json")]
        links += sorted(row.get("_links", {}).items())
        files = " ".join(f"<a href='{e(quote(f'{item}/{href}'))}'>{e(name)}</a>"
                         for name, href in links)
        out.append(f"<tr class='{e(str(row['status']))}'><td data-v=''>{files}</td>")
        for c in columns:
            text, key = _display(row.get(c))
            cls = " class='num'" if isinstance(row.get(c), (int, float)) and not \
                isinstance(row.get(c), bool) else (" class='error'" if c == "error" else "")
            if c == "item":
                text_html = f"<a href='{e(quote(item))}/'>{e(text)}</a>"
            else:
                text_html = e(text)
            out.append(f"<td{cls} data-v='{e(key)}'>{text_html}</td>")
        out.append("</tr>")
    out.append("</tbody></table>")
    if same:
        out.append("<h2 id='same'>Same for every item</h2><table><tbody>")
        out += [f"<tr><th>{e(c)}</th><td>{e(_display(rows[0].get(c))[0])}</td></tr>"
                for c in same]
        out.append("</tbody></table>")
    return h.page(title, "\n".join(out), style=_STYLE, script=_SCRIPT)
