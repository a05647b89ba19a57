"""The remesh report (pipeline/report/remesh.py): the comparison table, the verdicts, the
warnings and the page, on small meshes."""

from __future__ import annotations

import numpy as np

from pipeline.geometry.remesh_quality import remesh_quality
from pipeline.report.remesh import (Method, below_min_angle_warning, comparison_table,
                                    remesh_warnings, verdicts, write_report)
from pipeline.sample import make_face


def _methods():
    a, b = make_face(900), make_face(400)
    V, F = np.asarray(a.V, float), np.asarray(a.F)
    Vb, Fb = np.asarray(b.V, float), np.asarray(b.F)
    return {"input": Method("input", V, F, None, remesh_quality(V, F, V, F, distance=False)),
            "sem": Method("sem", Vb, Fb, 0.5, remesh_quality(V, F, Vb, Fb, 2000, 0)),
            "pymeshlab_isotropic": Method("pymeshlab_isotropic", None, None,
                                          note="pymeshlab is not installed"),
            "fast_simplification": Method("fast_simplification", Vb, Fb, 0.1,
                                          remesh_quality(V, F, Vb, Fb, 2000, 0))}


def test_table_verdicts_and_page(tmp_path):
    methods = _methods()
    rows = comparison_table(methods)
    assert rows[0]["measure"] == "vertices" and rows[0]["values"]["sem"] == len(methods["sem"].V)
    assert all(r["values"]["pymeshlab_isotropic"] is None for r in rows)
    v = verdicts(rows, methods)
    # the same mesh on both sides: every measure ties except the time
    assert set(v) == {"fast_simplification"}
    assert v["fast_simplification"] == ([], ["time: 0.50 vs 0.10 s"])
    paths = write_report(tmp_path, methods, np.zeros((len(methods["sem"].V), 2)),
                         methods["sem"].F, {"name": "face", "target": 400}, figures=False)
    assert [p.name for p in paths] == ["report.html"]
    text = paths[0].read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>") and "<table>" in text
    assert "pymeshlab is not installed" in text and "&amp;#x27;" not in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.html"]
    assert "Green: best of the three compared methods" in text


def test_verdicts_name_a_baseline_that_is_not_a_disk():
    """A baseline whose output is two disks (χ = 2, 2 loops, 2 components) loses the topology
    line, which the table marks no winner on; ours, a disk, wins it."""
    methods = _methods()
    sem = methods["sem"]
    V2 = np.vstack([sem.V, sem.V + [10.0, 0.0, 0.0]])
    F2 = np.vstack([sem.F, sem.F + len(sem.V)])
    V, F = methods["input"].V, methods["input"].F
    methods["fast_simplification"] = Method("fast_simplification", V2, F2, 0.5,
                                            remesh_quality(V, F, V2, F2, 2000, 0))
    better, worse = verdicts(comparison_table(methods), methods)["fast_simplification"]
    assert ("one disk (χ = 1, one boundary loop; with k holes χ = 1 − k, 1 + k loops) or closed "
            "genus 0 (χ = 2); manifold, oriented: yes, a disk vs no (χ = 2, 2 loops, 2 "
            "components)") in better
    assert not any(t.startswith("one disk") for t in worse)
    methods["sem"], methods["fast_simplification"] = methods["fast_simplification"], sem
    better, worse = verdicts(comparison_table(methods), methods)["fast_simplification"]
    assert any(t.startswith("one disk") and t.endswith("vs yes, a disk") for t in worse)


def test_page_without_baselines_says_so(tmp_path):
    """--no-compare: only the input and ours were measured; the caption names neither a
    comparison nor empty baseline notes."""
    methods = {k: m for k, m in _methods().items() if k in ("input", "sem")}
    paths = write_report(tmp_path, methods, np.zeros((len(methods["sem"].V), 2)),
                         methods["sem"].F, {"name": "face", "target": 400}, figures=False)
    text = paths[0].read_text(encoding="utf-8")
    assert "No baseline was run (--no-compare)" in text
    assert "neither the baselines nor our plain lift were measured" in text
    assert "Green: best" not in text and "pymeshlab: ." not in text
    assert "Decimation: ." not in text


