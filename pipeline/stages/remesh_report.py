"""The remesh report: our remesh measured side by side with what users remesh with today.

:func:`compare_methods` measures (:func:`pipeline.geometry.remesh_quality.remesh_quality`)
the input, our remesh straight after lifting (the paper's §8), our improved remesh, and — at
the same vertex count — pymeshlab's isotropic explicit remeshing and fast-simplification's
quadric decimation (:mod:`pipeline.stages.baselines`). :func:`write_report` writes
``report.html`` (self-contained apart from its PNGs, linked relatively) with one table, the
figures and captions saying how everything was measured and where each method wins:

* ``remesh_renders.png`` — every mesh seen the same way (orthographic view along the input's
  least-variance axis, flat Lambert shading, back faces darker), full view and two zoomed
  crops with the edges drawn: the middle of the surface and the place where our remesh is
  farthest from the input;
* ``remesh_min_angle.png`` — distribution of the smallest angle of every face;
* ``remesh_valence.png`` — valence of interior vertices;
* ``remesh_disk.png`` — our remesh on the disk, faces coloured by their smallest angle on the
  surface (where the map's angle distortion is, and what improvement did).

:func:`remesh_outputs` is what the runner and the CLI call after :func:`..remesh.remesh_stage`.
"""

from __future__ import annotations

import html
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from ..geometry.remesh_quality import (bounding_box_diagonal, point_mesh_distance,  # noqa: E402
                                       remesh_quality)
from . import baselines  # noqa: E402

__all__ = ["Method", "compare_methods", "write_report", "remesh_outputs", "plain_metrics"]

DPI = 110
LABELS = {
    "input": "input mesh",
    "sem_lifted": "SEM remesh, lifted only (paper §8)",
    "sem": "SEM remesh (ours, improved)",
    "pymeshlab_isotropic": "pymeshlab isotropic remeshing",
    "fast_simplification": "fast-simplification decimation",
}
COLORS = {"input": "0.45", "sem_lifted": "tab:cyan", "sem": "tab:blue",
          "pymeshlab_isotropic": "tab:orange", "fast_simplification": "tab:green"}
COMPARED = ("sem", "pymeshlab_isotropic", "fast_simplification")


@dataclass
class Method:
    key: str
    V: np.ndarray | None
    F: np.ndarray | None
    seconds: float | None = None
    quality: dict = field(default_factory=dict)
    note: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.V is not None


def plain_metrics(q: dict) -> dict:
    """A quality dict without its per-face arrays (keys starting with ``_``), for JSON."""
    if isinstance(q, dict):
        return {k: plain_metrics(v) for k, v in q.items() if not str(k).startswith("_")}
    return q


def compare_methods(V_in: np.ndarray, F_in: np.ndarray, remesh, target: int,
                    compare: bool = True, n_random: int = 200_000, seed: int = 0,
                    progress=None) -> dict[str, Method]:
    """Measure the input, our lifted and improved remeshes and (``compare``) the baselines."""
    def say(msg):
        if progress:
            progress(msg)

    out: dict[str, Method] = {}
    out["input"] = Method("input", V_in, F_in, None,
                          remesh_quality(V_in, F_in, V_in, F_in, distance=False))
    Xl, Fl = remesh.lifted
    say("measuring the lifted remesh")
    out["sem_lifted"] = Method("sem_lifted", Xl, Fl, remesh.seconds["sample"]
                               + remesh.seconds["delaunay"] + remesh.seconds["locate"]
                               + remesh.seconds["lift"],
                               remesh_quality(V_in, F_in, Xl, Fl, n_random, seed))
    say("measuring the improved remesh")
    out["sem"] = Method("sem", remesh.V, remesh.F, remesh.seconds["total"],
                        remesh_quality(V_in, F_in, remesh.V, remesh.F, n_random, seed))
    if not compare:
        return out
    if baselines.pymeshlab_available():
        say("pymeshlab isotropic explicit remeshing (solving for the target length)")
        b = baselines.isotropic_remesh(V_in, F_in, target)
        out["pymeshlab_isotropic"] = Method(
            "pymeshlab_isotropic", b.V, b.F, b.seconds,
            remesh_quality(V_in, F_in, b.V, b.F, n_random, seed),
            extra={"runs": b.runs, "parameters": b.parameter,
                   "seconds_all_runs": b.seconds_all_runs})
    else:
        out["pymeshlab_isotropic"] = Method("pymeshlab_isotropic", None, None,
                                            note="pymeshlab is not installed "
                                                 "(pip install pymeshlab)")
    say("fast-simplification decimation")
    b = baselines.decimate(V_in, F_in, target)
    if b is None:
        out["fast_simplification"] = Method(
            "fast_simplification", None, None,
            note=f"not applicable: decimation only removes vertices and the input has "
                 f"{len(V_in)} ≤ {target}")
    else:
        out["fast_simplification"] = Method(
            "fast_simplification", b.V, b.F, b.seconds,
            remesh_quality(V_in, F_in, b.V, b.F, n_random, seed),
            extra={"runs": b.runs, "parameters": b.parameter,
                   "seconds_all_runs": b.seconds_all_runs})
    return out


