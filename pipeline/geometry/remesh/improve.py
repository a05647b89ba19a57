"""Triangle-quality improvement of a lifted remesh (beyond the paper's §8), done on the disk.

An equiareal map keeps areas but distorts angles; where a shape has long protrusions or deep
folds (fingers, ears, sulci) the map squeezes them into thin slivers of the disk. Uniform disk
samples therefore have the right *density* on the surface but not the right *shape*: lifted
triangles are skewed, and across a sliver they bridge over the surface. The pass below
isotropically remeshes towards the target edge length ``L`` (3D, the mesh's units) with the
operations of Botsch & Kobbelt (2004) — split, collapse, flip, tangential smoothing — plus
splits where an edge leaves the surface, all made on the disk: a vertex is always a disk
position lifted by eq. (1), so it stays exactly on the input surface, and every face stays
counter-clockwise on the disk, so the output stays a parameterized disk.

The schedule (:func:`improve_remesh`):

1. given ``hole_loops``, locked vertices about ``L`` apart along each hole loop of the input,
   joined round it by kept edges that no step frees (:mod:`.holes`); snap (or insert) a
   locked vertex onto each sharp input corner (:mod:`.corners`), sharpest first, none
   within ``CORNER_GAP × L`` of one kept before or of a hole loop's edges; then locked
   vertices about ``L`` apart along the input's feature lines (the edges folded more than
   ``feature_angle_deg``, none of the holes' fans) and the edges between consecutive ones
   kept until the repairs free them (:mod:`.features`);
   then, given ``landmarks_uv``, one onto each landmark's input vertex, none within
   ``CORNER_GAP × L`` of a vertex locked before;
2. flips, then ``relax_iterations`` × (tangential smoothing, flips);
3. refinement: split the rim edges that cut off an input boundary vertex by more than
   ``RIM_TOL × refine_sag × L`` at that vertex (:mod:`.rim`); split edges farther than
   ``refine_sag × L`` from the surface; split once the
   edges still longer than ``LONG_EDGE × L`` (they lie along the map's stretch, on the surface,
   where the sag test cannot see them); flips; the sag splits again around what changed and
   what the rounds left (they can run out where a steep wall is squeezed against the rim),
   flips;
4. ``isotropic_iterations`` rounds of isotropic remeshing on the surface
   (:meth:`_Operations.isotropic_step`: split edges longer than ``ISO_LONG × ℓ``, collapse
   those shorter than ``ISO_SHORT × ℓ`` under the guards, flips, a smoothing step, flips) —
   the equiareal samples give the density, these rounds the shape. The rounds' length ``ℓ``
   starts at ``L`` and is scaled by ``√(n / target)`` after each, so that they end near the
   target count: the rounds settle at a count of their own (about 20 % above the target at
   ``ℓ = L``), and the collapses that gave the rest back in step 5 left the mesh irregular
   and its density uneven;
5. count correction: collapse the shortest edges (slivers shorter than ``SLIVER × L`` and as
   many more as the refinement added) under the gap and sag guards at ``refine_sag × L``, so
   that they do not undo the refinement; without the sag guard if it leaves the count above
   the target; split the longest edges if below;
6. ``final_relax_iterations`` × (smoothing step, valence flips): each step also evens out
   the areas of every vertex's faces (:func:`.relax.area_equalizing_steps`, weight
   ``AREA_EQUALIZE``), which the connectivity limits (a valence-5 or -7 vertex's faces cannot
   be both equilateral and as large as the others); the flips make the valences regular
   (:func:`.flips.valence_flips`, no new angle below ``VALENCE_MIN_DEG`` or the old faces'),
   which the smoothing then shapes;
7. the sag refinement again (the smoothing moves vertices off the folds the first one
   caught), the count restored, then ``pinned_relax_iterations`` smoothing steps and valence
   flips as in step 6 with the new sag vertices pinned and the moves that take an edge
   farther from the surface than the sag tolerance at its middle vetoed (:func:`sag_veto`:
   without it the steps slide the vertices around the new ones off the creases they caught,
   gpp_bunny at 5k vertices: edges 0.21 L from the surface before them, 0.29 L after); then
   ``RESHAPE_STEPS`` × (a smoothing
   step of the vertices around the faces with an angle below ``RESHAPE_DEG`` — the splits
   and collapses just made leave them skinny — under a veto of every move that takes an edge
   farther from the surface than the sag tolerance, flips) (:meth:`_Operations.reshape`; not
   without ``relax_iterations``); then the remesh follows the input (:meth:`_Operations.follow`,
   :mod:`.fidelity`): the rim split again where it cuts off an input boundary vertex (the
   isotropic collapses take back rim splits), ``FOLLOW_RIM_GAP × L`` from the rim's
   vertices at least; a vertex snapped (or inserted) and locked on every input point (an
   interior vertex, the middle of an interior edge or of a face) farther than
   the follow tolerance from the remesh (``follow_input × L``, ``COARSE_FOLLOW`` times that
   where a disk's input has fewer vertices than the target, :func:`follow_tolerance`) — the
   sharp creases and thin folds no sag test sees — no two closer than
   ``FOLLOW_GAPS[0] × L``, a snap undone where it leaves an edge farther than the sag
   tolerance from the surface, flips, as many guarded collapses of the shortest
   edges as vertices were added (none of the rim's), flips; then again for the points still
   that far, ``FOLLOW_GAPS[1] × L`` apart (those within the first gap of a snapped point,
   left by the first round, between the snapped ones), and once more at that gap (a snap moves
   the nearest free vertex, which can uncover an input point it held, such as a point on a
   lid's fold); after the smoothing, which would move
   the vertices next to them off the creases again, and locked until the minimum-angle pass
   (step 10), whose collapses keep them and whose later operations may move them;
8. up to ``SLIVER_PASSES`` collapses of the slivers the last steps left, under the same
   guards, the count given back by splits, each followed by flips;
9. the rim's fans opened (:func:`.rim.open_rim_fans`: the interior edge across an angle wider
   than ``RIM_FAN_MAX_DEG`` at a rim vertex is split — the caps a reflex input corner leaves),
   flips; then the folds repaired (:meth:`_Operations.repair_folds`): the faces turned over
   against the input (:func:`turned_over_faces`: where the map is strongly anisotropic and
   its stretch turns from one input face to the next, a face counter-clockwise on the disk
   can lift to one that doubles back over the surface) undone by flips, collapses and moves
   judged on the folds they leave (:func:`.unfold.unfold_locally`: a move to the point of the
   vertex's star on the disk that leaves the fewest folds; where a fold has a rim corner, also
   the removal along the rim of a rim vertex on a reflex corner of the input boundary that
   leaves the input no farther from the remesh than its farthest point already is,
   :func:`.fidelity.input_reach` — a fold across a notch of a ragged rim); then an edge
   between interior corners of every fold left collapsed, under the sag and gap guards, then
   under none, each time followed by the local operations and undone if it leaves as many
   folds or more;
   here, in step 10 and in step 11 the feature vertices at the faces being repaired are freed
   (:meth:`_Operations.release`) and their kept edges dropped;
10. the minimum-angle pass (:meth:`_Operations.guarantee`): collapses of the short edges of
    faces with a 3D angle below ``min_angle_deg``, guarded, then less so, each followed by
    splits for the count and flips, then collapses under no guard but validity of an edge of
    each face still below ``NEEDLE_DEG``; then the local operations of
    :func:`.angles.raise_min_angles` (flips, vertex moves, collapses, each made only if it
    raises the smallest 3D angle of the faces it touches, under the sag guard) around the
    faces still below, the count restored (splits that make no face below the minimum,
    :func:`.angles.split_for_count`, or guarded collapses of the shortest edges) and the
    operations again around the faces then below; then the rim's fans opened again as in
    step 9 (:meth:`_Operations.open_fans`: the minimum-angle operations' collapses can leave
    a reflex rim corner with two wide caps), kept only where it leaves fewer faces below the
    minimum and none smaller; then, up to ``GRADE_PASSES`` times while it is kept, the faces
    still below that no input corner forces refined at their off-centres
    (:meth:`_Operations.grade`, :mod:`.circumcentres`: the faces beside a short edge whose
    far corner no operation can bring closer), or where that is not kept with the long edges
    of their caps split, the local operations after every round of insertions; where the
    pass's operations turned faces over, the fold repair's local operations again and the
    minimum-angle ones after them (also under the looser guards below), a group of folds
    sharing vertices at a time, undone where they leave a smaller smallest angle and not every
    fold of the group undone, while the trials' work budget lasts (:class:`TrialBudget`; it
    also ends the face-by-face loops of :meth:`_Operations.refine_each` and
    :meth:`_Operations.move_each`); then, at the faces still below that no input corner
    forces, the local operations under sag and gap guards ``LAST_RESORT`` times looser
    (:meth:`_Operations.last_resort`: a vertex on a crease or bump narrower than the remesh,
    where only its removal or a move off it raises the angle), kept only where they leave
    fewer such faces or a larger smallest angle and no more folds, the vertices their
    collapses removed given back; last the refinement again, as above, or where neither of
    its kinds is kept with the interior edges at the faces' smallest corners split
    (:func:`.circumcentres.corner_split_round`), and the looser operations after it
    (:meth:`_Operations.refine_left`: the fold repair's and the looser operations leave faces
    below the minimum where the refinement before them found none); last, corner after
    corner, the faces an input corner too sharp for any fan forces below the minimum
    (:func:`.angles.forced_by_corners`: at a locked vertex or a rim vertex on a corner of the
    input's boundary) raised as far as the corner allows (:meth:`_Operations.raise_forced`:
    the local operations judged on their smallest angle alone, so that the corner's angle is
    shared out among its faces, then the usual ones at the faces they left below within
    ``FORCED_REACH × L``, undone unless the corner's smallest angle rises with no more folds
    and no more or worse faces below that no corner forces), and where a rim corner's two
    faces stay below ``AIM_SHARE`` × the even split of its angle, a new middle vertex on its
    middle edge or the middle vertex moved onto its wedge (:meth:`_Operations.aim_corner`,
    :mod:`.wedge`), judged the same way; then at each rim corner where a face below the
    minimum that no input corner forces has its smallest angle (a narrow tooth of a ragged
    rim, its input corner a little wider than two faces of the minimum), the same wedge's
    changes where it has two faces, splits of its rim edges at ``RIM_SPLIT_TS`` along them
    on the input's rim, one and both, and at the input boundary vertex each cuts off
    farthest (a tooth's tip the rim crosses), one and both, judged the same way; at those
    corners and at the rim corners where such a face has an angle wider than
    ``RIM_FAN_MAX_DEG`` (a rim cap), the corner's fan opened (the interior edge across each
    such angle at it split, :meth:`_Operations.open_fan`), judged the same way and kept only
    where it leaves fewer such faces or a larger smallest angle among them; the vertices
    added given back by guarded collapses where that leaves no more or worse such faces and
    no more folds, all at once or else one at a time (:meth:`_Operations.aim_unforced`,
    :meth:`_Operations.give_back`); last, where folds are left, the fold
    repair's local operations at all of them once more, their two-steps under no floor, and
    where they leave fewer folds the minimum-angle operations and the star moves after them,
    undone unless that leaves fewer folds and no more or worse faces below the minimum that
    no input corner forces (:meth:`_Operations.unfold_left`).
    A face none of this raises stays: the report counts the faces below the minimum and,
    among them, those an input corner forces, naming the corners (with the even split of each
    corner's angle sum); then ``EVEN_STEPS`` smoothing steps as in step 6
    (:meth:`_Operations.even_out`; not without ``relax_iterations``) that even out the
    faces the steps since step 7 left uneven, under vetoes of every move that makes a
    face's smallest angle smaller than it was and than
    ``min_angle_deg`` (:func:`angle_veto`) or takes an edge farther from the surface than the
    sag tolerance (:func:`sag_veto`), the followed vertices and their neighbours, the input
    corners and the ends of the edges folded more than ``EVEN_FOLD_DEG`` staying (the feature
    vertices at faces with an angle below ``FEATURE_RELEASE_DEG`` freed first, the others
    staying but not their neighbours), then ``RING_STEPS`` such steps that keep a vertex's
    move only where it raises the sum of its faces' smallest angles without spreading their
    areas (:func:`ring_veto`: the evening steps trade the angles for even areas, these take
    back what angle they can at no cost in evenness), no face's smallest angle below what it
    was and ``RING_FLOOR_DEG``; then the flips and moves of :func:`.angles.raise_min_angles`
    at the faces below ``RAISE_DEG`` that no input corner forces, none spreading the areas,
    under the sag and gap guards at ``RAISE_SAG`` × the tolerance, each group of them undone
    where it leaves more folds, more or worse faces below ``min_angle_deg``, a smaller sum of
    smallest angles or more spread areas (:meth:`_Operations.raise_above`: the evening steps
    let faces down to ``min_angle_deg``, and many of those are a flip or a move from a larger
    angle); before these steps and again after them
    (:meth:`_Operations.settle`), a vertex moved onto each input point still farther than
    ``SETTLE_TOL × L`` from the remesh and than any remesh edge's middle from the input,
    farthest first, while one can be without a new angle below ``min_angle_deg``, a fold, an
    edge farther than the sag tolerance from the surface or another input point left as far
    (:func:`.fidelity.settle_on_far_input`), and where it stops at a point farther than
    the follow tolerance (a hole the minimum-angle operations left at a crease the follow step
    covered, too wide for any vertex to move into), up to ``SETTLE_INSERTIONS`` vertices
    inserted at the farthest points instead, each with the minimum-angle operations around
    it and kept only where it leaves no more or worse faces below ``min_angle_deg``, no more
    folds and the farthest point nearer (:meth:`_Operations.insert_at_far_input`); the steps
    keep the first ones in place (their neighbours move); after the second, the edges farther
    from the surface (at ``SAG_FLIP_TS``) than the farthest input point from the remesh (as
    the settle step's own search leaves it, :attr:`.fidelity.Settled.reach`, at least
    ``SETTLE_TOL × L``) flipped where the other diagonal is within that distance, with no new
    angle below ``SAG_FLIP_MIN_DEG`` (or ``min_angle_deg`` if higher) and the old faces' and no
    new face turned from the input (:meth:`_Operations.flip_sagging`, :func:`.flips.sag_flips`: an
    edge across an input crease, which the Delaunay flips keep, decides the remesh-to-input
    side there and, at the crossing, the input-to-remesh side); last, the free corners of the
    faces still below ``min_angle_deg`` that no input corner forces each moved to the best
    point of its star where that leaves fewer such faces or a larger smallest angle among them
    (:meth:`_Operations.move_each`: on a ragged rim, an interior vertex in a notch that no
    collapse may remove), and where no move is kept, an interior edge of the corner's link
    flipped first, then its move and the local operations around it, kept where that leaves
    fewer such faces or a larger smallest angle among them, no more folds and no smaller
    smallest angle anywhere (:meth:`_Operations.flip_and_move`: a rim cap, an interior vertex
    with rim vertices all round, which no collapse may remove and no position widens);
11. a safety net (:meth:`_Operations.repair_degenerate`): any face degenerate on the surface
    or not counter-clockwise on the disk has an edge collapsed. No operation makes one — each
    refuses to make a face thinner on the disk than ``DISK_SHAPE_MIN``
    (:func:`.halfedge.disk_shape`) — so it normally has nothing to do; the caller checks that
    none is left (:func:`.uniform.uniform_remesh` raises otherwise).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from ..laplacian import face_double_areas
from ..metrics import min_corner_angles, min_corner_angles_below
from ..noise import noise_beyond, noise_level
from ..remesh_quality import closest_points_on_triangles
from ..rows import dots, norms, row_min
from ..topology import connected_components
from .angles import (SAG_TS, corner_angles_deg, forced_corners, input_vertex_under,
                     raise_min_angles, sharp_among, sharp_vertices, split_for_count)
from .circumcentres import (cap_split, corner_split_round, refine_at_circumcentres,
                            restore_state, saved_state, shortfall_of, shortfall_order,
                            unforced_among, unforced_below, unforced_shortfall)
from .collapse import collapse_short_edges
from .corners import insert_vertices, snap_vertices
from .domain import on_sphere
from .face_memo import FaceMemo
from .features import place_features, release_features
from .holes import all_loops_whole, away_from_holes, in_fans, place_holes
from .fidelity import follow_input as snap_far_input
from .fidelity import FarMemo, Settled, input_distance, input_reach, settle_on_far_input
from .flips import flip_edges, flip_in_place, sag_flips, valence_flips
from .halfedge import DISK_SHAPE_MIN, disk_shape, edge_table, independent_edges, touching
from .refine import (SAG_SAMPLES, polygon_segments, refine_by_sag, split_edges,
                     split_long_edges)
from .relax import tangential_smoothing
from .rim import (RIM_FAN_MAX_DEG, RIM_TOL, fan_edges, open_rim_fans, refine_rim, rim_corners,
                  rim_gaps)
from .sag import edge_sag, edge_sag_along, may_sag
from .state import RemeshState, at_points, face_normals, turned_against
from .unfold import star_positions, turned_over_rows, unfold_locally
from .wedge import (even_split_moves, even_split_points, half_edge, move_guards_ok, put_vertex,
                    two_face_fan)

SLIVER = 0.2          # edges shorter than this × L are collapsed
SLIVER_PASSES = 3     # at most this many last sliver collapses (each with its splits, flips),
SLIVER_AGAIN = 5e-4   # the next only after one that collapsed at least this × the vertex count
ISO_LONG, ISO_SHORT = 4.0 / 3.0, 0.8   # the isotropic rounds' split / collapse lengths (× ℓ)
AREA_EQUALIZE = 0.3   # the final smoothing's weight of the centroid step against even areas
VALENCE_MIN_DEG = 35.0   # its valence flips keep the new faces' angles above this (or the old)
LOOSE = 2.0           # the minimum-angle pass's last collapses: guards this much looser
NEEDLE_DEG = 5.0      # the minimum-angle pass ends with unguarded collapses below this angle,
NEEDLE_PASSES = 3     # at most this many
LAST_RESORT = (2.0, 4.0)   # the minimum-angle pass's last local operations, at the faces still
                           # below that no input corner forces: guards this many times looser
LONG_EDGE = 3.0       # after the sag refinement, split edges longer than this × L once
RESHAPE_STEPS = 4     # smoothing steps around the faces the pinned refinement left skinny,
RESHAPE_DEG = 35.0    # those with an angle below this, under the sag veto
EVEN_STEPS = 4        # the last smoothing steps, under the angle and sag vetoes,
EVEN_SAG_SAMPLES = 1  # their sag veto measuring at this many points along an edge (the
                      # middle: the folds stay put, below), the ends of the edges folded more
EVEN_FOLD_DEG = 45.0  # than this staying (moving them too lets the farthest input point
                      # drift away from the remesh at creases; test_remesh_fidelity)
RAISE_DEG = 30.0      # after them, the minimum-angle operations at the faces below this,
RAISE_SAG = 0.5       # their sag and gap guards at this × the tolerance (at the full one
                      # their moves take the remesh farther from the input: README)
RING_STEPS = 2        # then smoothing steps keeping a vertex's move only where it raises the
RING_FLOOR_DEG = 30.0  # sum of its faces' smallest angles without spreading their areas, no
                       # face's smallest angle below this (or the minimum-angle pass's) and what
                       # it was, so that the mean smallest angle rises and the area CV does not
FEATURE_RELEASE_DEG = 45.0   # with feature lines, the even-out pass first frees the feature
                             # vertices at the faces with an angle below this (freeing
                             # them trades a little RMS for mean smallest angle and area CV)
GRADE_PASSES = 3      # the minimum-angle pass's refinement again while it is kept, at most
GRADE_PATIENCE = 2    # its rounds stop after this many in a row that beat no earlier state
EACH_FACES = 100      # then at most this many of the faces it leaves refined one at a time
# the loops of trials made one at a time and each judged on the whole remesh (the fold groups
# of _Operations.unfold_kept, the faces of each_unforced_face) stop once their trials have
# cost this × the vertex count, a trial costing one plus the faces below the minimum angle
# that no input corner forces when it starts (the local operations it runs around them): a
# remesh with thousands of those faces and as many folds (a tube narrower than the remesh,
# its closed end crowded by the map) gets a few trials, not one per fold group
TRIAL_WORK = 4.0
# the follow step's rounds: the vertices snapped onto far input points are this × L apart at
# least (from each other and from the locked vertices, those of the rounds before among them);
# the last round takes the points the snaps of the one before uncovered
FOLLOW_GAPS = (0.4, 0.2, 0.2)
# where the input has fewer vertices than the remesh's target, the follow tolerance (and the
# settle step's insertion threshold) is this × the follow_input asked (follow_tolerance)
COARSE_FOLLOW = 0.8
# the follow step's rim splits are this × L from the ends of the edge at least: a rim vertex
# closer to another makes a rim face whose small angle no later pass raises (the rim's
# vertices stay)
FOLLOW_RIM_GAP = 0.5
# where the input has more vertices than the remesh's target (noise_tolerances): the sag
# tolerance is at least this × the input's noise level, and the follow tolerance at least the
# noise's size that about this share of the target count of input points exceed
NOISE_SAG = 3.0
NOISE_FOLLOW_SHARE = 0.01
# after the minimum-angle pass and the last smoothing, the input points farther than this × L
# from the remesh get a vertex moved onto them, farthest first, while one can be without a new
# angle below the minimum: the Hausdorff distance's input-to-remesh side
SETTLE_TOL = 0.15
# where the settle step stops at an input point farther than the follow tolerance, a vertex
# is inserted there instead (the minimum-angle operations around it), at most this many
# times a round
SETTLE_INSERTIONS = 5
# after an insertion, the input points within this × L of it are measured again (against the
# faces within one more L of it): the operations around it change the remesh there alone
NEAR_INSERTION = 2.0
# the last sag flips measure an edge at these t along it: finer than refine.SAG_TS, as the
# point where an edge crosses an input crease, where the Hausdorff distance is decided, is
# seldom one of those
SAG_FLIP_TS = np.arange(1, 16) / 16
# the sag flips make no face with a smallest angle below this (min_angle_deg if higher) and
# the old faces' smallest: at the minimum angle's 20° they cost faces under 30° and smallest
# angles for little Hausdorff gain
SAG_FLIP_MIN_DEG = 30.0
# the sag flips' first look at an edge: its sag at these t (a subset of SAG_FLIP_TS) must
# exceed SAG_SCREEN_MARGIN × the threshold before it is measured at all SAG_FLIP_TS (a
# cheap screen: the flips it misses are rare)
SAG_SCREEN_TS = SAG_FLIP_TS[3::4]
SAG_SCREEN_MARGIN = 0.5
# the forced faces' share-out (_Operations.raise_forced) changes the faces within two rings of
# the corner: the faces below the minimum it leaves within this × L of it are raised after it
FORCED_REACH = 3.0
# a rim corner whose faces' smallest angle stays below this × the even split of its input angle
# between two faces has the middle vertex of its two faces moved onto its wedge after that
# (_Operations.aim_corner)
AIM_SHARE = 0.95
# the rim edges at a rim corner where an unforced face has its smallest angle are split at
# these fractions along them from the corner (_Operations.aim_unforced)
RIM_SPLIT_TS = (0.3, 0.5)
# a sharp input corner this × L or closer to a sharper one keeps no vertex: three locked
# vertices that close make a face no later pass may change (on ICT faces: 0.3 L apart, 13°)
CORNER_GAP = 0.4


def improve_remesh(S: RemeshState, L: float, *, relax_iterations: int = 2, flips: bool = True,
                   max_dihedral_deg: float = 20.0, relax_step: float = 0.5,
                   refine_sag: float = 0.2, refine_budget: float = 0.3,
                   target_vertices: int | None = None,
                   corners_uv: np.ndarray | None = None,
                   landmarks_uv: np.ndarray | None = None,
                   isotropic_iterations: int = 4,
                   final_relax_iterations: int = 6,
                   pinned_relax_iterations: int = 2,
                   min_angle_deg: float = 20.0, sag_floor: float = 0.0,
                   follow_input: float = 0.25,
                   feature_angle_deg: float = 0.0,
                   hole_loops: list | None = None, fans: np.ndarray | None = None
                   ) -> RemeshState:
    """Improve the remesh ``S`` in place (see the module docstring for the schedule).

    Parameters
    ----------
    S : RemeshState
    L : float
        Target edge length on the surface, in the mesh's units.
    relax_iterations : int
        Tangential smoothing steps before refinement (each followed by flips); with 0, none
        after count correction either.
    flips : bool
        Delaunay flips on the lifted surface.
    max_dihedral_deg : float
        Quads folded less than this flip freely; more folded ones only towards an edge closer
        to the surface.
    relax_step : float
        The fraction of the way to the 1-ring centroid a smoothing step moves.
    refine_sag : float
        Split edges farther than ``refine_sag × L`` from the surface (0: no refinement); also
        the tolerance of the collapses' guards.
    refine_budget : float
        At most this fraction of the vertex count in sag splits (and in long-edge splits).
    target_vertices : int, optional
        The count to restore after refinement; default: the count after refinement.
    corners_uv : (k, 2) float, optional
        Disk images of sharp interior input vertices, sharpest first.
    landmarks_uv : (j, 2) float, optional
        Disk images of the interior input vertices that carry landmarks: each gets a locked
        vertex on it after the corners and feature lines (tallied as ``landmarks_snapped``,
        ``_inserted`` and ``_too_close``: one within ``CORNER_GAP × L`` of a vertex kept before
        gets none), which
        the later passes keep as they keep the corners'.
    isotropic_iterations : int
        Rounds of split / collapse / flip / smoothing at the target length (step 4).
    final_relax_iterations : int
        Smoothing steps after the count correction (step 6; none if ``relax_iterations`` is 0).
    pinned_relax_iterations : int
        Smoothing steps after the second sag refinement (step 7).
    min_angle_deg : float
        The minimum-angle pass's threshold (step 10; 0: no pass).
    sag_floor : float
        The sag tolerance (refinement and guards) is at least this, in the mesh's units
        (default 0: ``refine_sag × L`` alone). A remesh finer than its input sees the input's
        own facets: its edges sag across every input crease by about their length times the
        crease angle, which no split removes and which the refinement would chase at the cost
        of the triangles' shape; the sphere remesher floors the tolerance at ``refine_sag`` ×
        the input's own spacing (:func:`.sphere.sphere_remesh`). Both it and the follow
        tolerance are at least :func:`noise_tolerances` (a noisy input finer than the remesh).
    follow_input : float
        At the end of step 7, a vertex goes onto every input point (an interior vertex, the
        middle of an edge or a face away from the rim) farther than this × ``L`` from the
        remesh (0: none); ``COARSE_FOLLOW`` times that where a disk's input has fewer
        vertices than the target (:func:`follow_tolerance`).
    feature_angle_deg : float
        Step 1 also locks vertices along the input's feature lines, the edges whose dihedral
        angle exceeds this, and keeps the edges between them (:mod:`.features`; on the disk
        only; default 0: none — :data:`.features.FEATURE_DEG` is the threshold measured).
    hole_loops : list of (k,) int, optional
        The loops (input vertex indices) of the holes the input's fans fill: before
        everything else in step 1, each gets locked vertices along it joined by kept edges
        that no step frees (:func:`.holes.place_holes`; on the disk only).
    fans : (M,) bool, optional
        With ``hole_loops``, the input faces that fill the holes.

    Returns
    -------
    RemeshState
        ``S``, with counts and seconds per step in ``S.log``: ``log["seconds"]`` has ``flips``
        and ``relax`` (step 2), ``refine`` (3), ``isotropic`` (4), ``count`` (5),
        ``smoothing`` (6), ``pinned``, ``reshape`` and ``follow`` (7), ``slivers`` (8),
        ``rim_fans`` (9), ``guarantee``, ``settle`` and ``even`` (10) and ``repair`` (11).
    """
    noisy_sag, noisy_follow = noise_tolerances(
        S.V_in, S.F_in, S.n if target_vertices is None else target_vertices)
    ops = _Operations(S, L, flips, max_dihedral_deg, relax_step, refine_sag,
                      max(sag_floor, noisy_sag))
    lap = Stopwatch(S.log, "seconds")
    if hole_loops:
        place_holes(S, hole_loops, fans, L)
    if hole_loops and corners_uv is not None:
        corners_uv = away_from_holes(S, corners_uv, CORNER_GAP * L)
    if corners_uv is not None and len(corners_uv):
        snap_vertices(S, corners_uv, min_gap=CORNER_GAP * L)
    ops.corners = S.X[S.locked].copy()
    if feature_angle_deg > 0 and not on_sphere(S.uv):
        joined = place_features(S, L, feature_angle_deg, fans if hole_loops else None)
        ops.features = S.X[np.unique(joined)]
    if len(S.fixed):
        ops.features = np.vstack([S.fixed, ops.features])
    if landmarks_uv is not None and len(landmarks_uv):
        landmarks = snap_vertices(S, landmarks_uv, min_gap=CORNER_GAP * L, counts="landmarks")
        ops.corners = np.vstack([ops.corners, S.X[landmarks]])
    ops.flip()
    lap("flips")
    for _ in range(relax_iterations):
        ops.relax()
        lap("relax")
        ops.flip()
        lap("flips")
    if refine_sag > 0:
        ops.refine(budget=int(refine_budget * S.n))
        lap("refine")
    target = S.n if target_vertices is None else int(target_vertices)
    scale = 1.0
    for _ in range(isotropic_iterations):
        ops.isotropic_step(scale)
        scale *= np.sqrt(S.n / target)
        lap("isotropic")
    ops.restore_count(target)
    lap("count")
    for _ in range(final_relax_iterations if relax_iterations > 0 else 0):
        ops.smooth()
        lap("smoothing")
    if refine_sag > 0:
        ops.refine_pinned(target, int(refine_budget * S.n), pinned_relax_iterations)
        lap("pinned")
        for _ in range(RESHAPE_STEPS if relax_iterations > 0 else 0):
            ops.reshape(RESHAPE_DEG)
            lap("reshape")
    corners = S.X[S.locked].copy()
    follow = max(follow_tolerance(follow_input, len(S.V_in), target, on_sphere(S.uv)) * L,
                 noisy_follow)
    if follow_input > 0:
        ops.follow(follow)
        lap("follow")
    ops.remove_slivers(target)
    lap("slivers")
    if open_rim_fans(S):
        ops.flip()
    lap("rim_fans")
    followed = S.X[S.locked].copy()
    S.locked = at_points(S.X, corners)         # the followed vertices free again
    ops.repair_folds(target, floor=min_angle_deg)
    lap("folds")
    if min_angle_deg > 0:
        ops.guarantee(target, min_angle_deg, kept=(followed, corners))
        lap("guarantee")
    settle = follow_input > 0 and ops.tol is not None
    settled = (ops.settle(min_angle_deg, followed, follow, ops.far).vertices if settle
               else np.zeros(0, np.int64))               # most faces as the follow step left
    lap("settle")
    if relax_iterations > 0 and EVEN_STEPS > 0:
        S.locked[settled] = True
        ops.even_out(EVEN_STEPS, min_angle_deg, followed, RING_STEPS)
        lap("even")
        if 0 < min_angle_deg < RAISE_DEG:
            at_settled = S.X[settled]
            ops.raise_above(RAISE_DEG, min_angle_deg)
            settled = np.flatnonzero(at_points(S.X, at_settled))
            lap("raise")
        S.locked[settled] = False
        if settle:
            reach = ops.settle(min_angle_deg, np.vstack([followed, S.X[settled]]),
                               follow).reach
            ops.flip_sagging(reach, max(min_angle_deg, SAG_FLIP_MIN_DEG))
            lap("settle")
    if min_angle_deg > 0:
        ops.move_each(min_angle_deg)
        lap("star_moves")
    ops.repair_degenerate(target)
    lap("repair")
    return S


def noise_tolerances(V_in: np.ndarray, F_in: np.ndarray, target: int) -> tuple[float, float]:
    """The least sag and follow tolerances of :func:`improve_remesh` (mesh units) for the input
    ``(V_in, F_in)`` remeshed at ``target`` vertices: where the input has more vertices than
    that, ``NOISE_SAG`` × its :func:`..noise.noise_level`, and the size of normal noise at that
    level that ``NOISE_FOLLOW_SHARE`` × ``target`` of its input points exceed
    (:func:`..noise.noise_beyond`; the follow step looks at about 6 points per input vertex:
    the vertex, the middles of its 3 edges and of its 2 faces); else ``(0, 0)``. A scan's
    noise along its normals is a bend of the surface at every input vertex that a remesh of
    coarser spacing cannot follow: its splits and snaps would chase it (each input point
    farther than the follow tolerance gets a vertex, beyond the target count) at the cost of
    the faces' shape. On a clean input the level is near 0 and the floors with it."""
    if len(V_in) <= target:
        return 0.0, 0.0
    level = noise_level(V_in, F_in)
    share = NOISE_FOLLOW_SHARE * target / (6 * len(V_in))
    return NOISE_SAG * level, noise_beyond(level, share)


