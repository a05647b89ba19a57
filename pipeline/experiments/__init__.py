"""Experiments at scale: one config → many single-run work items (a dataset × a parameter
sweep), each run once into its own atomic folder, skipped on a re-run while its content hash is
unchanged, on a local process pool or a Dask cluster, with a CSV + HTML summary.

* :mod:`.spec` — the experiment schema and its expansion into :class:`~.spec.Item` s;
* :mod:`.cache` — content hashes of inputs and configs, atomic item folders, ``item.json``;
* :mod:`.execute` — running the items (serial, process pool, Dask) with a progress bar;
* :mod:`.summary` — ``summary.csv`` and the sortable ``summary.html``.

Kept import-light (no numpy here): pool workers import it before they limit BLAS threads.
"""
