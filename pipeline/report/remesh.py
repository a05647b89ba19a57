"""The remesh stage's report: our remesh measured side by side with what users remesh with today.

The stage (:func:`pipeline.stages.remesh.remesh_outputs`) measures every mesh into a
:class:`Method`; :func:`write_report` writes ``report.html`` (self-contained apart from its PNGs,
linked relatively) with one table, the verdicts, the figures and captions saying how
everything was measured and where each method wins (drawn by :mod:`.remesh_figures`, imported
only when figures are written):

* ``remesh_renders.png`` — every mesh seen the same way (the report camera,
  :func:`.figure.camera_for` of the input, flat shading, back faces darker), full view and two
  zoomed crops with the edges drawn: the middle of the surface and the place where our remesh is
  farthest from the input;
* ``remesh_min_angle.png`` — distribution of the smallest angle of every face;
* ``remesh_valence.png`` — valence of interior vertices;
* ``remesh_disk.png`` — our remesh on the disk, faces coloured by their smallest angle on the
  surface (where the map's angle distortion is, and what improvement did); for a closed mesh
  ``remesh_sphere.png`` instead: the remesh on the sphere, both hemispheres seen from outside,
  coloured the same way.

:func:`comparison_table`, :func:`verdicts` and :func:`remesh_warnings` also feed
``remesh_metrics.json``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .remesh_methods import LABELS, Method

__all__ = ["Method", "LABELS", "comparison_table", "verdicts", "remesh_warnings",
           "plain_metrics", "write_report"]

COMPARED = ("sem", "pymeshlab_isotropic", "fast_simplification")
COUNT_TOLERANCE = 0.02      # a vertex count farther than this from the request is a warning
STYLE = """
.cmp th, .cmp td { text-align: right; } .cmp tbody th { text-align: left; }
td.unit { color: #666; text-align: left; } td.best { background: #dff0d8; font-weight: bold; }
.cmp td.unit, .cmp td.na { text-align: left; }
td.na { color: #888; font-size: 0.85em; }
.vs { display: flex; gap: 2em; } .vs > div { flex: 1; } h3 { margin: 0.3em 0; }
"""


def plain_metrics(q: dict) -> dict:
    """A quality dict without its per-face arrays (keys starting with ``_``), for JSON."""
    if isinstance(q, dict):
        return {k: plain_metrics(v) for k, v in q.items() if not str(k).startswith("_")}
    return q


# ------------------------------------------------------------------------------- HTML


def _fmt(x, digits=2, pct=False):
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "–"
    if pct:
        x = 100.0 * x
    if isinstance(x, (int, np.integer)):
        return f"{int(x)}"
    return f"{x:.{digits}f}"


TOPOLOGY = ("one disk (χ = 1, one boundary loop; with k holes χ = 1 − k, 1 + k loops) or closed "
            "genus 0 (χ = 2); manifold, oriented")


def topology(q: dict) -> str:
    """What a quality dict says of the mesh's topology: ``yes, …`` for a disk (with its holes,
    if any) or a closed genus-0 surface, else ``no (χ, loops, components)``."""
    if q["is_disk"]:
        return "yes, a disk"
    if q.get("holes") and q.get("is_disk_with_holes"):
        return f"yes, a disk with {q['holes']} {'hole' if q['holes'] == 1 else 'holes'}"
    if q.get("is_sphere"):
        return "yes, closed genus 0"
    f = q["facts"]
    return (f"no (χ = {f['euler_characteristic']}, {f['boundary_loops']} loops, "
            f"{f['components']} components)")


ROWS = [
    # (label, unit, getter, better: 'low'|'high'|None, digits, pct)
    ("vertices", "count", lambda q, m: q["facts"]["vertices"], None, 0, False),
    ("faces", "count", lambda q, m: q["facts"]["faces"], None, 0, False),
    (TOPOLOGY, "", lambda q, m: topology(q), None, 0, False),
    ("degenerate faces", "count", lambda q, m: q["facts"]["degenerate_faces"], "low", 0, False),
    ("faces turned over against the input (folds)", "count",
     lambda q, m: q.get("distance", {}).get("turned_over_faces"), "low", 0, False),
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
    are left out); the topology counts where one mesh is a disk or closed genus 0 and the
    other is not."""
    out = {}
    for other in ("pymeshlab_isotropic", "fast_simplification"):
        if other not in methods or not methods[other].ok:
            continue
        better, worse = [], []
        for row in rows:
            a, b = row["values"].get("sem"), row["values"].get(other)
            if row["measure"] == TOPOLOGY and isinstance(a, str) and isinstance(b, str) \
                    and a.startswith("yes") != b.startswith("yes"):
                (better if a.startswith("yes") else worse).append(f"{TOPOLOGY}: {a} vs {b}")
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


def write_report(folder: Path, methods: dict[str, Method], uv: np.ndarray, F: np.ndarray,
                 meta: dict, figures: bool = True) -> list[Path]:
    """``report.html`` and its figures into ``folder``; returns the paths written.

    ``methods``: every measured mesh by key (``input``, ``sem_lifted``, ``sem``, baselines);
    ``uv`` (n×2), ``F`` (m×3): our remesh on the disk, or with ``uv`` n×3 (unit vectors) on
    the sphere; ``meta``: what the page says about the input (its repairs among it), the
    request, the map and the warnings."""
    folder = Path(folder)
    V_in, F_in = methods["input"].V, methods["input"].F
    paths = []
    if figures:
        from .remesh_figures import (plot_disk, plot_min_angles, plot_renders, plot_sphere,
                                     plot_valence)
        paths.append(plot_renders(folder / "remesh_renders.png", methods, V_in, F_in))
        paths.append(plot_min_angles(folder / "remesh_min_angle.png", methods))
        paths.append(plot_valence(folder / "remesh_valence.png", methods))
        if uv.shape[1] == 3:
            paths.append(plot_sphere(folder / "remesh_sphere.png", uv, F, methods))
        else:
            paths.append(plot_disk(folder / "remesh_disk.png", uv, F, methods))
    rows = comparison_table(methods)
    paths.append(_write_html(folder / "report.html", rows, methods, meta,
                             verdicts(rows, methods), [p.name for p in paths]))
    return paths


def landmarks_html(landmarks: dict, edge_length: float) -> str:
    """The page's section on the carried landmarks (empty without any): how far each one's
    remesh vertex is from its input vertex, also in target edge lengths ``edge_length``, and
    a folded table of all of them.

    ``landmarks``: ``{name: {"input_vertex", "vertex", "distance"}}``
    (:attr:`pipeline.stages.remesh.Remesh.landmarks`)."""
    from . import html as h

    if not landmarks:
        return ""
    e = h.esc
    d = np.array([x["distance"] for x in landmarks.values()], dtype=np.float64)
    in_edges = (f" ({d.max() / edge_length:.2f} and {d.mean() / edge_length:.2f} target edge "
                f"lengths)" if edge_length > 0 else "")
    rows = "".join(f"<tr><th>{e(str(name))}</th><td>{x['input_vertex']}</td><td>{x['vertex']}"
                   f"</td><td>{x['distance']:.4g}</td></tr>" for name, x in landmarks.items())
    how_far = ("each on a vertex exactly on its input vertex" if not d.any() else
               f"{np.count_nonzero(d == 0)} of them on a vertex exactly on their input vertex; "
               f"distance from the input vertex at most {d.max():.4g}, mean {d.mean():.4g}"
               f"{in_edges}")
    return (f"<h2>Landmarks</h2><p>{len(d)} landmarks carried to the remesh "
            f"(<code>remeshed_landmarks.json</code>), {how_far}.</p>\n<details><summary>each "
            f"landmark</summary><table><thead><tr><th>name</th><th>input vertex</th><th>remesh "
            f"vertex</th><th>distance</th></tr></thead><tbody>{rows}</tbody></table></details>\n")


def _write_html(path: Path, rows, methods, meta, verdict, figures) -> Path:
    from . import html as h

    e = h.esc
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
                        f"parameters {m.extra.get('parameters')}")
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
        "remesh_sphere.png": "Our remesh on the sphere (the closed mesh's domain), both "
                             "hemispheres seen from outside, coloured by the smallest angle of "
                             "each face on the surface: the spherical triangulation is nearly "
                             "equilateral, so red shows the map's angle distortion that "
                             "improvement could not remove.",
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
    if any(k in methods for k in ("pymeshlab_isotropic", "fast_simplification")):
        reference = ("Green: best of the three compared methods (ours improved, pymeshlab, "
                     "decimation); the input and our plain lift are shown for reference.")
        baseline_notes = (f"pymeshlab: {e(notes['pymeshlab_isotropic'])}. "
                          f"Decimation: {e(notes['fast_simplification'])}.")
    else:
        reference = ("The input is shown for reference; with --no-compare neither the "
                     "baselines nor our plain lift were measured.")
        baseline_notes = ""
    dd = meta.get("distortion", {})
    aniso = (f", stretch anisotropy σ₁/σ₂ (area-weighted) median {dd['anisotropy_median']:.1f}, "
             f"90th percentile {dd['anisotropy_p90']:.1f}, above 10:1 on "
             f"{100 * dd['anisotropy_area_above_10']:.0f} % of the surface"
             if "anisotropy_median" in dd else "")
    warn = "".join(f'<p class="warn"><b>Warning:</b> {e(w)}.</p>\n'
                   for w in meta.get("warnings", []))
    repairs = meta.get("repairs") or []
    repaired = (f"<p>The intake repaired the input: {'; '.join(e(r) for r in repairs)}.</p>\n"
                if repairs else "")
    n_in = len(methods["input"].V)
    sphere = meta.get("domain") == "sphere"
    domain = "sphere" if sphere else "disk"
    own_map = ("its own map onto the sphere (not written: a texture coordinate is 2D, so "
               "<code>remeshed.obj</code> has no <code>vt</code>)" if sphere else
               "its own disk parameterization (the <code>vt</code> of <code>remeshed.obj</code>)")
    corners = (f"({imp.get('corners_snapped', 0)} snapped, "
               f"{imp.get('corners_inserted', 0)} inserted)" if sphere else
               f"({imp.get('corners_snapped', 0)} interior, {imp.get('rim_corners_snapped', 0)} "
               f"on the boundary)")
    text = f"""<p>Input: <code>{e(str(meta.get('source', '')))}</code> — {n_in} vertices,
{len(methods['input'].F)} faces after repair; bounding-box diagonal
{dist.get('scale_bbox_diagonal', float('nan')):.4g} (the input's units). Requested:
{e(str(meta.get('target')))} vertices, pattern <code>{e(str(info.get('pattern')))}</code>.
SEM map: {e(str(pm.get('mode')))} mode, {e(str(pm.get('iterations')))} iterations, mean angular
distortion {meta.get('angular_distortion_deg', float('nan')):.1f}°{aniso}.</p>
{repaired}{warn}
<h2>Side by side, at the same vertex count</h2>
<div class="cmp"><table><thead><tr><th>measure</th><th>unit</th>{head}</tr></thead>
<tbody>{''.join(body)}</tbody></table></div>
<p class="caption">{reference} Angles are measured on the
3D faces. Valence counts edges at interior vertices. Distances: samples on each surface — all
vertices, edge midpoints and face centroids plus {dist.get('random_samples_per_side', 0)}
points uniform by area (seed 0) — and the exact Euclidean distance of each sample to the other
surface's triangles (exact point–triangle distances through a bounding-volume hierarchy); Hausdorff = the larger one-sided maximum (a sampled lower bound of the continuous
value), RMS = root mean square over the area-uniform samples of both sides. Relative to the
input's bounding-box diagonal. Times on this machine, wall clock; {e(notes['sem'])}.
{baseline_notes}</p>

{versus}
<p class="caption">Our remesh keeps every vertex exactly on the input surface (each vertex is a
{domain} position lifted by eq. (1)), hits the vertex count exactly or within 2 %, comes with
{own_map}, and carries
colours and landmarks. Its limits: the equiareal map distorts angles, so uniform samples are
skewed on the surface where the distortion is large (long protrusions, deep folds); the
improvement step (rounds of splits, collapses, flips and relaxation judged by 3D lengths,
splits of edges that leave the surface, {imp.get('sag_splits', 0)} here, and of rim edges at
the input boundary vertices they cut off, {imp.get('rim_splits', 0)} here, balanced by
collapses of the shortest edges, and a pass on faces below 20° that ends by inserting vertices at
their off-centres) removes most but not all of it, and
sharp features are kept at corner
vertices {corners} and along the creases that fold back beyond 90° or run as smooth lines of the
shape ({imp.get('features_joined', 0)} remesh edges along them here), not along other creases.</p>
{landmarks_html(meta.get("landmarks") or {}, imp.get("target_edge_length", 0.0))}{fig_html}"""
    return h.write_page(path, f"Remesh report: {meta.get('name', '')}", text, style=STYLE,
                        h1=f"Uniform remeshing through the SEM {domain} map: "
                           f"{meta.get('name', '')}")


