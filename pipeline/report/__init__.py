"""Presentation of the stages' results: figures, ``report.html`` pages and the run index.

* :mod:`.figure` — the figure toolkit (Agg backend, one camera, one shading, atomic PNG save);
* :mod:`.html` — the HTML page writer (shared head, stylesheet, tables, figures, links);
* :mod:`.parameterize`, :mod:`.remesh`, :mod:`.register`, :mod:`.morph` — one builder per
  stage report; :mod:`.index` — ``<run>/index.html`` linking every stage.

Layering: this package imports from :mod:`pipeline.geometry` and :mod:`pipeline.io` only, never
from :mod:`pipeline.stages`, the runner or the CLI; the stages pass plain arrays, dicts and
the small dataclasses defined here.
"""