def test_page_lists_the_intake_repairs_only_when_there_are_some(tmp_path):
    methods = {k: m for k, m in _methods().items() if k in ("input", "sem")}
    uv = np.zeros((len(methods["sem"].V), 2))
    repairs = ["split 1 non-manifold vertex (bowtie) into one vertex per fan",
               "split 2 leaf faces <all corners on the boundary>"]
    meta = {"name": "face", "target": 400, "repairs": repairs}
    text = write_report(tmp_path, methods, uv, methods["sem"].F, meta,
                        figures=False)[0].read_text(encoding="utf-8")
    assert ("<p>The intake repaired the input: split 1 non-manifold vertex (bowtie) into one "
            "vertex per fan; split 2 leaf faces &lt;all corners on the boundary&gt;.</p>") in text
    text = write_report(tmp_path, methods, uv, methods["sem"].F, dict(meta, repairs=[]),
                        figures=False)[0].read_text(encoding="utf-8")
    assert "The intake repaired" not in text


def test_remesh_warnings_name_the_anisotropy_and_the_hausdorff_excess():
    calm = {"anisotropy_median": 2.0, "anisotropy_p90": 4.0, "anisotropy_area_above_10": 0.25}
    close = {"sem": {"distance": {"hausdorff_rel": 0.005}},
             "pymeshlab_isotropic": {"distance": {"hausdorff_rel": 0.003}}}
    assert remesh_warnings(calm, close) == []                  # both exactly at the limits
    assert remesh_warnings({}, {}) == []                        # nothing measured: no claim
    stretched = dict(calm, anisotropy_median=6.8, anisotropy_area_above_10=0.31)
    far = {"sem": {"distance": {"hausdorff_rel": 0.0089}},
           "pymeshlab_isotropic": {"distance": {"hausdorff_rel": 0.0031}}}
    w = remesh_warnings(stretched, far)
    assert len(w) == 2
    assert "31 % of the surface more than 10:1" in w[0] and "σ₁/σ₂ = 6.8" in w[0]
    assert "0.89 %" in w[1] and "pymeshlab's is 0.31 %" in w[1]
    w = remesh_warnings(calm, {"sem": far["sem"]})              # --no-compare: no reference
    assert len(w) == 1 and "pymeshlab" not in w[0]


def test_remesh_warnings_count_the_folds_in_the_singular_and_the_plural():
    one, three = ({"sem": {"distance": {"turned_over_faces": k}}} for k in (1, 3))
    assert remesh_warnings({}, one) == [
        "1 face of the remesh is turned over against the input (its normal points against the "
        "input's where it lies): the remesh folds there"]
    assert remesh_warnings({}, three)[0].startswith(
        "3 faces of the remesh are turned over against the input (their normals point")


def test_remesh_warnings_say_when_the_work_budget_ended_the_repairs():
    assert remesh_warnings({}, {}) == [] and remesh_warnings({}, {}, trials_cut=0) == []
    w = remesh_warnings({}, {}, trials_cut=2)
    assert len(w) == 1 and "work budget" in w[0] and "TRIAL_WORK" in w[0]


def test_remesh_warnings_say_the_remesh_covers_the_holes_the_intake_closed():
    assert remesh_warnings({}, {}, holes_closed=0) == []
    assert remesh_warnings({}, {}, holes_closed=1) == [
        "the remesh covers the 1 hole close_holes filled with fans to a new centre vertex: it "
        "has one boundary where the input had 2, and its surface there is the fans', not the "
        "input's"]
    assert "the 3 holes close_holes filled" in remesh_warnings({}, {}, holes_closed=3)[0]


