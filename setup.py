"""Compiled inner loops, built by ``pip install`` (everything else is in pyproject.toml).

Only loops whose numpy form is dominated by per-call overhead are compiled; their arithmetic is
the numpy formulas' operation for operation, and ``-ffp-contract=off`` keeps it bit for bit (no
fused multiply-adds; ``-O3``, like ``-O2``, reorders no floating-point arithmetic, and its inlining
and unrolling make the loops faster). The OBJ reader's one pass over a file's bytes is compiled
too."""

from setuptools import Extension, setup

setup(ext_modules=[
    Extension("pipeline.geometry._kernels", ["pipeline/geometry/_kernels.pyx"],
              extra_compile_args=["-O3", "-ffp-contract=off"]),
    Extension("pipeline.io._obj", ["pipeline/io/_obj.pyx"], extra_compile_args=["-O2"]),
])