# ------------------------------------------------------------------------------- figures


def _figure(w, h):
    fig = Figure(figsize=(w, h), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path: Path) -> Path:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp.png", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fig.savefig(fh, format="png", dpi=DPI)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


class _View:
    """Orthographic view of the input along its least-variance axis (PCA), from the side its
    face normals point to; the same view for every mesh."""

    def __init__(self, V, F):
        self.c = V.mean(axis=0)
        _, _, Wt = np.linalg.svd(V - self.c, full_matrices=False)
        e3 = Wt[2]
        n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]).sum(axis=0)
        if n @ e3 < 0:
            e3 = -e3
        # "up" on the screen: the model's +y axis when it is not along the view (faces and most
        # scans are stored y-up), else the direction of largest extent
        up = np.array([0.0, 1.0, 0.0]) - e3[1] * e3
        if np.linalg.norm(up) < 0.3:
            up = Wt[0] - (Wt[0] @ e3) * e3
        e2 = up / np.linalg.norm(up)
        e1 = np.cross(e2, e3)
        self.E = np.stack([e1, e2, e3])
        light = e3 + 0.35 * e2 - 0.25 * e1
        self.light = light / np.linalg.norm(light)

    def project(self, X):
        Y = (X - self.c) @ self.E.T
        return Y[:, :2], Y[:, 2]

    def draw(self, ax, V, F, window=None, edges=False, colors=None):
        P, depth = self.project(V)
        if window is not None:
            (x0, x1), (y0, y1) = window
            C = P[F].mean(axis=1)
            pad = 0.15 * (x1 - x0)
            keep = ((C[:, 0] > x0 - pad) & (C[:, 0] < x1 + pad)
                    & (C[:, 1] > y0 - pad) & (C[:, 1] < y1 + pad))
            F = F[keep]
            if colors is not None:
                colors = colors[keep]
        N = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)
        lam = N @ self.light
        front = N @ self.E[2] >= 0
        shade = np.where(front, 0.3 + 0.7 * np.clip(lam, 0, 1), 0.15 + 0.2 * np.abs(lam))
        base = np.array([0.78, 0.80, 0.84]) if colors is None else colors[:, :3]
        rgb = np.clip(base * shade[:, None], 0, 1)
        order = np.argsort(depth[F].mean(axis=1), kind="stable")
        pc = PolyCollection(P[F[order]], facecolors=rgb[order],
                            edgecolors=(0.05, 0.05, 0.1, 0.9) if edges else "none",
                            linewidths=0.35 if edges else 0.0, antialiased=edges,
                            rasterized=True)
        ax.add_collection(pc)
        if window is None:
            lo, hi = P.min(axis=0), P.max(axis=0)
            pad = 0.02 * float((hi - lo).max())
            ax.set_xlim(lo[0] - pad, hi[0] + pad)
            ax.set_ylim(lo[1] - pad, hi[1] + pad)
        else:
            ax.set_xlim(*window[0])
            ax.set_ylim(*window[1])
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])


