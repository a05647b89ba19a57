"""The remesh's domain: the disk of a disk map or the unit sphere of a sphere map.

A remesh vertex is a *domain position* located in the input map and lifted by eq. (1). The
operations (:mod:`.flips`, :mod:`.relax`, :mod:`.refine`, :mod:`.collapse`, :mod:`.corners`)
are written once for both domains; they tell them apart by the positions' columns:

* **disk** — ``(n, 2)`` points of the plane; a face is valid when counter-clockwise there;
* **sphere** — ``(n, 3)`` unit vectors; a face is valid when ``det[p0, p1, p2] > 0``
  (counter-clockwise seen from outside). It is the disk's test with the plane's points read as
  ``(u, v, 1)`` (:func:`.halfedge.double_areas`; the compiled kernels do the same), and it
  holds in any local gnomonic chart, so a triangulation all of whose faces pass it is an
  embedding of a closed genus-0 mesh on the sphere, as the disk's is an embedding in the plane.

A new position (a split point, a relaxation step) is computed as on the disk and then put back
on the domain by :func:`project` (nothing on the disk; normalised onto the sphere). Point
location: :class:`..locate.PointLocator` on the disk, :class:`..locate_sphere.SphereLocator` on
the sphere (:func:`locator`); both lift by :func:`..locate.lift`.
"""

from __future__ import annotations

import numpy as np


def on_sphere(P: np.ndarray) -> bool:
    """Whether the domain positions ``P`` (n×2 or n×3) are on the sphere."""
    return P.shape[-1] == 3


def project(P: np.ndarray) -> np.ndarray:
    """Put positions computed in the domain's ambient space back on the domain: the same array
    on the disk, normalised to unit length on the sphere.

    Parameters
    ----------
    P : (k, 2) or (k, 3) float

    Returns
    -------
    (k, 2) or (k, 3) float
    """
    if not on_sphere(P):
        return P
    return P / np.maximum(np.linalg.norm(P, axis=-1, keepdims=True), 1e-300)


def locator(P: np.ndarray, F: np.ndarray, boundary: np.ndarray | None = None):
    """Point location in the triangulation ``(P, F)`` of the domain: a
    :class:`..locate.PointLocator` on the disk (``boundary``: the loop outside points are
    projected onto), a :class:`..locate_sphere.SphereLocator` on the sphere."""
    if on_sphere(P):
        from ..locate_sphere import SphereLocator
        return SphereLocator(P, F)
    from ..locate import PointLocator
    return PointLocator(P, F, boundary)


def locate_once(P: np.ndarray, F: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The face of the triangulation ``(P, F)`` of the domain holding each of ``points`` (k×2
    or k×3), for one large batch: on the disk each point walks from a face of its grid cell
    (:meth:`..locate.PointLocator.locate_from_cells`), on the sphere from a face at its
    nearest vertex (:meth:`..locate_sphere.SphereLocator.locate`).

    Returns
    -------
    (k,) int
    """
    loc = locator(P, F)
    if on_sphere(P):
        return loc.locate(points)[0]
    return loc.locate_from_cells(points)[0]