def follow_tolerance(follow_input: float, n_input: int, target: int,
                     sphere: bool = False) -> float:
    """The follow step's tolerance (× L) for an input of ``n_input`` vertices remeshed at
    ``target``: ``follow_input``, or ``COARSE_FOLLOW`` times it where the input is the
    coarser and the domain the disk (``sphere`` False). There every input vertex and crease is
    a corner of the surface the remesh must pass through, and a vertex put on one costs the
    faces around it little; where the input is the finer, input points are dense, and a
    tighter tolerance locks so many vertices that the minimum-angle pass loses angles it could
    otherwise raise. On the sphere, as the feature lines, it is not used: on the closed meshes
    it took no farthest point the looser tolerance leaves and cost the faces' evenness and
    angles."""
    return follow_input * (COARSE_FOLLOW if n_input < target and not sphere else 1.0)


@dataclass
class _Operations:
    """The steps of :func:`improve_remesh` on ``S``, with its parameters."""

    S: RemeshState
    L: float
    flips: bool
    max_dihedral_deg: float
    relax_step: float
    refine_sag: float
    sag_floor: float = 0.0
    corners: np.ndarray | None = None     # the locked input corners (k×3), never released
    features: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))   # where feature
                                          # vertices were placed (k×3)
    freed: list = field(default_factory=list)   # where feature vertices were freed (k×3 each)
    folds: FaceMemo = field(default_factory=lambda: FaceMemo(turned_over_at))   # the fold
                                          # counts of the minimum-angle pass's refinements
    judged: dict = field(default_factory=dict)   # the minimum-angle operations' answers by
                                          # surroundings (raise_min_angles' memo)
    chord: float | None = None            # how far the fold repair's rim collapses may
                                          # leave the input from the remesh (repair_folds)
    far: FarMemo = field(default_factory=FarMemo)   # the follow step's searches of the far
                                          # input points and the first settle step's

    @property
    def tol(self) -> float | None:
        """The sag tolerance of the refinement and the collapse guards (mesh units):
        ``refine_sag × L``, at least ``sag_floor``; None without refinement."""
        return max(self.refine_sag * self.L, self.sag_floor) if self.refine_sag > 0 else None

    def flip(self, since: np.ndarray | None = None) -> None:
        """Flips everywhere, or — given the faces before a run of splits — only from the
        faces those splits changed or added."""
        if not self.flips:
            return
        S = self.S
        active = None if since is None else _corners_changed_since(S, since)
        twin = S.twins().copy()
        F, k, _ = flip_edges(S.X, S.F, S.uv, self.max_dihedral_deg, sag=partial(edge_sag, S),
                             boundary=S.is_rim, active=active, twin=twin, fixed=S.is_joined)
        S.set_faces(F, twin)
        S.tally("flips", k)

    def flip_sagging(self, threshold: float, min_angle_deg: float) -> None:
        """Flip the edges farther than ``threshold`` from the surface (at the points
        ``SAG_FLIP_TS``, :func:`sag_at_samples`) whose other diagonal is within it, no new face's
        smallest angle below ``min_angle_deg`` and the old faces' (:func:`.flips.sag_flips`)."""
        if not self.flips:
            return
        S = self.S
        twin = S.twins().copy()
        F, k = sag_flips(S.X, S.F, S.uv, S.is_rim, partial(sag_at_samples, S, threshold), threshold,
                         min_angle_deg, twin=twin, fixed=S.is_joined,
                         turned=partial(turned_from_input, S),
                         screen=partial(may_sag_beyond, S, threshold))
        S.set_faces(F, twin)
        S.tally("sag_flips", k)

    def smooth(self, veto=None) -> None:
        """A smoothing step that also evens out the areas of every vertex's faces (weight
        ``AREA_EQUALIZE``), without the moves ``veto`` drops, then flips towards regular
        valences (:meth:`flip_valence`)."""
        self.relax(veto=veto, equalize=AREA_EQUALIZE)
        self.flip_valence()

    def flip_valence(self) -> None:
        """Flips towards regular valences (:func:`.flips.valence_flips`), the new faces'
        smallest angle at least ``VALENCE_MIN_DEG`` or the old faces', none of a hole loop's
        edges (:meth:`.state.RemeshState.is_fixed`)."""
        if not self.flips:
            return
        S = self.S
        twin = S.twins().copy()
        F, k = valence_flips(S.X, S.F, S.uv, S.is_rim, self.max_dihedral_deg, VALENCE_MIN_DEG,
                             twin=twin, fixed=S.is_fixed if len(S.fixed) else None)
        S.set_faces(F, twin)
        S.tally("valence_flips", k)

    def relax(self, movable: np.ndarray | None = None, veto=None,
              equalize: float | None = None) -> None:
        """One tangential smoothing step of every vertex not on the rim and not locked (and
        ``movable``, n bool, if given), without the moves ``veto`` drops, evening out the
        areas of each vertex's faces with the weight ``equalize`` if given
        (:func:`.relax.tangential_smoothing`)."""
        S = self.S
        free = ~S.is_rim & ~S.locked
        S.uv, S.face, S.bary, S.X, moved = tangential_smoothing(
            S.V_in, S.F_in, S.uv_in, S.locator, S.uv, S.F, S.face, S.bary,
            free if movable is None else free & movable, 1, self.relax_step, X=S.X,
            pullback=S.pullback(), veto=veto, equalize=equalize)
        S.tally("relaxed_vertex_moves", sum(moved))

    def release(self, faces: np.ndarray) -> None:
        """Free the feature vertices at the corners of ``faces`` (indices) for the repairs
        and the minimum-angle pass (:func:`.features.release_features`); the input corners
        stay locked."""
        S = self.S
        if len(S.joined) == 0:
            return
        at = np.zeros(S.n, bool)
        at[S.F[faces].ravel()] = True
        free = release_features(S, at, self.corners)
        self.freed.append(S.X[free])
        S.tally("features_released", len(free))

    def lock_at(self, points: np.ndarray) -> None:
        """Lock the vertices at ``points`` (k×3) and no others, except those where a feature
        vertex was freed (:meth:`release`): a snapshot of the locks taken before a release
        must not lock them again, which no later release could undo (they are on no kept
        edge) and which would keep the minimum-angle pass off their faces."""
        S = self.S
        S.locked = at_points(S.X, points)
        if self.freed:
            S.locked &= ~at_points(S.X, np.vstack(self.freed))

    def reshape(self, angle_deg: float) -> None:
        """A smoothing step of the corners of the faces with an angle below ``angle_deg``
        (those the pinned refinement's splits and collapses left skinny) and of their
        neighbours, no move taking an edge farther from the surface than the sag tolerance
        (:func:`sag_veto`), then flips."""
        S = self.S
        near = np.zeros(S.n, bool)
        near[S.F[skinny_faces(S.X, S.F, angle_deg)].ravel()] = True
        near[S.F[touching(S.F, near)].ravel()] = True
        if near.any():
            self.relax(near, None if self.tol is None else partial(sag_veto, S, self.tol))
            self.flip()

    def refine(self, budget: int) -> None:
        """Rim splits (:func:`.rim.refine_rim`), sag splits, one long-edge split, flips, sag
        splits again around what changed and what the first rounds left, flips; at most
        ``budget`` rim and ``budget`` sag splits in all."""
        S, L = self.S, self.L
        F_pre = S.F.copy()
        refine_rim(S, RIM_TOL * self.tol, SLIVER * L, budget)
        done, pending = refine_by_sag(S, self.tol, budget)
        F0 = S.F.copy()
        split_long_edges(S, LONG_EDGE * L, budget=budget)
        self.flip(since=F_pre)
        active = _corners_changed_since(S, F0)
        active[:len(pending)] |= pending
        F1 = S.F.copy()
        refine_by_sag(S, self.tol, budget - done, active=active)
        self.flip(since=F1)

    def isotropic_step(self, scale: float = 1.0) -> None:
        """One round of isotropic remeshing on the surface (Botsch & Kobbelt 2004), made on
        the disk, at the length ``scale × L``: split edges longer than ``ISO_LONG`` times it,
        collapse those shorter than ``ISO_SHORT`` times it under the guards, flips, a
        relaxation step, flips."""
        S, L, tol = self.S, scale * self.L, self.tol
        split_long_edges(S, ISO_LONG * L)
        collapse_short_edges(S, ISO_SHORT * L, ISO_LONG * L, max_gap=tol, max_sag=tol)
        self.flip()
        self.relax()
        self.flip()

    def follow(self, tol: float) -> None:
        """For each gap of ``FOLLOW_GAPS``: rim splits at the input boundary vertices farther
        than ``RIM_TOL`` × the sag tolerance from the rim, ``FOLLOW_RIM_GAP`` × ``L`` from the
        edge's ends at least (:func:`.rim.refine_rim`: the isotropic collapses take back some
        of the first refinement's); snap (or insert) a locked vertex onto every input point
        farther than ``tol`` from the remesh (an interior vertex, the middle of an interior
        edge or of a face), that gap × ``L`` apart, no snap leaving an edge farther than the
        sag tolerance from the surface (:func:`.fidelity.follow_input`; the rounds' searches
        share :attr:`far`), flips, as many
        collapses of the shortest edges under the guards as vertices were added, none of the
        rim's (their gap guard lets a rim vertex go that stands out less than the sag
        tolerance, and the chord left can cut off a boundary vertex farther), flips."""
        S = self.S
        for gap in FOLLOW_GAPS:
            n0 = S.n
            refine_rim(S, RIM_TOL * self.tol, FOLLOW_RIM_GAP * self.L, S.n)
            snap_far_input(S, tol, gap * self.L, self.tol, self.far)
            self.flip()
            if S.n > n0:
                free_rim = S.X[S.is_rim & ~S.locked]
                S.locked |= S.is_rim
                collapse_short_edges(S, np.inf, 2.0 * self.L, budget=S.n - n0,
                                     max_gap=self.tol, max_sag=self.tol)
                S.locked &= ~at_points(S.X, free_rim)
                self.flip()

    def settle(self, min_angle_deg: float, followed: np.ndarray, insert_beyond: float,
               memo: FarMemo | None = None) -> Settled:
        """A vertex moved onto each input point farther than ``SETTLE_TOL × L`` from the
        remesh, farthest first, while one can be without a new angle below ``min_angle_deg``,
        a new fold, an edge farther than the sag tolerance from the surface or another input
        point left as far (:func:`.fidelity.settle_on_far_input`, its search from ``memo``
        where given; the vertices at ``followed``, k×3 points, stay); where it stops at a
        point farther than ``insert_beyond`` (the follow tolerance), vertices inserted at the
        points left instead (:meth:`insert_at_far_input`). Returns the vertices moved and
        inserted and the input's reach left."""
        S = self.S
        settled = settle_on_far_input(S, SETTLE_TOL * self.L, FOLLOW_GAPS[1] * self.L,
                                      min_angle_deg, self.tol, fixed=at_points(S.X, followed),
                                      memo=memo)
        beyond = settled.distances > insert_beyond
        if not beyond.any():
            return settled
        moved = S.X[settled.vertices]
        put, d = self.insert_at_far_input(min_angle_deg, settled.left_uv[beyond],
                                          settled.left[beyond], settled.distances[beyond],
                                          insert_beyond)
        if len(put) == 0:
            return settled
        left = np.flatnonzero(d > insert_beyond)
        left = left[np.argsort(-d[left], kind="stable")]            # farthest first
        return Settled(np.flatnonzero(at_points(S.X, np.vstack([moved, put]))),
                       float(d[left[0]]) if len(left) else insert_beyond,
                       settled.left_uv[beyond][left], settled.left[beyond][left], d[left])

    def insert_at_far_input(self, min_angle_deg: float, far: np.ndarray, P: np.ndarray,
                            d: np.ndarray, beyond: float) -> tuple[np.ndarray, np.ndarray]:
        """Up to ``SETTLE_INSERTIONS`` times, while one is farther than ``beyond``: a vertex
        inserted at the farthest of the input points ``far`` (k×2 domain positions; ``P`` k×3
        on the surface, ``d`` (k,) their distances from the remesh) that no existing vertex
        could be moved onto
        (:meth:`settle`: a hole the minimum-angle pass's collapses left at a crease the
        follow step covered), then flips and the minimum-angle operations around the faces
        below ``min_angle_deg`` (:meth:`raise_angles`), the new vertex staying; undone, and
        the insertions ended, where that leaves more faces below the minimum or a smaller
        smallest angle among them (:func:`.circumcentres.unforced_shortfall`), more folds
        (also by the report's test, :func:`turned_from_nearest`, at the new vertex), or the
        farthest of the points no nearer (:func:`distances_near`); ended too where no vertex
        goes in (:func:`.corners.insert_vertices` finds no face around the point that holds
        it: where the map squeezes the remesh, the point's nearest vertices on the disk need
        not surround it). Returns the points inserted (j×3) and the points' distances after
        them (k,)."""
        S = self.S
        locked = S.X[S.locked].copy()
        d = d.copy()
        put = []
        after, folds = unforced_shortfall(S, min_angle_deg), int(self.folds(S).sum())
        for _ in range(SETTLE_INSERTIONS):
            i = int(np.argmax(d))
            if d[i] <= beyond:
                break
            before, n_folds, saved = after, folds, self.saved()
            F_before = S.F.copy()
            v = insert_vertices(S, far[i:i + 1], counts="settle")
            if len(v) == 0:             # no face around the point took it (corners.locate_near)
                self.restore(saved)
                break
            self.flip(since=F_before)
            point = S.X[v][0]
            self.raise_angles(min_angle_deg, norms(S.X - point) < NEAR_INSERTION * self.L)
            near = norms(P - point) < NEAR_INSERTION * self.L
            d_after = d.copy()
            d_after[near] = distances_near(S, P[near], point, (NEAR_INSERTION + 1) * self.L)
            around = S.F[touching(S.F, np.all(S.X == point, axis=1))]
            after, folds = unforced_shortfall(S, min_angle_deg), int(self.folds(S).sum())
            if (shortfall_order(after) > shortfall_order(before) or folds > n_folds
                    or turned_from_nearest(S, around).any() or d_after.max() >= d[i]):
                self.restore(saved)
                break
            put.append(point)
            d = d_after
        S.locked = at_points(S.X, locked)
        return np.reshape(put, (-1, 3)), d

    def refine_pinned(self, target: int, budget: int, relax_iterations: int) -> None:
        """Sag refinement again after the relaxation (which moves vertices off the folds the
        first one caught), the count restored by guarded collapses, then ``relax_iterations``
        smoothing steps (:meth:`smooth`) with the new sag vertices pinned where they catch the
        surface, without the moves that take an edge farther from the surface than the sag
        tolerance at its middle (:func:`sag_veto` at ``EVEN_SAG_SAMPLES`` points)."""
        S = self.S
        corners = S.X[S.locked].copy()
        n0 = S.n
        self.refine(budget)
        S.locked[n0:] = True
        self.restore_count(target)
        veto = partial(sag_veto, S, self.tol, samples=EVEN_SAG_SAMPLES)
        for _ in range(relax_iterations):
            self.smooth(veto)
        S.locked = at_points(S.X, corners)

    def even_out(self, steps: int, min_angle_deg: float, kept: np.ndarray,
                 ring_steps: int = 0) -> None:
        """``steps`` last smoothing steps evening out the areas of every vertex's faces (as
        :meth:`smooth`, weight ``AREA_EQUALIZE``) without the moves that make a face's
        smallest angle smaller than it was and than ``min_angle_deg`` (:func:`angle_veto`) or
        take an edge farther from the surface than the sag tolerance (:func:`sag_veto`, at
        ``EVEN_SAG_SAMPLES`` points). The locked vertices stay, and so do those at ``kept``
        (k×3 points: the ones the follow step put on the input) and their neighbours, and the
        ends of the edges folded more than ``EVEN_FOLD_DEG`` (:func:`folded_vertices`): a
        tangential move there slides the remesh's fold off the input's crease, which the sag
        test, looking along the edges, does not see. The feature vertices at the corners of
        faces with an angle below ``FEATURE_RELEASE_DEG`` are freed first (:meth:`release`);
        the others stay, locked, but their neighbours move (the feature vertices are among
        ``kept``, and their kept edges already hold the crease). Then ``ring_steps`` more such
        steps, under the same locks, keep only the moves that raise the sum of the moving
        vertex's faces' smallest angles without spreading their areas (:func:`ring_veto`), no
        face's smallest angle below what it was and than ``RING_FLOOR_DEG`` (or
        ``min_angle_deg`` if higher).

        The steps before it (the second refinement, the follow step, the repairs and the
        minimum-angle pass) split, collapse and move vertices where the surface needs them
        and leave the faces around them uneven."""
        S = self.S
        if len(S.joined):
            self.release(skinny_faces(S.X, S.F, FEATURE_RELEASE_DEG))
        locked = S.locked
        followed = at_points(S.X, kept) & ~at_points(S.X, self.features)
        S.locked = locked | _ring(S.F, followed) | folded_vertices(S, EVEN_FOLD_DEG)
        floor = np.minimum(min_corner_angles(S.X, S.F), np.radians(min_angle_deg))
        sag = None if self.tol is None else partial(sag_veto, S, self.tol,
                                                    samples=EVEN_SAG_SAMPLES)
        for _ in range(steps):
            self.relax(veto=partial(angle_veto, S, floor, sag), equalize=AREA_EQUALIZE)
        if ring_steps > 0:
            floor = np.minimum(min_corner_angles(S.X, S.F),
                               np.radians(max(min_angle_deg, RING_FLOOR_DEG)))
            veto = ring_step_veto(S, floor, sag)
            for _ in range(ring_steps):
                self.relax(veto=veto, equalize=AREA_EQUALIZE)
        S.locked = locked

    def raise_above(self, angle_deg: float, min_angle_deg: float) -> None:
        """The flips and vertex moves of :func:`.angles.raise_min_angles` (each made only where
        it raises the smallest angle of the faces it touches and leaves no more of them below
        ``angle_deg``, under the sag and gap guards at ``RAISE_SAG`` × the tolerance: the
        other steps' full tolerance lets a move take the remesh farther from the input than
        it is anywhere; a face takes the first that lifts it to ``angle_deg``; no collapses:
        the count stays, with no splits to give it back) around the faces with an angle below
        ``angle_deg`` that no input corner forces (:func:`.angles.forced_corners` at
        ``min_angle_deg``) and, those not below ``min_angle_deg``, whose smallest angle is not
        at a corner too sharp to give its faces ``angle_deg`` (its share caps them); each group
        of operations (those whose faces share a vertex they change) undone where it leaves
        among its faces more turned over, more or worse faces below ``min_angle_deg`` that no
        corner forces, a smaller sum of smallest angles or a larger sum of squared relative
        area deviations (:func:`raise_judge`: the faces below ``angle_deg`` lifted at no cost
        to the mean smallest angle or the evenness of the areas). The evening steps
        trade angles for even areas down to ``min_angle_deg``: a face between that and
        ``angle_deg`` is often one flip or move from a larger angle (a short rim edge with its
        far corner pushed away, the faces around a vertex the repairs moved)."""
        S = self.S
        bad = skinny_faces(S.X, S.F, angle_deg)
        A = corner_angles_deg(S.X, S.F[bad])
        bad = bad[~forced_corners(S, min_angle_deg, bad).any(axis=1) &
                  ~(forced_corners(S, angle_deg, bad)[np.arange(len(bad)), A.argmin(axis=1)] &
                    (row_min(A) >= min_angle_deg))]
        tol = None if self.tol is None else RAISE_SAG * self.tol
        mean_area = float(face_double_areas(S.X, S.F).mean())
        raise_min_angles(S, angle_deg, tol, bad, first_enough=True, collapses=False,
                         mean_area=mean_area,
                         judge=partial(raise_judge, S, min_angle_deg,
                                       sharp_vertices(S, min_angle_deg), mean_area))

    def guarantee(self, target: int, min_angle_deg: float, passes: int = 4,
                  kept: tuple | None = None) -> None:
        """Collapse the edges shorter than ``L`` between interior corners of faces with a 3D angle
        below ``min_angle_deg`` (the first half of the passes under the sag and gap guards, the
        rest under guards ``LOOSE`` times looser), the count given back by splits, then flips;
        then the needles and caps left (an angle below ``NEEDLE_DEG``: vertices crowded onto a
        line where the map is most anisotropic, which no guarded collapse or flip removes) as
        the degenerate faces are, between interior corners (:meth:`collapse_at_faces`: the
        rim's vertices, those of its refinement among them, stay); last the local operations
        of :func:`.angles.raise_min_angles` around the faces still below, the count restored
        (splits, or collapses of the shortest edges under the guards) and the operations
        again around the faces then below; where folds are left at the end (these operations
        judge angles, and near a fold they can turn faces over), the local operations judged
        on the folds and the minimum-angle ones again, a group of folds at a time
        (:meth:`unfold_kept`); then those at the faces still below under looser guards
        (:meth:`last_resort`); last the faces still below that no input corner forces refined
        (:meth:`refine_left`: the fold repair's operations and the looser ones leave faces the
        refinement before them did not see), the corner splits among its kinds, and the looser
        operations again; then those faces refined one at a time (:meth:`refine_each`); then
        the faces forced by input corners raised (:meth:`raise_forced`) and the rim corners
        of the unforced ones changed (:meth:`aim_unforced`); last, where folds are left, the
        fold repair's operations at them once more (:meth:`unfold_left`). Given ``kept``
        (``(P, Q)``, k×3 and l×3 points),
        the vertices at ``P`` are locked for the first collapses (they remove none of them:
        a vertex followed onto the input, :meth:`follow`, stays on it), those at ``Q`` for
        the rest, but not the feature vertices freed since (:meth:`lock_at`). The feature
        vertices of the faces each of these works on are freed first (:meth:`release`)."""
        S, L, tol = self.S, self.L, self.tol
        if kept is not None:
            self.lock_at(kept[0])
        for i in range(passes):
            bad = skinny_faces(S.X, S.F, min_angle_deg)
            if len(bad) == 0:
                break
            self.release(bad)
            at = np.zeros(S.n, bool)
            at[S.F[bad].ravel()] = True
            at &= ~S.is_rim
            t = None if tol is None else tol * (1.0 if i < passes // 2 else LOOSE)
            collapse_short_edges(S, L, 2.0 * L, max_gap=t, max_sag=t, at=at)
            if S.n < target:
                split_long_edges(S, 0.0, budget=target - S.n)
            self.flip()
        if kept is not None:
            self.lock_at(kept[1])
        self.collapse_at_faces(target, lambda: skinny_faces(S.X, S.F, NEEDLE_DEG),
                               "needles_collapsed", NEEDLE_PASSES, rim=False)
        self.raise_angles(min_angle_deg)
        self.restore_angle_count(target, min_angle_deg)
        self.raise_angles(min_angle_deg)
        self.open_fans(target, min_angle_deg)
        self.refine_left(target, min_angle_deg)
        self.unfold_kept(min_angle_deg)
        self.last_resort(min_angle_deg)
        self.refine_left(target, min_angle_deg, corners=True)
        self.last_resort(min_angle_deg)
        self.refine_each(target, min_angle_deg)
        self.raise_forced(min_angle_deg)
        self.aim_unforced(min_angle_deg)
        self.unfold_left(min_angle_deg)

    def refine_left(self, target: int, min_angle_deg: float, corners: bool = False) -> None:
        """Up to ``GRADE_PASSES`` times while it is kept: the faces below ``min_angle_deg``
        that no input corner forces refined (:meth:`grade`, with ``corners`` its corner
        splits too)."""
        for _ in range(GRADE_PASSES):
            if not self.grade(target, min_angle_deg, corners):
                break

    def refine_each(self, target: int, min_angle_deg: float) -> None:
        """Face after face, worst first, each once (known by its corners' positions), none in
        a hole the cut removes (:func:`each_unforced_face` with ``outside_holes``): a face
        still below ``min_angle_deg`` that no input corner forces refined alone (:meth:`grade`
        with its corner splits, ``only`` its corners, the caps' splits only for a cap:
        :func:`.circumcentres.cap_split`), at most ``EACH_FACES`` of them. Kept as
        :meth:`refine_unforced` keeps it, judged on the whole remesh: a refinement of all of
        them at once is kept or undone as a whole, and where a ragged rim's teeth leave many
        such faces the insertions that make some of them worse undo those that mend others
        (an interior vertex with rim vertices all round it, squeezed against a short rim
        edge, whose collapse would make a face with three rim corners)."""
        S = self.S
        for f, shortfall in each_unforced_face(S, min_angle_deg, EACH_FACES,
                                               outside_holes=True):
            caps = (False, True) if cap_split(S, f) is not None else (False,)
            self.grade(target, min_angle_deg, corners=True, only=S.X[S.F[f]], caps=caps,
                       shortfall=shortfall)

    def move_each(self, min_angle_deg: float) -> None:
        """Face after face, worst first, each once, none in a hole the cut removes
        (:func:`each_unforced_face` with ``outside_holes``: each face's trials judge the whole
        remesh, and a scan's ragged openings leave many faces in their fans): the free
        corners (interior, not locked) of a face still below ``min_angle_deg`` that no input
        corner forces, one after the other, each moved to the point of its star
        (:func:`.unfold.star_positions`) with no face of the star turned over and none at a
        sharp input corner (:func:`.angles.sharp_vertices`: the faces the judge below does not
        count) with a smallest angle below what it was and ``min_angle_deg``, first in
        :func:`star_order`
        (fewest faces of the star below the minimum, then the largest smallest angle), where
        that comes before the star as it is;
        undone if it leaves more such faces, or as many with no larger smallest angle, or more
        faces turned over (:attr:`folds`); the first move kept ends the face's turn. A face
        with no free corner (three locked ones: a tooth of a ragged hole loop) has the free
        vertices across its edges that are not kept (:func:`across_unjoined`) tried instead,
        whose :meth:`flip_and_move` can flip that edge away. Where the
        rim is sampled closer than the remesh's spacing, such a corner is an interior vertex
        with rim vertices all round (a notch), which no collapse may remove (it would make a
        face with three rim corners) and whose moves among the minimum-angle operations' few
        candidates (:func:`.angles.move_candidates`) do not reach the star's best point."""
        S = self.S
        for f, shortfall in each_unforced_face(S, min_angle_deg, EACH_FACES, outside_holes=True):
            free = free_corners(S, f).tolist() or across_unjoined(S, f).tolist()
            if not any(self.move_in_star(v, min_angle_deg, shortfall) for v in free):
                any(self.flip_and_move(v, min_angle_deg, shortfall) for v in free)

    def move_in_star(self, v: int, min_angle_deg: float, before: tuple[int, float]) -> bool:
        """Vertex ``v`` moved as :meth:`move_each` moves it, kept as it keeps it, ``before``
        the remesh's :func:`.circumcentres.unforced_shortfall`. Returns whether it was kept."""
        S = self.S
        found = star_candidates(S, v, min_angle_deg)
        if found is None:
            return False
        star, where, angles, ok, now = found
        best = star_best(angles[ok], min_angle_deg)
        if best is None or star_order(angles[ok][best], min_angle_deg) >= \
                star_order(now, min_angle_deg):
            return False
        saved, n_folds = self.saved(), int(self.folds(S).sum())
        S.uv[v], S.face[v], S.bary[v], S.X[v] = (w[ok][best] for w in where)
        if shortfall_order(unforced_shortfall(S, min_angle_deg)) >= shortfall_order(before) \
                or self.folds(S).sum() > n_folds:
            self.restore(saved)
            return False
        S.tally("star_moves", 1)
        return True

    def flip_and_move(self, v: int, min_angle_deg: float, before: tuple[int, float]) -> bool:
        """Each interior edge of the link of the free vertex ``v`` flipped (``v`` gains the
        vertex across it, :func:`link_flip`), then ``v`` moved to the best point of its new star
        where one passes :meth:`move_to_best`'s guards, and the local operations at the faces
        below the minimum that no input corner forces within ``FORCED_REACH × L`` of where it
        was (among them the collapse of ``v`` the flip let through); the one
        that leaves the fewest such faces, then the largest smallest angle, kept where that
        beats ``before`` (the remesh's :func:`.circumcentres.unforced_shortfall`) with no
        more folds and no smaller smallest angle of the remesh (a face an input corner
        forces). Where a ragged rim's tooth is narrower than the remesh, ``v`` can have
        rim vertices all round (a rim cap), or some rim-to-rim edges in its link, whose star no
        position of ``v`` makes wide enough, which no collapse may remove (a face with three
        rim corners) and whose link edges no flip judged on its own angles opens. Where no
        single flip is kept, each pair of flips (a link edge, then one of the link after it)
        is tried the same way: beside a rim cap, a reflex rim vertex can need two of its
        neighbour's link edges opened at once. Returns whether one was kept."""
        S = self.S
        judge = partial(self.judge_flipped, v, min_angle_deg, before, int(self.folds(S).sum()),
                        float(np.degrees(min_corner_angles(S.X, S.F)).min()))
        best = self.best_flips(v, judge, 1)
        pairs = best is None
        if pairs:
            best = self.best_flips(v, judge, 2)
        if best is None:
            return False
        self.restore(best[1])
        S.tally("link_flip_pairs" if pairs else "link_flips", 1)
        return True

    def best_flips(self, v: int, judge, flips: int, best: tuple | None = None
                   ) -> tuple | None:
        """Each sequence of ``flips`` flips of interior link edges of ``v`` (:func:`link_edges`,
        :func:`link_flip`; each after the one before it), then ``judge(best)`` (the best so
        far, :meth:`judge_flipped`), the remesh put back after each. Returns the best."""
        S = self.S
        start = self.saved()
        for h in link_edges(S, v):
            if not link_flip(S, int(h)):
                continue
            best = judge(best) if flips == 1 else self.best_flips(v, judge, flips - 1, best)
            self.restore(start)
            start = self.saved()                 # (restore puts the saved arrays themselves)
        return best

    def judge_flipped(self, v: int, min_angle_deg: float, before: tuple[int, float],
                      n_folds: int, smallest: float, best: tuple | None) -> tuple | None:
        """After flips at ``v``: ``v`` moved to the best point of its star
        (:meth:`move_to_best`) and the local operations near where it was (:meth:`raise_near`);
        the remesh's shortfall order and state (:meth:`saved`) where they beat ``before`` and
        ``best`` (``(shortfall order, state)`` or None) with no more than ``n_folds`` folds and
        no smallest angle below ``smallest``; else ``best``."""
        S = self.S
        point = S.X[v].copy()
        self.move_to_best(v, min_angle_deg)
        self.raise_near(point, min_angle_deg, S.n)
        after = shortfall_order(unforced_shortfall(S, min_angle_deg))
        if after < shortfall_order(before) and self.folds(S).sum() <= n_folds and \
                (best is None or after < best[0]) and \
                np.degrees(min_corner_angles(S.X, S.F)).min() >= smallest:
            return after, self.saved()
        return best

    def move_to_best(self, v: int, min_angle_deg: float) -> bool:
        """Vertex ``v`` moved to the point of its star first in :func:`star_order` among those
        that turn no face of the star over, leave no face at a sharp input corner
        (:func:`.angles.sharp_vertices`) smaller than it was and ``min_angle_deg``, and pass
        the guards of the wedge's moves (:func:`.wedge.move_guards_ok`: the old position
        within the sag tolerance of the new star, no edge of ``v`` farther from the surface
        than the tolerance or than it was). Returns whether it was moved."""
        S = self.S
        found = star_candidates(S, v, min_angle_deg)
        if found is None:
            return False
        star, where, angles, ok, now = found
        for _ in range(int(ok.sum())):
            row = np.flatnonzero(ok)[star_best(angles[ok], min_angle_deg)]
            at = tuple(w[row] for w in where)
            if move_guards_ok(S, v, star, *at, self.tol):
                S.uv[v], S.face[v], S.bary[v], S.X[v] = at
                return True
            ok[row] = False
        return False

    def last_resort(self, min_angle_deg: float) -> None:
        """The local operations of :func:`.angles.raise_min_angles` at the faces still below
        ``min_angle_deg`` that no input corner forces (:func:`.circumcentres.unforced_below`),
        under sag and gap guards ``LAST_RESORT`` times looser, one factor after the other, the
        vertices their collapses removed given back by splits that make no face below the
        minimum (:func:`.angles.split_for_count`), each undone unless it leaves fewer such
        faces, or as many with a larger smallest angle, and no more folds: the guards keep a
        vertex on a crease narrower than the remesh (a valence-3 vertex followed onto it, a cap
        beside it) where only its removal or a move off the crease raises the angle."""
        S = self.S
        if self.tol is None:
            return
        bad, worst = unforced_below(S, min_angle_deg)
        for scale in LAST_RESORT:
            if len(bad) == 0:
                return
            saved, n_folds, n0 = self.saved(), int(self.folds(S).sum()), S.n
            self.release(bad)
            after = None
            if raise_min_angles(S, min_angle_deg, scale * self.tol, bad, self.judged):
                if S.n < n0:
                    split_for_count(S, n0 - S.n, min_angle_deg)
                after = unforced_below(S, min_angle_deg)
            if after is None or self.folds(S).sum() > n_folds or \
                    shortfall_order(shortfall_of(after[1])) >= \
                    shortfall_order(shortfall_of(worst)):
                self.restore(saved)              # (also the faces' order, where none was made)
            else:
                bad, worst = after

    def raise_forced(self, min_angle_deg: float) -> None:
        """Corner after corner, the faces an input corner forces below ``min_angle_deg``
        (:func:`.angles.forced_corners`) raised as far as the corner allows: the local
        operations of :func:`.angles.raise_min_angles` at its faces judged on their smallest
        angle alone (``count_below`` False: a 36° rim corner's two faces of 4° and 32° become
        two of 18°, which the rest of the pass, leaving no more faces below the minimum,
        never passes through), then the usual operations at the faces below the minimum that
        no input corner forces within ``FORCED_REACH × L`` of the corner (those the first
        left below), the vertices their collapses removed given back
        (:func:`.angles.split_for_count`); undone unless the smallest angle of the faces at
        the corner rises (:meth:`smallest_at`), with no more folds and no more faces below
        the minimum that no input corner forces, nor as many with a smaller smallest angle
        (:func:`.circumcentres.unforced_shortfall`; :meth:`share_corner`); then, where a rim
        corner's two faces stay short of their even split, a new or moved middle vertex on the
        corner's wedge (:meth:`aim_corner`)."""
        S = self.S
        bad = skinny_faces(S.X, S.F, min_angle_deg)
        at = forced_corners(S, min_angle_deg, bad)
        for point in S.X[np.unique(S.F[bad][at])]:
            self.share_corner(point, min_angle_deg, partial(
                raise_min_angles, S, min_angle_deg, self.tol, self.faces_at(point), self.judged,
                count_below=False))
            self.aim_corner(point, min_angle_deg)

    def aim_unforced(self, min_angle_deg: float) -> None:
        """The rim corners at which a face below ``min_angle_deg`` that no input corner forces
        has its smallest angle, each changed as :meth:`rim_corner_attempts` lists (the best
        kept, :meth:`best_change`): a narrow tooth of a ragged rim (an input corner a little
        wider than two faces of the minimum) whose middle vertex the local operations leave
        near one rim neighbour, or whose rim edges cut across the input's rim beside it; at
        these and at the rim corners where such a face has an angle wider than
        :data:`.rim.RIM_FAN_MAX_DEG` (a rim cap: its long edge across the rim vertex, its
        small angles at the ends), the corner's fan opened (:meth:`open_fan`), kept as
        :meth:`share_corner` keeps a change and only where it mends a face (``gain``: the
        global fan opening of :meth:`open_fans`, judged on the whole remesh, is undone where
        it opens fans that need no opening); then the vertices they added given back
        (:meth:`give_back`)."""
        S = self.S
        bad, _ = unforced_below(S, min_angle_deg)
        if len(bad) == 0:
            return
        T = S.F[bad]
        A = corner_angles_deg(S.X, T)
        smallest = T[np.arange(len(bad)), A.argmin(axis=1)]
        widest = T[np.arange(len(bad)), A.argmax(axis=1)]
        smallest = np.unique(smallest[S.is_rim[smallest]])
        widest = np.setdiff1d(widest[S.is_rim[widest] & (A.max(axis=1) > RIM_FAN_MAX_DEG)],
                              smallest)
        n0, points = S.n, S.X[np.r_[smallest, widest]]
        for i, point in enumerate(points):
            c = self.rim_vertex_at(point)
            if c is not None and i < len(smallest):
                self.best_change(point, min_angle_deg, self.rim_corner_attempts(c, min_angle_deg))
            c = self.rim_vertex_at(point)
            if c is not None:
                self.share_corner(point, min_angle_deg, partial(self.open_fan, c), gain=True)
        if S.n > n0:
            self.give_back(n0, min_angle_deg)

    def give_back(self, target: int, min_angle_deg: float) -> None:
        """The count brought back to ``target`` by collapses of the shortest edges under the
        guards away from the vertices added since (:meth:`restore_angle_count`) and the local
        operations around the faces then below ``min_angle_deg`` (:meth:`raise_angles`),
        undone where that leaves another count, more faces below the minimum that no input
        corner forces, as many with a smaller smallest angle, or more folds; where that is
        undone, one vertex at a time the same way (the added vertices known by their
        positions), until one is undone: the collapses of many at once can squeeze a face
        that those of fewer leave alone."""
        S = self.S
        added = S.X[target:].copy()
        if self.give_back_to(target, min_angle_deg, at_points(S.X, added)):
            return
        while S.n > target and self.give_back_to(S.n - 1, min_angle_deg, at_points(S.X, added)):
            pass

    def give_back_to(self, count: int, min_angle_deg: float, added: np.ndarray) -> bool:
        """:meth:`give_back`'s collapses down to ``count`` vertices, away from the vertices
        ``added`` (n bool) and their neighbours, and the local operations after them; undone
        as it says. Returns whether they were kept."""
        S = self.S
        before, saved, n_folds = unforced_shortfall(S, min_angle_deg), self.saved(), \
            int(self.folds(S).sum())
        self.restore_angle_count(count, min_angle_deg, keep=added)
        self.raise_angles(min_angle_deg)
        after = unforced_shortfall(S, min_angle_deg)
        if S.n != count or shortfall_order(after) > shortfall_order(before) or \
                self.folds(S).sum() > n_folds:
            self.restore(saved)
            return False
        return True

    def rim_corner_attempts(self, c: int, min_angle_deg: float) -> list:
        """The changes tried at the rim corner ``c``: with two faces, those of
        :meth:`aim_corner`'s wedge (:meth:`wedge_attempts`); and the split of each of its two
        rim edges at ``RIM_SPLIT_TS`` along it from ``c`` (:meth:`split_rim_edges`: the new
        vertex on the input's rim, where it leaves a wider angle at ``c`` where the rim
        bulges out beside it), and of both together; and the split of each at the input
        boundary vertex it cuts off farthest (:meth:`cut_off_corners`: a new rim vertex at the
        tip of a tooth the rim crosses, ragged ones among them, where ``c``'s angle is the
        narrower for the rim edge cutting across the tooth), and of both together. Each is
        ``(change, held vertex)``."""
        S = self.S
        star = vertex_star(S.F, c)
        fan = two_face_fan(star)
        attempts = [] if fan is None else self.wedge_attempts(c, fan, min_angle_deg)
        ends = np.unique(star[:, 1:])
        ends = [int(x) for x in ends[S.is_rim[ends]]]
        attempts += [(partial(self.split_rim_edges, c, [x], t), None)
                     for x in ends for t in RIM_SPLIT_TS]
        attempts += [(partial(self.split_rim_edges, c, ends, t), None)
                     for t in RIM_SPLIT_TS if len(ends) == 2]
        tips = self.cut_off_corners(c, ends)
        attempts += [(partial(self.split_rim_edges_at, c, [tip]), None) for tip in tips]
        return attempts + ([(partial(self.split_rim_edges_at, c, tips), None)]
                           if len(tips) == 2 else [])

    def open_fan(self, c: int) -> bool:
        """The fan of the rim vertex ``c`` opened: the interior edges across its angles wider
        than :data:`.rim.RIM_FAN_MAX_DEG` split at their middles on the disk
        (:func:`.rim.fan_edges`; those of no face in common), flips around the faces
        changed. Returns whether one was."""
        S = self.S
        at = np.zeros(S.n, bool)
        at[c] = True
        h, twin = fan_edges(S, at)
        sel = independent_edges(len(S.F), h, twin, np.zeros(len(h)))
        if len(sel) == 0:
            return False
        F_before = S.F.copy()
        split_edges(S, h[sel], twin[sel])
        self.flip(since=F_before)
        return True

    def cut_off_corners(self, c: int, ends: list) -> list:
        """For the rim edge from ``c`` to each of ``ends``, the input boundary vertex (a polygon
        corner, ragged ones among them) that the edge cuts off farthest from it
        (:func:`.rim.rim_gaps`): the tip of a tooth the rim crosses. None for an edge that cuts
        none off or whose corner is within ``SLIVER × L`` of an end (a needle). Returns
        ``(end, domain point)`` pairs (the point (2,) a corner of ``S.polygon``)."""
        S = self.S
        corners_X, corner_s = S.of_input(rim_corners)
        _, a, b, corner, gap = rim_gaps(S, corners_X, corner_s,
                                        skip=np.zeros(len(S.polygon), bool))
        out = []
        for x in ends:
            row = np.flatnonzero(((a == c) & (b == x)) | ((a == x) & (b == c)))
            if len(row) == 0 or gap[row[0]] <= 0:
                continue
            k = corner[row[0]]
            if min(norms(corners_X[[k, k]] - S.X[[c, x]])) >= SLIVER * self.L:
                out.append((x, S.polygon[k]))
        return out

    def aim_corner(self, point: np.ndarray, min_angle_deg: float) -> None:
        """At a rim corner (the vertex at ``point``, 3,) with two faces whose smallest angle is
        below ``AIM_SHARE`` × the even split of its input angle sum between them: the changes
        of :meth:`wedge_attempts`, the best kept (:meth:`best_change`)."""
        S = self.S
        c = self.rim_vertex_at(point)
        if c is None:
            return
        even = float(S.angle_sums_in()[input_vertex_under(S, np.array([c]))[0]]) / 2
        if self.smallest_at(point) >= AIM_SHARE * even:
            return
        fan = two_face_fan(vertex_star(S.F, c))
        if fan is None:
            return
        self.best_change(point, min_angle_deg, self.wedge_attempts(c, fan, min_angle_deg))

    def wedge_attempts(self, c: int, fan: tuple[int, int, int], min_angle_deg: float) -> list:
        """The changes at the rim corner ``c`` with the two-face fan ``fan`` (``(b, w, a)``,
        :func:`.wedge.two_face_fan`): its middle edge split at the points of
        :func:`.wedge.even_split_points` (a new middle vertex, :meth:`split_middle_edge`) and
        the middle vertex moved to those of :func:`.wedge.even_split_moves`. Each is
        ``(change, held vertex)``."""
        S = self.S
        b, w, a = fan
        attempts = [(partial(self.split_middle_edge, c, w, M), S.n)
                    for M in even_split_points(S, c, b, w, a)]
        return attempts + [(partial(put_vertex, S, w, where), w) for where in
                           even_split_moves(S, c, vertex_star(S.F, w), self.tol, min_angle_deg)]

    def best_change(self, point: np.ndarray, min_angle_deg: float, attempts: list) -> None:
        """Each of ``attempts`` (``(change, held vertex)``) tried at the corner at ``point``
        (3,) from the remesh as it was and judged as :meth:`share_corner` judges a change (the
        vertex held meanwhile); the one kept that leaves the corner's faces the largest
        smallest angle stays. The judge's measures of the remesh as it was
        (:meth:`corner_measures`) are taken once: every attempt starts from it."""
        start, best = self.saved(), None
        measured = self.corner_measures(point, min_angle_deg)
        for change, hold in attempts:
            if self.share_corner(point, min_angle_deg, change, hold=hold, measured=measured):
                if best is None or self.smallest_at(point) > best[0]:
                    best = (self.smallest_at(point), self.saved())
                self.restore(start)
                start = self.saved()             # (restore puts the saved arrays themselves)
        if best is not None:
            self.restore(best[1])

    def split_rim_edges(self, c: int, ends: list, t: float) -> bool:
        """Split the rim edges from ``c`` to each of ``ends``, each with a new rim vertex at the
        point of the input's rim (the image polygon) nearest to the domain point ``t`` along
        it from ``c`` (:meth:`split_middle_edge`); all undone, returning False, where one is
        refused."""
        S = self.S
        M = np.array([(1.0 - t) * S.uv[c] + t * S.uv[x] for x in ends])
        _, _, M = S.of_input(polygon_segments).closest(M)
        return self.split_rim_edges_at(c, list(zip(ends, M)))

    def split_rim_edges_at(self, c: int, splits: list) -> bool:
        """Split the rim edge from ``c`` to each ``end`` of ``splits`` (``(end, domain point)``
        pairs) with a new rim vertex at its point (:meth:`split_middle_edge`); all undone,
        returning False, where one is refused."""
        S = self.S
        saved = saved_state(S)
        for x, M in splits:
            if not self.split_middle_edge(c, x, M):
                restore_state(S, saved)
                return False
        return True

    def split_middle_edge(self, c: int, w: int, M: np.ndarray) -> bool:
        """Split the edge ``c–w`` (a rim edge too) with a new vertex at the domain point ``M``
        (2,) (:func:`.refine.split_edges`); undone, returning False, where an edge of the new
        vertex is farther from the surface than the sag tolerance (:func:`.sag.edge_sag_along`
        at :data:`.angles.SAG_TS`)."""
        S = self.S
        saved = saved_state(S)
        h = half_edge(S.F, c, w, either=True)
        split_edges(S, np.array([h]), S.twins()[[h]], points=M[None])
        p = S.n - 1
        if self.tol is not None:
            ends = np.unique(vertex_star(S.F, p)[:, 1:])
            ends = ends[ends != p]
            if (edge_sag_along(S, np.full(len(ends), p), ends, SAG_TS)[0] > self.tol).any():
                restore_state(S, saved)
                return False
        return True

    def share_corner(self, point: np.ndarray, min_angle_deg: float, change,
                     hold: int | None = None, measured: tuple | None = None,
                     gain: bool = False) -> bool:
        """``change()`` at the corner at ``point`` (3,) (returns whether it changed anything),
        then the usual operations at the faces below ``min_angle_deg`` that no input corner
        forces within ``FORCED_REACH × L`` of the corner, the vertices their collapses removed
        given back (:func:`.angles.split_for_count`); undone unless the smallest angle of the
        faces at the corner rises (:meth:`smallest_at`), with no more folds and no more faces
        below the minimum that no input corner forces, nor as many with a smaller smallest
        angle (:func:`.circumcentres.unforced_shortfall`); the vertex ``hold`` (once ``change``
        made it), where given, locked meanwhile (the operations at the faces around it would
        move it back). ``measured``: :meth:`corner_measures` of the remesh as it is, when the
        caller knows them. With ``gain``, also undone unless the shortfall shrinks (fewer such
        faces, or as many with a larger smallest angle): a change whose vertex the count may
        not get back must mend a face. Returns whether it was kept."""
        S = self.S
        before, n_folds, worst = (self.corner_measures(point, min_angle_deg)
                                  if measured is None else measured)
        saved, n0 = self.saved(), S.n
        if not change():
            return False
        held = None if hold is None else (S.X[hold].copy(), bool(S.locked[hold]))
        if held is not None:
            S.locked[hold] = True
        self.raise_near(point, min_angle_deg, n0)
        if held is not None:
            S.locked[at_points(S.X, held[0][None])] = held[1]
        after = shortfall_order(unforced_shortfall(S, min_angle_deg))
        if self.smallest_at(point) <= worst or self.folds(S).sum() > n_folds or \
                after > shortfall_order(before) or (gain and after == shortfall_order(before)):
            self.restore(saved)
            return False
        return True

    def corner_measures(self, point: np.ndarray, min_angle_deg: float
                        ) -> tuple[tuple[int, float], int, float]:
        """What :meth:`share_corner` compares a change at the corner at ``point`` (3,) with:
        the remesh's :func:`.circumcentres.unforced_shortfall` at ``min_angle_deg``, its
        number of folds (:attr:`folds`) and the smallest angle at the corner
        (:meth:`smallest_at`)."""
        S = self.S
        return (unforced_shortfall(S, min_angle_deg), int(self.folds(S).sum()),
                self.smallest_at(point))

    def raise_near(self, point: np.ndarray, min_angle_deg: float, count: int) -> None:
        """The usual operations (:func:`.angles.raise_min_angles`) at the faces below
        ``min_angle_deg`` that no input corner forces within ``FORCED_REACH × L`` of ``point``
        (3,), then the vertices their collapses took below ``count`` given back
        (:func:`.angles.split_for_count`)."""
        S = self.S
        near = norms(S.X - point) < FORCED_REACH * self.L
        low, _ = unforced_among(S, min_angle_deg, np.flatnonzero(near[S.F].any(axis=1)))
        raise_min_angles(S, min_angle_deg, self.tol, low, self.judged)
        if S.n < count:
            split_for_count(S, count - S.n, min_angle_deg)

    def rim_vertex_at(self, point: np.ndarray) -> int | None:
        """The rim vertex at ``point`` (3,); None where no vertex is there (a collapse removed
        it) or it is not on the rim."""
        S = self.S
        c = np.flatnonzero(at_points(S.X, point[None]))
        return int(c[0]) if len(c) and S.is_rim[c[0]] else None

    def faces_at(self, point: np.ndarray) -> np.ndarray:
        """The faces (indices) at the vertex at ``point`` (3,); none where no vertex is there
        (a collapse removed it)."""
        S = self.S
        return np.flatnonzero(touching(S.F, at_points(S.X, point[None])))

    def smallest_at(self, point: np.ndarray) -> float:
        """The smallest angle (degrees) of the faces at the vertex at ``point`` (3,)
        (:meth:`faces_at`); 180 where no vertex is there."""
        S = self.S
        T = S.F[self.faces_at(point)]
        return float(np.degrees(min_corner_angles(S.X, T)).min(initial=180.0))

    def restore_angle_count(self, target: int, min_angle_deg: float,
                            keep: np.ndarray | None = None) -> None:
        """The count restored after the minimum-angle operations: splits that make no face
        below ``min_angle_deg`` (:func:`.angles.split_for_count`) or collapses of the
        shortest edges under the guards, none at the vertices ``keep`` (n bool) and their
        neighbours."""
        S = self.S
        if S.n < target:
            split_for_count(S, target - S.n, min_angle_deg)
        elif S.n > target:
            at = None if keep is None else ~_ring(S.F, keep)
            collapse_short_edges(S, np.inf, 2.0 * self.L, budget=S.n - target,
                                 max_gap=self.tol, max_sag=self.tol, at=at)

    def grade(self, target: int, min_angle_deg: float, corners: bool = False,
              only: np.ndarray | None = None, caps: tuple = (False, True),
              shortfall: tuple[int, float] | None = None) -> bool:
        """The faces still below ``min_angle_deg`` that no input corner forces refined
        (:func:`.circumcentres.refine_at_circumcentres`, after each round flips and the local
        operations, :meth:`flip_and_raise`): at their off-centres, or where that is not kept,
        with their caps' long edges split, each until ``GRADE_PATIENCE`` rounds in a row beat no
        earlier state, or, with ``corners``, where neither is kept with the interior edges at
        their smallest corners split (:func:`.circumcentres.corner_split_round`), then flips;
        kept as :meth:`refine_unforced` keeps it. Given ``only`` (j×3 points), the insertions
        are for the faces with their corners all at these points alone; ``caps``: the first two
        kinds, as the refinement's ``caps`` (on a face that is no cap, the second makes the
        first again). ``shortfall``: :func:`.circumcentres.unforced_shortfall` of the remesh
        as it is, when the caller knows it; measured once, as every kind starts from the same
        remesh (one not kept is undone). Returns whether it was kept."""
        S = self.S
        if shortfall is None:
            shortfall = unforced_shortfall(S, min_angle_deg)
        raise_after = partial(self.flip_and_raise, min_angle_deg)
        for cap in caps:
            insert = partial(refine_at_circumcentres, S, min_angle_deg, raise_after,
                             lambda: np.flatnonzero(self.folds(S)), caps=cap,
                             patience=GRADE_PATIENCE, only=only, shortfall=shortfall)
            if self.refine_unforced(target, min_angle_deg, insert, before=shortfall):
                return True
        if not corners:
            return False

        def split_corners() -> int:
            k = corner_split_round(S, min_angle_deg, only)
            if k:
                self.flip()
            return k

        return self.refine_unforced(target, min_angle_deg, split_corners, before=shortfall)

    def flip_and_raise(self, min_angle_deg: float, F_before: np.ndarray) -> None:
        """Flips around the faces changed since ``F_before`` (m₀×3), then the local
        operations around the faces below ``min_angle_deg`` (:meth:`raise_angles`)."""
        self.flip(since=F_before)
        self.raise_angles(min_angle_deg)

    def raise_angles(self, min_angle_deg: float, at: np.ndarray | None = None) -> None:
        """The local operations of :func:`.angles.raise_min_angles` around the faces with a 3D
        angle below ``min_angle_deg`` (with a corner among the vertices ``at``, n bool, if
        given), their feature vertices freed first (:meth:`release`)."""
        bad = skinny_faces(self.S.X, self.S.F, min_angle_deg)
        if at is not None:
            bad = bad[at[self.S.F[bad]].any(axis=1)]
        self.release(bad)
        raise_min_angles(self.S, min_angle_deg, self.tol, bad, self.judged)

    def open_fans(self, target: int, min_angle_deg: float) -> bool:
        """The rim's fans opened (:func:`.rim.open_rim_fans`: a vertex in the middle of the
        interior edge across an angle wider than :data:`.rim.RIM_FAN_MAX_DEG` at a rim
        vertex, the caps a reflex corner of the boundary leaves), flips, kept as
        :meth:`refine_unforced` keeps it and only if it leaves no smaller smallest angle (a
        fan opened on a rim edge between close corners can trade two faces for a worse one).
        Returns whether it was kept."""
        def insert() -> int:
            k = open_rim_fans(self.S)
            if k:
                self.flip()
            return k

        return self.refine_unforced(target, min_angle_deg, insert, pareto=True)

    def refine_unforced(self, target: int, min_angle_deg: float, insert,
                        pareto: bool = False, before: tuple[int, float] | None = None
                        ) -> bool:
        """Where faces below ``min_angle_deg`` that no input corner forces are left:
        ``insert()`` (adds vertices, returns how many), the count restored away from the new
        vertices (:meth:`restore_angle_count`) and the local operations again around the faces
        then below; all of it undone if it leaves more such faces, or as many with a smaller
        smallest angle (with ``pareto``: or a smaller smallest angle at all), or more faces
        turned over (counted with :attr:`folds`, again only where the remesh changed).
        ``before``: :func:`.circumcentres.unforced_shortfall` of the remesh as it is, when the
        caller knows it. Returns whether it was kept."""
        S = self.S
        if before is None:
            before = unforced_shortfall(S, min_angle_deg)
        if before[0] == 0:
            return False
        saved, n_folds, n0 = self.saved(), int(self.folds(S).sum()), S.n
        if not insert():
            return False
        added = np.zeros(S.n, bool)
        added[n0:] = True
        self.restore_angle_count(target, min_angle_deg, keep=added)
        self.raise_angles(min_angle_deg)
        after = unforced_shortfall(S, min_angle_deg)
        if shortfall_order(after) >= shortfall_order(before) or \
                (pareto and after[1] < before[1]) or self.folds(S).sum() > n_folds:
            self.restore(saved)
            return False
        return True

    def repair_folds(self, target: int, passes: int = 3, floor: float = 0.0) -> None:
        """Undo the folds (:func:`turned_over_faces`) by the local operations judged on them
        (:meth:`unfold`); then, for the folds left, collapse an edge between interior corners
        of each, shortest first (:meth:`collapse_at_faces`), under the sag and gap guards, then
        under none but the result's validity, each time followed by the local operations and
        undone if it leaves as many folds or more (a collapse at a fold turns its neighbours
        over where the map is that anisotropic). Where a fold has a rim corner, the local
        operations may also remove rim vertices on reflex input corners where that leaves the
        input no farther from the remesh than its farthest point is now (:attr:`chord`,
        :func:`.fidelity.input_reach`; these and the later ones of :meth:`unfold_kept`). The
        two-steps of the local operations push no face below ``floor`` (degrees) where none
        of those they replace was."""
        S = self.S
        folds = lambda: np.flatnonzero(self.folds(S))        # noqa: E731
        if self.tol is not None and S.is_rim[S.F[folds()]].any():
            self.chord = input_reach(S, self.tol)
        self.unfold(floor=floor)
        for guard in (self.tol, None):
            n_folds = len(folds())
            if n_folds == 0:
                return
            saved = self.saved()
            self.collapse_at_faces(target, folds, "folds_repaired", passes, rim=False,
                                   guard=guard)
            self.unfold(floor=floor)
            if len(folds()) >= n_folds:
                self.restore(saved)

    def unfold_kept(self, min_angle_deg: float) -> None:
        """Group after group of folds (faces turned over sharing vertices): the local
        operations around it (:meth:`unfold`; the rim vertices they removed given back by
        splits that make no face below ``min_angle_deg``, :func:`.angles.split_for_count`),
        then those around the faces below ``min_angle_deg`` (:meth:`raise_angles`, then
        :meth:`last_resort`: the faces a fold's undoing leaves skinny stand where the input
        turns, on a crease the guards keep the vertices on), undone unless they leave fewer
        folds and either remove as many as the group had or leave no smaller smallest angle
        among the faces below that no input corner forces
        (:func:`.circumcentres.unforced_shortfall`: where the operations cannot undo a fold,
        what they leave skinny the minimum-angle ones may not raise). A group undone is not
        tried again; the groups tried are tallied under ``fold_groups_tried``, and none is
        tried once the trials have spent their :class:`TrialBudget` (the folds left stay)."""
        S = self.S
        tried, budget, trials = np.zeros((0, 3)), TrialBudget.for_remesh(S), 0
        while True:
            bad = np.flatnonzero(self.folds(S))
            _, group = connected_components(S.F[bad], S.n)
            fresh = ~at_points(S.X[S.F[bad, 0]], tried)
            if not fresh.any():
                break
            at = bad[group == group[fresh.argmax()]]
            before = unforced_shortfall(S, min_angle_deg)
            if not budget.spend(S, before[0]):
                break
            trials, saved = trials + 1, self.saved()
            corners = S.X[S.F[at].ravel()]
            self.unfold_giving_back(at, min_angle_deg, floor=min_angle_deg)
            self.raise_angles(min_angle_deg)
            self.last_resort(min_angle_deg)
            left = int(self.folds(S).sum())
            if left >= len(bad) or (left > len(bad) - len(at) and
                                    unforced_shortfall(S, min_angle_deg)[1] < before[1]):
                self.restore(saved)
                tried = np.vstack([tried, corners])
        if trials:
            S.tally("fold_groups_tried", trials)

    def unfold_giving_back(self, bad: np.ndarray | None, min_angle_deg: float, floor: float
                           ) -> None:
        """The local operations around the folds ``bad`` (:meth:`unfold`, default all, their
        two-steps under ``floor``, degrees), the rim vertices they removed given back by
        splits that make no face below ``min_angle_deg`` (:func:`.angles.split_for_count`)."""
        S = self.S
        rim = int(S.is_rim.sum())
        self.unfold(bad, floor=floor)
        if S.is_rim.sum() < rim:
            split_for_count(S, rim - int(S.is_rim.sum()), min_angle_deg)

    def unfold_left(self, min_angle_deg: float) -> None:
        """Where folds are left at the end of the minimum-angle pass: the local operations
        around all of them once more, their two-steps under no floor
        (:meth:`unfold_giving_back` with ``floor`` 0); where that leaves fewer folds, the
        minimum-angle operations around the faces below ``min_angle_deg`` (:meth:`raise_angles`,
        :meth:`last_resort`) and the free corners of those that no input corner forces moved
        (:meth:`move_each`); undone unless that leaves fewer folds and no more or worse such
        faces (:func:`.circumcentres.unforced_shortfall`). The folds :meth:`unfold_kept`
        leaves (its groups put back, or made by the refinements after it) may have an undoing
        once the passes after it have changed the faces around them; and at a ragged rim's
        notch end beside a locked spike tip, the only pairs of operations that undo the fold
        (a rim collapse and an operation after it, :meth:`.unfold._FoldPatch.two_step`) make a
        face below the minimum, which the earlier repairs' floor refuses and the operations
        after them can raise."""
        S = self.S
        n_folds = int(self.folds(S).sum())
        if n_folds == 0:
            return
        saved, before = self.saved(), unforced_shortfall(S, min_angle_deg)
        self.unfold_giving_back(None, min_angle_deg, floor=0.0)
        if self.folds(S).sum() < n_folds:
            self.raise_angles(min_angle_deg)
            self.last_resort(min_angle_deg)
            self.move_each(min_angle_deg)
        if self.folds(S).sum() >= n_folds or shortfall_order(
                unforced_shortfall(S, min_angle_deg)) > shortfall_order(before):
            self.restore(saved)

    def unfold(self, bad: np.ndarray | None = None, floor: float = 0.0) -> None:
        """The local operations around the folds ``bad`` (face indices; default: all of them,
        :func:`.unfold.unfold_locally`, its two-steps under ``floor``, degrees), the feature
        vertices at them freed first (:meth:`release`)."""
        if bad is None:
            bad = np.flatnonzero(self.folds(self.S))
        if len(bad):
            self.release(bad)
            unfold_locally(self.S, bad, chord=self.chord, floor=floor)

    def saved(self) -> tuple:
        """The state of the remesh, its log and the fold counts (:attr:`folds`), for
        :meth:`restore`."""
        return saved_state(self.S), dict(self.S.log), self.folds.kept()

    def restore(self, saved: tuple) -> None:
        """Put the remesh and its log back as :meth:`saved` returned them, and the fold
        counts with them (the next count recomputes none of the faces put back)."""
        state, log, counted = saved
        restore_state(self.S, state)
        self.S.log.clear()
        self.S.log.update(log)
        self.folds.restore(counted)

    def repair_degenerate(self, target: int, passes: int = 3) -> None:
        """Collapse an edge of every degenerate face (:func:`degenerate_faces`), shortest
        first, under no guard but the result's validity, the count given back by splits, then
        flips; the operations do not make such faces, so this normally finds none."""
        self.collapse_at_faces(target, lambda: degenerate_faces(self.S), "degenerate_repaired",
                               passes)

    def collapse_at_faces(self, target: int, faces, key: str, passes: int, rim: bool = True,
                          guard: float | None = None) -> None:
        """Up to ``passes`` times: free the feature vertices of every face ``faces()``
        (indices) gives (:meth:`release`) and collapse an edge of each (between interior
        corners unless ``rim``), shortest first, under the sag and gap guards
        at ``guard`` (None: under no guard but the result's validity), the count given back by
        splits, then flips; their number tallied under ``key``."""
        S = self.S
        for _ in range(passes):
            bad = faces()
            if len(bad) == 0:
                return
            S.tally(key, len(bad))
            self.release(bad)
            at = np.zeros(S.n, bool)
            at[S.F[bad].ravel()] = True
            if not rim:
                at &= ~S.is_rim
            collapse_short_edges(S, np.inf, np.inf, max_gap=guard, max_sag=guard, at=at)
            if S.n < target:
                split_long_edges(S, 0.0, budget=target - S.n)
            self.flip()

    def restore_count(self, target: int) -> None:
        """Collapse the slivers and as many of the shortest edges as the count exceeds
        ``target``, under the guards (without the sag guard if it refuses too many); split the
        longest edges if the count is below ``target``."""
        S, L, tol = self.S, self.L, self.tol
        h, a, b, _ = edge_table(S.F, twin=S.twins())
        n_short = int(np.count_nonzero(norms(S.X[a] - S.X[b]) < SLIVER * L))
        excess = max(S.n - target, 0) + n_short
        if excess > 0:
            collapse_short_edges(S, np.inf, 2.0 * L, budget=excess, max_gap=tol, max_sag=tol)
            if tol is not None and S.n > target:
                collapse_short_edges(S, np.inf, 2.0 * L, budget=S.n - target, max_gap=tol)
        if S.n < target:
            split_long_edges(S, 0.0, budget=target - S.n)

    def remove_slivers(self, target: int) -> None:
        """Collapse the edges shorter than ``SLIVER × L`` under the guards, the count given back
        by splits, then flips; again while a pass collapses many (the flips let the guards pass
        collapses next to it that they refused before)."""
        S, L, tol = self.S, self.L, self.tol
        for _ in range(SLIVER_PASSES):
            collapsed = collapse_short_edges(S, SLIVER * L, 2.0 * L, max_gap=tol, max_sag=tol)
            if not collapsed:
                break
            if S.n < target:
                split_long_edges(S, 0.0, budget=target - S.n)
            self.flip()
            if collapsed < SLIVER_AGAIN * S.n:
                break


class Stopwatch:
    """``lap(key)`` adds the seconds since the last lap to ``log[key]``, or with ``within`` to
    ``log[within][key]``."""

    def __init__(self, log: dict, within: str | None = None):
        self.log, self.within = log, within
        self.tick = time.perf_counter()

    def __call__(self, key: str) -> None:
        now = time.perf_counter()
        seconds = self.log if self.within is None else self.log.setdefault(self.within, {})
        seconds[key] = seconds.get(key, 0.0) + now - self.tick
        self.tick = now


def sag_at_samples(S: RemeshState, threshold: float, a: np.ndarray, b: np.ndarray
                   ) -> np.ndarray:
    """How far the edges ``a–b`` (k) are from the surface at the points ``SAG_FLIP_TS``
    along them (:func:`.sag.edge_sag_along`), in the mesh's units (k float); 0 for those that
    cannot be farther than ``threshold`` (:func:`.sag.may_sag`)."""
    sag = np.zeros(len(a))
    bent = may_sag(S, a, b, threshold)
    sag[bent] = edge_sag_along(S, a[bent], b[bent], SAG_FLIP_TS)[0]
    return sag


def may_sag_beyond(S: RemeshState, threshold: float, a: np.ndarray, b: np.ndarray
                   ) -> np.ndarray:
    """Which edges ``a–b`` (k) may be farther than ``threshold`` from the surface at the points
    ``SAG_FLIP_TS`` (k bool): those :func:`.sag.may_sag` keeps whose sag at the fewer points
    ``SAG_SCREEN_TS`` (:func:`.sag.edge_sag_along`; never more than at ``SAG_FLIP_TS``)
    exceeds ``SAG_SCREEN_MARGIN × threshold``."""
    out = may_sag(S, a, b, threshold)
    bent = np.flatnonzero(out)
    out[bent] = (edge_sag_along(S, a[bent], b[bent], SAG_SCREEN_TS)[0]
                 > SAG_SCREEN_MARGIN * threshold)
    return out


def turned_from_input(S: RemeshState, faces: np.ndarray) -> np.ndarray:
    """Whether each of the ``faces`` (k×3) faces away from the input's normal under all three
    of its corners (k bool; :func:`.state.turned_against`, the first test of
    :func:`turned_over_faces`)."""
    return turned_against(S.X, faces, S.normals_in().take(S.face[faces], axis=0))


def distances_near(S: RemeshState, P: np.ndarray, centre: np.ndarray, radius: float
                   ) -> np.ndarray:
    """The distances (k,) of the points ``P`` (k×3) to the faces of ``S`` with a corner within
    ``radius`` of ``centre`` (3,): their distances to the remesh where those faces hold their
    nearest points."""
    near = norms(S.X - centre) < radius
    T = S.X.take(S.F[touching(S.F, near)], axis=0)
    k, m = len(P), len(T)
    if k == 0 or m == 0:
        return np.full(k, np.inf)
    Q = np.repeat(P, m, axis=0)
    C = closest_points_on_triangles(Q, *(np.tile(T[:, c], (k, 1)) for c in range(3)))
    return norms(Q - C).reshape(k, m).min(axis=1)


def turned_from_nearest(S: RemeshState, faces: np.ndarray) -> np.ndarray:
    """Whether each of the ``faces`` (k×3) faces away from the input faces nearest to its
    centroid and to each of its corners (k bool): the report's test of a fold
    (:func:`..remesh_quality.turned_over_faces`), which at a crease narrower than the remesh
    can pick the input face across it where the map's face under a corner
    (:func:`turned_over_faces`) does not."""
    T = S.X.take(faces, axis=0)
    P = np.vstack([T.mean(axis=1), T.reshape(-1, 3)])
    _, nearest = S.of_input(input_distance)(P)
    k = len(faces)
    N_in = S.normals_in().take(nearest, axis=0)
    normal = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    centroid_side = dots(normal, N_in[:k]) < 0
    corner_side = np.einsum("ij,ikj->ik", normal, N_in[k:].reshape(k, 3, 3)) < 0
    return centroid_side & corner_side.all(axis=1)


def turned_over_faces(S: RemeshState, faces: np.ndarray | None = None) -> np.ndarray:
    """The faces (indices) of ``S`` whose surface normal points against the input's at each of
    their corners (the normal of the input face each corner lies in) and at their centroid:
    folds, where the remesh doubles back over the surface (:func:`.unfold.turned_over`: the
    definition of :func:`..remesh_quality.turned_over_faces`, with the input faces found
    through the map, and for a centroid whose domain position passes also by closest point);
    given ``faces`` (k indices), those among them."""
    faces = np.arange(len(S.F)) if faces is None else np.asarray(faces)
    return faces[turned_over_rows(S, S.F[faces])]


def degenerate_faces(S: RemeshState) -> np.ndarray:
    """The faces (indices) of ``S`` that are degenerate on the surface (a repeated or
    coincident corner, or zero area: :func:`..remesh_quality.degenerate_faces`) or not
    counter-clockwise on the disk."""
    from ..remesh_quality import degenerate_faces as degenerate_3d
    from .halfedge import double_areas

    bad = np.zeros(len(S.F), bool)
    bad[degenerate_3d(S.X, S.F)] = True
    bad |= ~(double_areas(S.uv, S.F) > 0)
    return np.flatnonzero(bad)


def sag_veto(S: RemeshState, tol: float, uv: np.ndarray, face: np.ndarray, bary: np.ndarray,
             X: np.ndarray, samples: int = SAG_SAMPLES) -> np.ndarray:
    """The ``veto`` of :func:`.relax.tangential_smoothing` that keeps the remesh on the surface:
    given ``S`` with its vertices moved to ``uv`` (n×2; located at ``face``, ``bary``, lifted
    to ``X``), the moving ends (n bool) of the edges with a moving end whose sag at
    ``samples`` points ``t = 1/(samples + 1) …`` (:func:`.sag.edge_sag_along`) would exceed
    ``tol`` and grow."""
    from dataclasses import replace

    moved = np.any(uv != S.uv, axis=1)
    _, a, b, _ = edge_table(S.F, twin=S.twins())
    e = np.flatnonzero(moved[a] | moved[b])
    a, b = a[e], b[e]
    ts = np.arange(1, samples + 1) / (samples + 1)
    after = edge_sag_along(replace(S, uv=uv, face=face, bary=bary, X=X), a, b, ts)[0]
    far = np.flatnonzero(after > tol)
    worse = far[after[far] > edge_sag_along(S, a[far], b[far], ts)[0]]
    drop = np.zeros(len(uv), bool)
    drop[a[worse]] = drop[b[worse]] = True
    return drop & moved


def angle_veto(S: RemeshState, floor: np.ndarray, then, uv: np.ndarray, face: np.ndarray,
               bary: np.ndarray, X: np.ndarray) -> np.ndarray:
    """The ``veto`` of :func:`.relax.tangential_smoothing` that keeps the faces' shape: given
    ``S`` with its vertices moved to ``uv`` (n×2; located at ``face``, ``bary``, lifted to
    ``X``), the moving vertices (n bool) the veto ``then`` (same arguments, or None) drops and
    then, until none is left, the moving corners of every face whose smallest 3D angle would
    be below ``floor`` (m, radians) with the moves dropped so far undone (a face whose moving
    corners are all dropped keeps its angles, so ``floor`` at most the faces' angles before
    the moves ends the rounds)."""
    moved = np.any(uv != S.uv, axis=1)
    drop = np.zeros(len(uv), bool) if then is None else then(uv, face, bary, X) & moved
    while True:
        corners = S.F[min_corner_angles(np.where(drop[:, None], S.X, X), S.F) < floor]
        corners = corners[moved[corners] & ~drop[corners]]
        if len(corners) == 0:
            return drop
        drop[corners] = True


def ring_veto(S: RemeshState, then, uv: np.ndarray, face: np.ndarray, bary: np.ndarray,
              X: np.ndarray) -> np.ndarray:
    """The ``veto`` of :func:`.relax.tangential_smoothing` that keeps only the moves making a
    vertex's faces better shaped and no less even: given ``S`` with its vertices moved to
    ``uv`` (n×2; located at ``face``, ``bary``, lifted to ``X``), the moving vertices (n bool)
    the veto ``then`` (same arguments, or None) drops and, with those moves undone, those
    whose faces' smallest 3D angles would sum lower or whose faces' squared relative area
    deviations ``(A / Ā − 1)²`` (``Ā``: the mean face area before the moves) would sum higher.
    Undoing a move changes the faces of the moves kept: a floor on their angles is the
    outer veto's (:func:`angle_veto` with this one as its ``then``)."""
    moved = np.any(uv != S.uv, axis=1)
    drop = np.zeros(len(uv), bool) if then is None else then(uv, face, bary, X) & moved
    X_kept = np.where(drop[:, None], S.X, X)
    angle_gain = min_corner_angles(X_kept, S.F) - min_corner_angles(S.X, S.F)
    area_before, area_after = face_double_areas(S.X, S.F), face_double_areas(X_kept, S.F)
    mean = area_before.mean()
    spread_gain = (area_after / mean - 1) ** 2 - (area_before / mean - 1) ** 2
    corners = S.F.ravel()
    angle_sum = np.bincount(corners, np.repeat(angle_gain, 3), S.n)
    spread_sum = np.bincount(corners, np.repeat(spread_gain, 3), S.n)
    return drop | (moved & ((angle_sum < 0) | (spread_sum > 0)))


def ring_step_veto(S: RemeshState, floor: np.ndarray, sag=None):
    """The ``veto`` of the ring steps (:meth:`_Operations.even_out`): :func:`ring_veto` after
    the veto ``sag`` (or None), then :func:`angle_veto` with the floor ``floor`` (m, radians)
    over both, so that the moves the ring veto undoes leave no face of a kept move below
    its floor."""
    return partial(angle_veto, S, floor, partial(ring_veto, S, sag))


def folded_vertices(S: RemeshState, max_dihedral_deg: float) -> np.ndarray:
    """The ends (n bool) of the interior edges of ``S`` whose two faces' normals are more than
    ``max_dihedral_deg`` apart: where the remesh folds over a crease or a ridge of the input."""
    N = face_normals(S.X, S.F)
    h, a, b, twin = edge_table(S.F, twin=S.twins())
    inner = twin >= 0
    cos = np.einsum("ij,ij->i", N.take(h[inner] // 3, axis=0), N.take(twin[inner] // 3, axis=0))
    fold = cos < math.cos(math.radians(max_dihedral_deg))
    out = np.zeros(S.n, bool)
    out[a[inner][fold]] = out[b[inner][fold]] = True
    return out


def turned_over_at(S: RemeshState, faces: np.ndarray) -> np.ndarray:
    """Whether each of the ``faces`` (k indices) of ``S`` is turned over
    (:func:`turned_over_faces`; k bool): the measure of a :class:`.face_memo.FaceMemo`."""
    return turned_over_rows(S, S.F[faces])


def raise_judge(S: RemeshState, min_angle_deg: float, sharp: np.ndarray, mean_area: float,
                T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ``judge`` of :meth:`_Operations.raise_above`'s groups of operations: for faces
    ``T`` (k×3) of ``S``, the smallest angle (k, degrees) of each face below
    ``min_angle_deg`` that no input corner forces (its small angle not at a ``sharp`` vertex,
    n bool: :func:`.angles.sharp_vertices`; +inf for the other faces), and the costs of each
    (k×3): turned over (1 or 0, :func:`.unfold.turned_over_rows`), minus its smallest angle
    (degrees), and its squared relative area deviation ``(A / Ā − 1)²`` (``mean_area``:
    ``Ā``, the mean double area, :func:`ring_veto`'s measure)."""
    A = corner_angles_deg(S.X, T)
    smallest = row_min(A)
    forced = (sharp[T] & (A < min_angle_deg)).any(axis=1)
    counts = (smallest < min_angle_deg) & ~forced
    spread = (face_double_areas(S.X, T) / mean_area - 1) ** 2
    return np.where(counts, smallest, np.inf), \
        np.column_stack([turned_over_rows(S, T), -smallest, spread])


def skinny_faces(X: np.ndarray, F: np.ndarray, min_angle_deg: float) -> np.ndarray:
    """The faces (indices) with a 3D angle below ``min_angle_deg`` (the angles of
    :func:`..metrics.corner_angles`; of the faces near it alone,
    :func:`..metrics.min_corner_angles_below`)."""
    limit = np.radians(min_angle_deg)
    faces, smallest = min_corner_angles_below(X, F, limit)
    return faces[smallest < limit]


@dataclass
class TrialBudget:
    """The work left to a loop of trials made one at a time, each judged on the whole remesh
    (:data:`TRIAL_WORK`): a trial started with ``k`` faces below the minimum angle costs
    ``1 + k``; one starts while any work is left, so the last may overspend."""

    left: float

    @classmethod
    def for_remesh(cls, S: RemeshState) -> "TrialBudget":
        """``TRIAL_WORK`` × the vertex count of ``S``."""
        return cls(TRIAL_WORK * S.n)

    def spend(self, S: RemeshState, faces: int) -> bool:
        """Whether a trial at ``faces`` faces below the minimum may start; if so its cost is
        charged, and where none may, the refusal is tallied in ``S.log`` under
        ``trials_cut`` (the loops it ends)."""
        if self.left <= 0:
            S.tally("trials_cut", 1)
            return False
        self.left -= 1 + int(faces)
        return True


def each_unforced_face(S: RemeshState, min_angle_deg: float, limit: int,
                       outside_holes: bool = False):
    """Yield the faces below ``min_angle_deg`` that no input corner forces
    (:func:`.circumcentres.unforced_below`), measured again after each, with
    ``outside_holes`` none in a hole the cut will remove (where every hole loop is whole,
    :func:`.holes.all_loops_whole`: the faces whose disk centroid is in a hole's fan,
    :func:`.holes.in_fans`; the work on them is lost with them): the worst one not yielded
    before (known by its corners' positions, :func:`corner_key`), with the shortfall
    measured (:func:`.circumcentres.shortfall_of`), at most ``limit`` of them and none once
    they have spent their :class:`TrialBudget` (each costing the faces below when it is
    yielded); the caller may change ``S`` in between.

    Yields
    ------
    f : int
    shortfall : (int, float)
    """
    tried, budget, cut = set(), TrialBudget.for_remesh(S), \
        outside_holes and all_loops_whole(S)
    for _ in range(limit):
        bad, worst = unforced_below(S, min_angle_deg)
        outside = bad[~in_fans(S, bad)] if cut and len(bad) else bad
        f = next((f for f in outside if corner_key(S.X[S.F[f]]) not in tried), None)
        if f is None or not budget.spend(S, len(bad)):
            return
        tried.add(corner_key(S.X[S.F[f]]))
        yield int(f), shortfall_of(worst)


def star_order(angles: np.ndarray, min_angle_deg: float) -> tuple[int, float]:
    """The order of a star's faces with smallest angles ``angles`` (d, degrees) in
    :meth:`_Operations.move_each`: fewer of them below ``min_angle_deg`` first, then the larger
    smallest angle (as :func:`.circumcentres.shortfall_order` orders a remesh)."""
    return shortfall_order((int(np.count_nonzero(angles < min_angle_deg)),
                            float(angles.min())))


def star_best(angles: np.ndarray, min_angle_deg: float) -> int | None:
    """The row of ``angles`` (j×d, degrees: a star's faces' smallest angles with its vertex at
    each of j points) first in :func:`star_order`; None when j is 0."""
    if len(angles) == 0:
        return None
    return int(np.lexsort((-angles.min(axis=1),
                           np.count_nonzero(angles < min_angle_deg, axis=1)))[0])


def star_candidates(S: RemeshState, v: int, min_angle_deg: float):
    """The positions of vertex ``v`` in its star (:func:`.unfold.star_positions`) and which of
    them turn no face of the star over and leave no face at a sharp input corner
    (:func:`.angles.sharp_vertices`) smaller than it was and ``min_angle_deg``; None where
    there is no position.

    Returns
    -------
    star : (d, 3) int
    where : tuple
        :func:`.unfold.star_positions`' ``(uv, face, bary, X)`` of j positions.
    angles : (j, d) float
        The star's faces' smallest angles (degrees) at each position.
    ok : (j,) bool
    now : (d,) float
        The star's faces' smallest angles as they are.
    """
    star = vertex_star(S.F, v)
    found = star_positions(S, v, star)
    if found is None:
        return None
    where, n_turned, angles = found
    now = np.degrees(min_corner_angles(S.X, star))
    at_sharp = sharp_among(S, min_angle_deg, star).any(axis=1)
    ok = (n_turned == 0) & \
        (angles[:, at_sharp] >= np.minimum(now[at_sharp], min_angle_deg)).all(axis=1)
    return star, where, angles, ok, now


def free_corners(S: RemeshState, f: int) -> np.ndarray:
    """The corners of face ``f`` that the operations may move (:func:`free_of`), in its
    order; (j,) int."""
    return free_of(S, S.F[f])


def free_of(S: RemeshState, v: np.ndarray) -> np.ndarray:
    """The vertices ``v`` (k int) that the operations may move: neither on the rim nor
    locked, in their order; (j,) int."""
    return v[~S.is_rim[v] & ~S.locked[v]]


def across_unjoined(S: RemeshState, f: int) -> np.ndarray:
    """The free vertices (:func:`free_of`) across the edges of face ``f`` that are not
    kept (``S.joined``) and have a face on the other side, in the order of ``f``'s edges;
    (j,) int. A face with three locked corners (a tooth of a ragged hole loop, its chord the
    one edge not kept) changes only by a flip of that edge, which gives the vertex across it
    the tooth's tip (:meth:`_Operations.flip_and_move`)."""
    F, twin = S.F, S.twins()
    h = 3 * f + np.arange(3)
    kept = S.is_joined(F[f], F[f, [1, 2, 0]])
    g = twin[h][~kept & (twin[h] >= 0)]
    return free_of(S, F[g // 3, (g % 3 + 2) % 3])


def link_edges(S: RemeshState, v: int) -> np.ndarray:
    """The interior half-edges of the link of vertex ``v`` (the edges of its star's faces
    opposite it that another face shares), each in its face of the star."""
    faces = faces_at_vertex(S.F, v)
    slot = np.argmax(S.F[faces] == v, axis=1)
    h = 3 * faces + (slot + 1) % 3
    return h[S.twins()[h] >= 0]


def link_flip(S: RemeshState, h: int) -> bool:
    """Flip the interior half-edge ``h`` (``a → b`` in face ``a, b, p``; ``b, a, q`` across):
    the faces become ``p, a, q`` and ``q, b, p``, where both are counter-clockwise and not
    thinner than ``DISK_SHAPE_MIN`` on the domain (:func:`.halfedge.disk_shape`), neither has
    three rim corners, ``p`` and ``q`` are not joined already and the edge is no kept feature
    edge. Returns whether it was flipped."""
    F, twin = S.F, S.twins()
    g = int(twin[h])
    f, c, d = h // 3, h % 3, g % 3
    a, b, p = int(F[f, c]), int(F[f, (c + 1) % 3]), int(F[f, (c + 2) % 3])
    q = int(F[g // 3, (d + 2) % 3])
    if S.is_joined(np.array([a]), np.array([b]))[0] or sharing_edge(F, p, q):
        return False
    new = np.array([[p, a, q], [q, b, p]])
    if (S.is_rim[new].all(axis=1)).any() or (disk_shape(S.uv, new) < DISK_SHAPE_MIN).any():
        return False
    F, twin = F.copy(), twin.copy()
    flip_in_place(F, twin, np.array([h]), tuple(np.array([x]) for x in (a, b, p, q)))
    S.set_faces(F, twin)
    return True


def sharing_edge(F: np.ndarray, p: int, q: int) -> bool:
    """Whether a face of ``F`` (m×3) has ``q`` next to ``p`` (either way round): whether
    ``p`` and ``q`` are joined by an edge. Only the faces at ``p`` are read."""
    T = F[np.flatnonzero(F.ravel() == p) // 3]
    return bool(((T == p) & ((np.roll(T, 1, axis=1) == q) | (np.roll(T, -1, axis=1) == q))).any())


def vertex_star(F: np.ndarray, v: int) -> np.ndarray:
    """The faces of ``F`` (m×3) at vertex ``v``, each rotated so that ``v`` comes first
    (d×3, in the order of ``F``)."""
    T = F[faces_at_vertex(F, v)]
    first = np.argmax(T == v, axis=1)
    return np.stack([T[np.arange(len(T)), (first + i) % 3] for i in range(3)], axis=1)


def faces_at_vertex(F: np.ndarray, v: int) -> np.ndarray:
    """The faces of ``F`` (m×3) with ``v`` among their corners (indices, in order):
    ``np.flatnonzero((F == v).any(axis=1))`` in one compiled pass (:func:`.halfedge.touching`).
    """
    mark = np.zeros(max(int(F.max(initial=-1)), int(v)) + 1, bool)
    mark[v] = True
    return np.flatnonzero(touching(F, mark))


def corner_key(P: np.ndarray) -> bytes:
    """A face's key by its corners' positions ``P`` (3×3), whatever their order: their rows'
    bytes, sorted and joined."""
    return b"".join(sorted(p.tobytes() for p in P))


def _corners_changed_since(S: RemeshState, F_before: np.ndarray) -> np.ndarray:
    """The corners (n bool) of the faces rewritten or added since ``F_before`` (m₀×3) by
    splits and flips (both rewrite faces in place and only append new ones)."""
    changed = np.r_[np.flatnonzero((S.F[:len(F_before)] != F_before).any(axis=1)),
                    np.arange(len(F_before), len(S.F))]
    corners = np.zeros(S.n, bool)
    corners[S.F[changed].ravel()] = True
    return corners


def _ring(F: np.ndarray, mark: np.ndarray) -> np.ndarray:
    """The marked vertices (n bool) and the corners of every face at one of them."""
    out = mark.copy()
    out[F[touching(F, mark)].ravel()] = True
    return out