def _windows(view: _View, methods: dict[str, Method], V_in, F_in):
    """Two zoom windows (about 14 of our edge lengths wide): the middle of the surface and the
    place where our remesh is farthest from the input."""
    sem = methods["sem"]
    P, depth = view.project(V_in)
    lo, hi = P.min(axis=0), P.max(axis=0)
    edge = sem.quality["triangles"]["mean_edge_length"]
    half = 7.0 * edge
    # middle: the input vertex nearest the centre of the view that faces the viewer
    centre = 0.5 * (lo + hi)
    front = np.argsort(np.linalg.norm(P - centre, axis=1))[:50]
    c1 = P[front[np.argmax(depth[front])]]
    C = sem.V[sem.F].mean(axis=1)
    d, _ = point_mesh_distance(C, V_in, F_in)
    worst = C[np.argmax(d)]
    c2, _ = view.project(worst[None])
    wins = []
    for c in (c1, c2[0]):
        wins.append(((c[0] - half, c[0] + half), (c[1] - half, c[1] + half)))
    return wins, float(d.max())


def plot_renders(path: Path, methods: dict[str, Method], V_in, F_in) -> Path:
    keys = [k for k in ("input", "sem_lifted", "sem", "pymeshlab_isotropic",
                        "fast_simplification") if methods.get(k) and methods[k].ok]
    view = _View(V_in, F_in)
    wins, _ = _windows(view, methods, V_in, F_in)
    fig = _figure(3.0 * len(keys), 9.2)
    axs = fig.subplots(3, len(keys), squeeze=False)
    for j, k in enumerate(keys):
        m = methods[k]
        view.draw(axs[0, j], m.V, m.F)
        axs[0, j].set_title(f"{LABELS[k]}\n{len(m.V)} vertices, {len(m.F)} faces", fontsize=8)
        for i, w in enumerate(wins):
            view.draw(axs[1 + i, j], m.V, m.F, window=w, edges=True)
            for (x0, x1), (y0, y1) in [w]:
                axs[0, j].plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0],
                               color=("tab:red" if i else "tab:purple"), lw=0.8)
    axs[1, 0].set_ylabel("zoom: middle (purple box)", fontsize=8)
    axs[2, 0].set_ylabel("zoom: where ours is farthest\nfrom the input (red box)", fontsize=8)
    fig.suptitle("Same orthographic view for every mesh (flat shading; darker = back faces)",
                 fontsize=9)
    return _save(fig, path)


def plot_min_angles(path: Path, methods: dict[str, Method]) -> Path:
    fig = _figure(6.4, 4.0)
    ax = fig.add_subplot()
    bins = np.linspace(0, 60, 61)
    for k in ("input", "sem_lifted", "sem", "pymeshlab_isotropic", "fast_simplification"):
        m = methods.get(k)
        if not m or not m.ok:
            continue
        mn = m.quality["triangles"]["_per_face_min_angle"]
        w = np.full(len(mn), 100.0 / len(mn))
        ax.hist(mn, bins=bins, weights=w, histtype="step", lw=1.6 if k == "sem" else 1.1,
                color=COLORS[k], label=f"{LABELS[k]} (mean {mn.mean():.1f}°)",
                ls="--" if k in ("input", "sem_lifted") else "-")
    ax.axvline(30, color="0.6", lw=0.8, ls=":")
    ax.set_xlabel("smallest angle of a face (degrees; 60° = equilateral)")
    ax.set_ylabel("faces (%) per 1° bin")
    ax.legend(fontsize=7, loc="upper left")
    ax.set_xlim(0, 60)
    return _save(fig, path)