HAUSDORFF_GOAL = 0.005        # of the bounding-box diagonal
ANISOTROPY_SHARE = 0.25       # of the surface stretched more than 10:1


def below_min_angle_warning(below: dict) -> str:
    """One sentence on the faces the minimum-angle pass left below its threshold
    (``remesh.improve.below_min_angle``): how many, how many a sharp input corner forces and
    which (input vertex, its angle sum, its faces, their smallest angle there and, where the
    report has it, the even split of the sum among the fewest faces the corner can have; at
    most 10 named), and how many no corner forces."""
    n, thr = below["faces"], below["threshold_deg"]
    forced = below.get("at_input_corners", 0)
    unforced = below.get("unforced_faces", n - forced)
    corners = below.get("input_corners") or [{"vertex": v} for v in
                                             below.get("input_corner_vertices") or []]

    def corner(c):
        if "angle_sum_deg" not in c:
            return f"input vertex {c['vertex']}"
        even = f", {c['even_split_deg']:.1f}° in an even split" if "even_split_deg" in c else ""
        return (f"input vertex {c['vertex']}, a {c['angle_sum_deg']:.1f}° corner: "
                f"{c['faces']} face{'s' if c['faces'] != 1 else ''}, "
                f"{c['smallest_angle_deg']:.1f}° there{even}")
    parts = []
    if forced:
        named = "; ".join(corner(c) for c in corners[:10]) + (" …" if len(corners) > 10 else "")
        parts.append(f"{forced} forced by sharp input corners ({named})")
    if unforced:
        parts.append(f"{unforced} that no input corner forces (the minimum-angle pass and its "
                     f"refinement could not raise them)")
    return (f"{n} face{'s' if n != 1 else ''} keep{'s' if n == 1 else ''} an angle below "
            f"{thr:g}°: " + "; ".join(parts))