def test_remesh_warnings_name_a_vertex_count_off_the_request():
    """Within 2 % of the request: nothing; beyond it, one sentence with the count, the
    deviation and its cause (the rim's share of the samples when it is over half)."""
    assert remesh_warnings({}, {}, count={"requested": 1000, "vertices": 1020, "rim": 90}) == []
    [w] = remesh_warnings({}, {}, count={"requested": 100, "vertices": 192, "rim": 27})
    assert w.startswith("the remesh has 192 vertices, +92 % from the 100 requested: the "
                        "improvement's splits")
    [w] = remesh_warnings({}, {}, count={"requested": 100, "vertices": 130, "rim": 60})
    assert "the boundary alone took 60 rim samples" in w
    [w] = remesh_warnings({}, {}, count={"requested": 1000, "vertices": 970, "rim": 90})
    assert w == "the remesh has 970 vertices, -3 % from the 1000 requested"


def test_below_min_angle_warning_names_forcing_corners_and_counts_the_rest():
    """The faces left below the minimum angle: those a sharp input corner forces, with the
    corner named (its angle sum, its faces, their smallest angle there, and the even split of
    the sum where the report has it), and those no corner forces, counted apart; singular for
    one face."""
    below = {"threshold_deg": 20.0, "faces": 3, "at_input_corners": 1, "unforced_faces": 2,
             "input_corner_vertices": [136],
             "input_corners": [{"vertex": 136, "angle_sum_deg": 26.725, "faces": 1,
                                "smallest_angle_deg": 8.69}]}
    assert below_min_angle_warning(below) == (
        "3 faces keep an angle below 20°: 1 forced by sharp input corners (input vertex 136, a "
        "26.7° corner: 1 face, 8.7° there); 2 that no input corner forces (the minimum-angle "
        "pass and its refinement could not raise them)")
    one = {"threshold_deg": 20.0, "faces": 1, "at_input_corners": 0, "unforced_faces": 1}
    assert below_min_angle_warning(one).startswith("1 face keeps an angle below 20°: 1 that")
    assert remesh_warnings({}, {}, below) == [below_min_angle_warning(below)]
    below["input_corners"][0]["even_split_deg"] = 13.3625
    assert "26.7° corner: 1 face, 8.7° there, 13.4° in an even split); 2 that" in \
        below_min_angle_warning(below)


def test_landmarks_section_gives_the_distances_and_every_landmark(tmp_path):
    from pipeline.report.remesh import landmarks_html

    assert landmarks_html({}, 1.0) == ""
    carried = {"nose <tip>": {"input_vertex": 7, "vertex": 3, "distance": 0.5},
               "chin": {"input_vertex": -1, "vertex": 9, "distance": 0.25}}
    text = landmarks_html(carried, 2.0)
    assert ("2 landmarks carried to the remesh (<code>remeshed_landmarks.json</code>), 0 of "
            "them on a vertex exactly on their input vertex; distance from the input vertex at "
            "most 0.5, mean 0.375 (0.25 and 0.19 target edge lengths).") in text
    carried["chin"]["distance"] = 0.0
    assert "1 of them on a vertex exactly" in landmarks_html(carried, 2.0)
    carried["nose <tip>"]["distance"] = 0.0
    assert ("2 landmarks carried to the remesh (<code>remeshed_landmarks.json</code>), each on a "
            "vertex exactly on its input vertex.</p>") in landmarks_html(carried, 2.0)
    assert "<tr><th>nose &lt;tip&gt;</th><td>7</td><td>3</td><td>0.5</td></tr>" in text
    assert "<tr><th>chin</th><td>-1</td><td>9</td><td>0.25</td></tr>" in text
    methods = _methods()
    page = write_report(tmp_path, methods, np.zeros((len(methods["sem"].V), 2)),
                        methods["sem"].F, {"name": "face", "target": 400, "landmarks": carried},
                        figures=False)[0].read_text(encoding="utf-8")
    assert "<h2>Landmarks</h2>" in page and "target edge" not in page   # no edge length given