def plot_valence(path: Path, methods: dict[str, Method]) -> Path:
    fig = _figure(6.4, 3.6)
    ax = fig.add_subplot()
    keys = [k for k in ("input", "sem_lifted", "sem", "pymeshlab_isotropic",
                        "fast_simplification") if methods.get(k) and methods[k].ok]
    vals = np.arange(3, 11)
    width = 0.8 / len(keys)
    for i, k in enumerate(keys):
        h = methods[k].quality["valence"]["interior_histogram"]
        tot = sum(h.values())
        y = [100.0 * (h.get(str(v), 0) if v < 10 else
                      sum(c for k2, c in h.items() if int(k2) >= 10)) / tot for v in vals]
        ax.bar(vals - 0.4 + (i + 0.5) * width, y, width, color=COLORS[k], label=LABELS[k])
    ax.set_xticks(vals)
    ax.set_xticklabels([str(v) if v < 10 else "10+" for v in vals])
    ax.set_xlabel("valence of interior vertices (6 = regular)")
    ax.set_ylabel("interior vertices (%)")
    ax.legend(fontsize=7)
    return _save(fig, path)


def plot_disk(path: Path, remesh, methods: dict[str, Method]) -> Path:
    fig = _figure(11.0, 5.2)
    axs = fig.subplots(1, 2)
    mn = methods["sem"].quality["triangles"]["_per_face_min_angle"]
    uv, F = remesh.uv, remesh.F
    for ax, zoom in zip(axs, (False, True)):
        pc = PolyCollection(uv[F], array=mn, cmap="RdYlGn", clim=(0, 60),
                            edgecolors="k" if zoom else "none",
                            linewidths=0.2 if zoom else 0, rasterized=True)
        ax.add_collection(pc)
        ax.set_aspect("equal")
        if zoom:
            ax.set_xlim(0.70, 1.01)
            ax.set_ylim(-0.155, 0.155)
            ax.set_title("zoom at the rim (right edge of the disk)", fontsize=9)
        else:
            ax.set_xlim(-1.02, 1.02)
            ax.set_ylim(-1.02, 1.02)
            ax.set_title("the whole disk", fontsize=9)
    cb = fig.colorbar(pc, ax=list(axs), shrink=0.85)
    cb.set_label("smallest angle of the face on the surface (°)")
    fig.suptitle("Our remesh on the disk: faces coloured by their smallest angle on the surface "
                 "(red: skewed by the map's angle distortion)", fontsize=9)
    return _save(fig, path)


# ------------------------------------------------------------------------------- HTML


def _fmt(x, digits=2, pct=False):
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "–"
    if pct:
        x = 100.0 * x
    if isinstance(x, (int, np.integer)):
        return f"{int(x)}"
    return f"{x:.{digits}f}"


ROWS = [
    # (label, unit, getter, better: 'low'|'high'|None, digits, pct)
    ("vertices", "count", lambda q, m: q["facts"]["vertices"], None, 0, False),
    ("faces", "count", lambda q, m: q["facts"]["faces"], None, 0, False),
    ("one disk (χ = 1, one boundary loop, manifold, oriented)", "",
     lambda q, m: "yes" if q["is_disk"] else
     f"no (χ = {q['facts']['euler_characteristic']}, {q['facts']['boundary_loops']} loops, "
     f"{q['facts']['components']} components)", None, 0, False),
    ("degenerate faces", "count", lambda q, m: q["facts"]["degenerate_faces"], "low", 0, False),
    ("smallest angle", "°", lambda q, m: q["triangles"]["min_angle_deg"], "high", 2, False),
    ("5th percentile of the faces' smallest angles", "°",
     lambda q, m: q["triangles"]["min_angle_p05_deg"], "high", 1, False),
    ("mean of the faces' smallest angles", "°",
     lambda q, m: q["triangles"]["mean_min_angle_deg"], "high", 1, False),
    ("faces with smallest angle < 30°", "%",
     lambda q, m: q["triangles"]["fraction_min_angle_below_30"], "low", 1, True),
    ("largest angle", "°", lambda q, m: q["triangles"]["max_angle_deg"], "low", 1, False),
    ("interior vertices of valence 6", "%",
     lambda q, m: q["valence"]["interior_fraction_6"], "high", 1, True),
    ("coefficient of variation of face areas", "SD/mean",
     lambda q, m: q["triangles"]["area_cv"], "low", 3, False),
    ("coefficient of variation of edge lengths", "SD/mean",
     lambda q, m: q["triangles"]["edge_length_cv"], "low", 3, False),
    ("Hausdorff distance, two-sided", "% of bbox diagonal",
     lambda q, m: q.get("distance", {}).get("hausdorff_rel"), "low", 3, True),
    ("… output → input (max)", "% of bbox diagonal",
     lambda q, m: q.get("distance", {}).get("output_to_input", {}).get("max_rel"), "low", 3,
     True),
    ("… input → output (max)", "% of bbox diagonal",
     lambda q, m: q.get("distance", {}).get("input_to_output", {}).get("max_rel"), "low", 3,
     True),
    ("RMS distance, two-sided", "% of bbox diagonal",
     lambda q, m: q.get("distance", {}).get("rms_rel"), "low", 4, True),
    ("time", "s", lambda q, m: m.seconds, "low", 2, False),
]