def remesh_warnings(distortion: dict, methods: dict, below: dict | None = None,
                    count: dict | None = None, trials_cut: int = 0,
                    holes_closed: int = 0, holes_covered: list | None = None) -> list[str]:
    """What the user should know before trusting the remesh, one sentence per finding.

    ``distortion``: the map's summary (:func:`..geometry.metrics.distortion_summary`, with the
    stretch anisotropy); ``methods``: ``remesh_metrics.json``'s ``methods`` block; ``below``:
    the faces the minimum-angle pass left (``remesh.improve.below_min_angle``); ``count``:
    ``{"requested", "vertices", "rim"}``, the vertex count asked for and made, and how many of
    the samples were on the rim; ``trials_cut``: the loops of trials the improvement's work
    budget ended (``remesh.improve.trials_cut``); ``holes_closed``: the input's holes the
    intake's ``close_holes`` filled (``input.repair.holes_closed``), which the remesh covers;
    ``holes_covered``: the loop sizes (input vertices) of the holes the remesh meant to keep
    open and covered instead (``remesh.improve.holes_covered``)."""
    out = []
    for size in holes_covered or []:
        out.append(f"the hole with a {size}-vertex loop could not be kept open (its loop's "
                   f"edges could not all be made or kept): the remesh covers it with the "
                   f"fan's surface close_holes filled it with, one boundary fewer than the "
                   f"input")
    if holes_closed:
        what = "hole" if holes_closed == 1 else "holes"
        out.append(f"the remesh covers the {holes_closed} {what} close_holes filled with fans "
                   f"to a new centre vertex: it has one boundary where the input had "
                   f"{holes_closed + 1}, and its surface there is the fans', not the input's")
    want = (count or {}).get("requested")
    got = (count or {}).get("vertices")
    if want and got is not None and abs(got - want) > COUNT_TOLERANCE * want:
        rim = count.get("rim") or 0
        why = (f": the boundary alone took {rim} rim samples at the spacing {want} vertices "
               f"give (a surface long and thin for that count); ask for more vertices"
               if rim > want / 2 else
               ": the improvement's splits (of edges the map stretches or that leave the "
               "surface) could not all be given back by collapses without making faces worse"
               if got > want else "")
        out.append(f"the remesh has {got} vertices, {100 * (got - want) / want:+.0f} % from the "
                   f"{want} requested{why}")
    if below and below.get("faces"):
        out.append(below_min_angle_warning(below))
    share = distortion.get("anisotropy_area_above_10", 0.0)
    if share > ANISOTROPY_SHARE:
        out.append(f"the SEM map stretches {100 * share:.0f} % of the surface more than 10:1 "
                   f"(median σ₁/σ₂ = {distortion['anisotropy_median']:.1f}): uniform samples "
                   f"of the map are that much farther apart along one direction there, so the "
                   f"lifted triangles are skewed before the improvement step")
    folds = methods.get("sem", {}).get("distance", {}).get("turned_over_faces")
    if folds:
        what = ("face of the remesh is", "its normal points", "it lies") if folds == 1 else \
            ("faces of the remesh are", "their normals point", "they lie")
        out.append(f"{folds} {what[0]} turned over against the input ({what[1]} against the "
                   f"input's where {what[2]}): the remesh folds there")
    if trials_cut:
        out.append("the fold repair and the refinement one face at a time stopped at their work "
                   "budget (improve.TRIAL_WORK × the vertex count) with folds or faces below "
                   "the minimum angle left untried (so many that the map likely crowds part "
                   "of the surface: a tube or finger narrower than the remesh)")
    for key, m in methods.items():
        if str(m.get("note", "")).startswith("failed"):
            out.append(f"{m.get('label', key)} {m['note']}; its column is empty")
    ours = methods.get("sem", {}).get("distance", {}).get("hausdorff_rel")
    theirs = methods.get("pymeshlab_isotropic", {}).get("distance", {}).get("hausdorff_rel")
    if ours is not None and ours > HAUSDORFF_GOAL:
        ref = f"; pymeshlab's is {100 * theirs:.2f} %" if theirs is not None else ""
        out.append(f"the remesh leaves the input surface by up to {100 * ours:.2f} % of the "
                   f"bounding-box diagonal (Hausdorff){ref}: edges bridge over regions the map "
                   f"squeezes into slivers (protrusions, deep folds); more vertices reduce it")
    return out