def comparison_table(methods: dict[str, Method]) -> list[dict]:
    """The report's rows as plain data (also written to ``remesh_metrics.json``)."""
    rows = []
    for label, unit, get, better, digits, pct in ROWS:
        row = {"measure": label, "unit": unit, "better": better, "values": {}}
        for k, m in methods.items():
            try:
                row["values"][k] = get(m.quality, m) if m.ok else None
            except (KeyError, TypeError):
                row["values"][k] = None
        row["digits"], row["pct"] = digits, pct
        rows.append(row)
    return rows


def _best(row) -> set:
    if row["better"] is None:
        return set()
    vals = {k: v for k, v in row["values"].items() if k in COMPARED and isinstance(
        v, (int, float, np.integer, np.floating)) and v is not None and np.isfinite(v)}
    if len(vals) < 2:
        return set()
    target = (min if row["better"] == "low" else max)(vals.values())
    return {k for k, v in vals.items() if np.isclose(v, target, rtol=1e-9, atol=0)}


def verdicts(rows, methods) -> dict[str, tuple[list[str], list[str]]]:
    """Per baseline: the measures where ours is better, and those where it is worse (ties
    are left out)."""
    out = {}
    for other in ("pymeshlab_isotropic", "fast_simplification"):
        if other not in methods or not methods[other].ok:
            continue
        better, worse = [], []
        for row in rows:
            a, b = row["values"].get("sem"), row["values"].get(other)
            if row["better"] is None or not all(isinstance(x, (int, float, np.integer,
                                                                np.floating)) for x in (a, b)):
                continue
            if np.isclose(a, b, rtol=1e-9, atol=0):
                continue
            ours_better = a < b if row["better"] == "low" else a > b
            text = (f"{row['measure']}: {_fmt(a, row['digits'], row['pct'])} vs "
                    f"{_fmt(b, row['digits'], row['pct'])} {row['unit']}").rstrip()
            (better if ours_better else worse).append(text)
        out[other] = (better, worse)
    return out


def write_report(folder: Path, methods: dict[str, Method], remesh, meta: dict,
                 figures: bool = True) -> list[Path]:
    """``report.html`` and its figures into ``folder``; returns the paths written."""
    folder = Path(folder)
    V_in, F_in = methods["input"].V, methods["input"].F
    paths = []
    if figures:
        paths.append(plot_renders(folder / "remesh_renders.png", methods, V_in, F_in))
        paths.append(plot_min_angles(folder / "remesh_min_angle.png", methods))
        paths.append(plot_valence(folder / "remesh_valence.png", methods))
        paths.append(plot_disk(folder / "remesh_disk.png", remesh, methods))
    rows = comparison_table(methods)
    paths.append(_write_html(folder / "report.html", rows, methods, meta,
                             verdicts(rows, methods), [p.name for p in paths]))
    return paths


def _write_html(path: Path, rows, methods, meta, verdict, figures) -> Path:
    e = html.escape
    keys = [k for k in ("input", "sem_lifted", "sem", "pymeshlab_isotropic",
                        "fast_simplification") if k in methods]
    head = "".join(f"<th>{e(LABELS[k])}</th>" for k in keys)
    body = []
    for row in rows:
        best = _best(row)
        cells = []
        for k in keys:
            v = row["values"].get(k)
            m = methods[k]
            if not m.ok:
                txt = e(m.note) if row is rows[0] else ""
                cells.append(f'<td class="na">{txt}</td>')
                continue
            txt = v if isinstance(v, str) else _fmt(v, row["digits"], row["pct"])
            cls = ' class="best"' if k in best else ""
            cells.append(f"<td{cls}>{e(str(txt))}</td>")
        body.append(f"<tr><th>{e(row['measure'])}</th><td class='unit'>{e(row['unit'])}</td>"
                    + "".join(cells) + "</tr>")
    pm = meta.get("parameterization", {})
    dist = methods["sem"].quality.get("distance", {})
    notes = {
        "sem": f"time = sample + Delaunay + locate + lift + improve; the SEM map itself took "
               f"{meta.get('parameterization_seconds', float('nan')):.2f} s more",
        "pymeshlab_isotropic": "",
        "fast_simplification": "",
    }
    for k in ("pymeshlab_isotropic", "fast_simplification"):
        m = methods.get(k)
        if m is not None and m.ok:
            runs = m.extra.get("runs", [])
            notes[k] = (f"time of the reported run; {len(runs)} run(s) to hit the vertex count "
                        f"took {m.extra.get('seconds_all_runs', float('nan')):.2f} s; "
                        f"parameters {e(str(m.extra.get('parameters')))}")
        elif m is not None:
            notes[k] = m.note
    li = lambda xs: "".join(f"<li>{e(x)}</li>" for x in xs) or "<li>none</li>"  # noqa: E731
    imgs = {
        "remesh_renders.png": "Renders: full view (top), zoom in the middle (purple box) and "
                              "where our remesh is farthest from the input (red box), edges "
                              "drawn. Same view and windows for every mesh.",
        "remesh_min_angle.png": "Smallest angle per face, as a share of the faces per 1° bin. "
                                "Right is better; 60° is equilateral.",
        "remesh_valence.png": "Valence of interior vertices (6 is regular).",
        "remesh_disk.png": "Our remesh on the disk, coloured by the smallest angle of each face "
                           "on the surface: the disk triangulation is nearly equilateral, so "
                           "red shows the map's angle distortion that improvement could not "
                           "remove.",
    }
    fig_html = "".join(
        f'<figure><img src="{e(name)}" alt="{e(name)}"><figcaption>{e(imgs.get(name, ""))}'
        f"</figcaption></figure>" for name in figures)
    info = meta.get("remesh", {})
    imp = info.get("improve", {})
    versus = "".join(
        f"<h2>Ours against {e(LABELS[k])}</h2><div class='vs'><div><h3>ours better</h3>"
        f"<ul>{li(b)}</ul></div><div><h3>ours worse</h3><ul>{li(w)}</ul></div></div>"
        for k, (b, w) in verdict.items()) or "<p>No baseline was run (--no-compare).</p>"
    dd = meta.get("distortion", {})
    aniso = (f", stretch anisotropy σ₁/σ₂ (area-weighted) median {dd['anisotropy_median']:.1f}, "
             f"90th percentile {dd['anisotropy_p90']:.1f}, above 10:1 on "
             f"{100 * dd['anisotropy_area_above_10']:.0f} % of the surface"
             if "anisotropy_median" in dd else "")
    warn = "".join(f'<p class="warn"><b>Warning:</b> {e(w)}.</p>\n'
                   for w in meta.get("warnings", []))
    text = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>Remesh report: {e(meta.get('name', ''))}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1200px; color: #222;
       line-height: 1.45; padding: 0 1em; }}
table {{ border-collapse: collapse; font-size: 0.9em; margin: 1em 0; }}
th, td {{ border: 1px solid #ccc; padding: 0.3em 0.6em; text-align: right; }}
th {{ background: #f3f3f3; }} tbody th {{ text-align: left; font-weight: normal; }}
td.unit {{ color: #666; text-align: left; }} td.best {{ background: #dff0d8; font-weight: bold; }}
td.na {{ color: #888; font-size: 0.85em; text-align: left; }}
figure {{ margin: 1.5em 0; }} img {{ max-width: 100%; border: 1px solid #ddd; }}
figcaption, .caption {{ color: #555; font-size: 0.9em; }}
code {{ background: #f4f4f4; padding: 0 0.2em; }}
p.warn {{ background: #fcf3d9; border-left: 4px solid #e0a800; padding: 0.5em 0.8em; }}
.vs {{ display: flex; gap: 2em; }} .vs > div {{ flex: 1; }} h3 {{ margin: 0.3em 0; }}
</style></head><body>
<h1>Uniform remeshing through the SEM disk map: {e(meta.get('name', ''))}</h1>
<p>Input: <code>{e(str(meta.get('source', '')))}</code> — {len(methods['input'].V)} vertices,
{len(methods['input'].F)} faces after repair; bounding-box diagonal
{dist.get('scale_bbox_diagonal', float('nan')):.4g} (the input's units). Requested:
{e(str(meta.get('target')))} vertices, pattern <code>{e(str(info.get('pattern')))}</code>.
SEM map: {e(str(pm.get('mode')))} mode, {e(str(pm.get('iterations')))} iterations, mean angular
distortion {meta.get('angular_distortion_deg', float('nan')):.1f}°{aniso}.</p>
{warn}
<h2>Side by side, at the same vertex count</h2>
<table><thead><tr><th>measure</th><th>unit</th>{head}</tr></thead>
<tbody>{''.join(body)}</tbody></table>
<p class="caption">Green: best of the three compared methods (ours improved, pymeshlab,
decimation); the input and our plain lift are shown for reference. Angles are measured on the
3D faces. Valence counts edges at interior vertices. Distances: samples on each surface — all
vertices, edge midpoints and face centroids plus {dist.get('random_samples_per_side', 0)}
points uniform by area (seed 0) — and the exact Euclidean distance of each sample to the other
surface's triangles (point–triangle closest points with a nearest-centroid search and an exact
bound); Hausdorff = the larger one-sided maximum (a sampled lower bound of the continuous
value), RMS = root mean square over the area-uniform samples of both sides. Relative to the
input's bounding-box diagonal. Times on this machine, wall clock; {e(notes['sem'])}.
pymeshlab: {e(notes['pymeshlab_isotropic'])}. Decimation: {e(notes['fast_simplification'])}.</p>

{versus}
<p class="caption">Our remesh keeps every vertex exactly on the input surface (each vertex is a
disk position lifted by eq. (1)), hits the vertex count exactly or within 2 %, comes with its
own disk parameterization (the <code>vt</code> of <code>remeshed.obj</code>), and carries
colours and landmarks. Its limits: the equiareal map distorts angles, so uniform samples are
skewed on the surface where the distortion is large (long protrusions, deep folds); the
improvement step (Delaunay flips and tangential relaxation on the surface, splits of edges that
leave the surface, {imp.get('sag_splits', 0)} here, balanced by as many collapses of the
shortest edges) removes most but not all of it, and sharp features are kept only at corner
vertices ({imp.get('corners_snapped', 0)} interior, {imp.get('rim_corners_snapped', 0)} on
the boundary), not along creases.</p>
{fig_html}
</body></html>
"""
    path.write_text(text, encoding="utf-8")
    return path


HAUSDORFF_GOAL = 0.005        # of the bounding-box diagonal
ANISOTROPY_SHARE = 0.25       # of the surface stretched more than 10:1


def remesh_warnings(distortion: dict, methods: dict) -> list[str]:
    """What the user should know before trusting the remesh, one sentence per finding.

    ``distortion``: the map's summary (:func:`..geometry.metrics.distortion_summary`, with the
    stretch anisotropy); ``methods``: ``remesh_metrics.json``'s ``methods`` block."""
    out = []
    share = distortion.get("anisotropy_area_above_10", 0.0)
    if share > ANISOTROPY_SHARE:
        out.append(f"the SEM map stretches {100 * share:.0f} % of the surface more than 10:1 "
                   f"(median σ₁/σ₂ = {distortion['anisotropy_median']:.1f}): uniform disk "
                   f"samples are that much farther apart along one direction there, so the "
                   f"lifted triangles are skewed before the improvement step")
    ours = methods.get("sem", {}).get("distance", {}).get("hausdorff_rel")
    theirs = methods.get("pymeshlab_isotropic", {}).get("distance", {}).get("hausdorff_rel")
    if ours is not None and ours > HAUSDORFF_GOAL:
        ref = f"; pymeshlab's is {100 * theirs:.2f} %" if theirs is not None else ""
        out.append(f"the remesh leaves the input surface by up to {100 * ours:.2f} % of the "
                   f"bounding-box diagonal (Hausdorff){ref}: edges bridge over regions the map "
                   f"squeezes into slivers (protrusions, deep folds); more vertices reduce it")
    return out


def remesh_outputs(mesh, parameterization, remesh, out_dir, input_info: dict | None = None,
                   compare: bool = True, report: bool = True, figures: bool = True,
                   n_random: int = 200_000, progress=None):
    """Measure, compare and write everything of the remesh stage into ``out_dir``; returns
    ``(files, metrics)``."""
    from .remesh import write_remesh

    t0 = time.perf_counter()
    target = remesh.info.get("requested_vertices") or len(remesh.V)
    methods = compare_methods(mesh.V, mesh.F, remesh, target, compare, n_random,
                              progress=progress)
    t_measure = time.perf_counter() - t0
    pm = parameterization.metrics
    rows = comparison_table(methods)
    metrics = {
        "input": dict(input_info or {}, vertices=int(len(mesh.V)), faces=int(len(mesh.F)),
                      bbox_diagonal=bounding_box_diagonal(mesh.V)),
        "parameterization": {"mode": pm["parameterization"]["mode"],
                             "iterations": pm["parameterization"]["iterations"],
                             "status": pm["parameterization"]["status"],
                             "distortion": pm["distortion"],
                             "seconds": float(sum(pm["seconds"].values()))},
        "remesh": {k: v for k, v in remesh.info.items() if k != "attributes"},
        "landmarks": remesh.landmarks,
        "methods": {k: {"label": LABELS[k], "available": m.ok, "note": m.note,
                        "seconds": m.seconds, **plain_metrics(m.quality),
                        **({"baseline": m.extra} if m.extra else {})}
                    for k, m in methods.items()},
        "table": [{k: v for k, v in r.items() if k not in ("digits", "pct")} for r in rows],
        "seconds": dict(remesh.seconds, measure=t_measure),
    }
    metrics["warnings"] = remesh_warnings(pm["distortion"], metrics["methods"])
    metrics["summary"] = {f"vs_{k}": {"ours_better": b, "ours_worse": w}
                          for k, (b, w) in verdicts(rows, methods).items()}
    meta = {"name": Path(str((input_info or {}).get("source", "mesh"))).stem,
            "source": (input_info or {}).get("source", ""), "target": target,
            "parameterization": metrics["parameterization"],
            "parameterization_seconds": metrics["parameterization"]["seconds"],
            "angular_distortion_deg": pm["distortion"]["angular_distortion_mean_deg"],
            "distortion": pm["distortion"], "warnings": metrics["warnings"],
            "remesh": metrics["remesh"]}
    writer = (lambda tmp: write_report(tmp, methods, remesh, meta, figures)) if report else None
    files = write_remesh(remesh, out_dir, metrics, writer)
    return files, metrics
