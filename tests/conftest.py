"""Shared test helpers.

``require_data(*parts)`` locates the third-party test meshes (never copied into the repo):
``$SEM_DATA`` or ``<repo>/../shared/data``. Missing data skips the test locally and fails it on
CI (``CI=true``). Import it with ``from conftest import require_data`` (``tests`` must be on the
python path: ``pythonpath = [".", "tests"]`` in the pytest config).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DATA_DIR = Path(
    os.environ.get("SEM_DATA", Path(__file__).resolve().parents[1].parent / "shared" / "data")
)


def require_data(*parts) -> Path:
    """Path of ``DATA_DIR / parts``; skip (fail on CI) when it does not exist."""
    path = DATA_DIR.joinpath(*parts)
    if not path.exists():
        msg = f"shared data not found at {path}; set SEM_DATA"
        if os.environ.get("CI") == "true":
            pytest.fail(msg)
        pytest.skip(msg)
    return path


def run_cli(*args, cwd=None):
    """Run ``python -m pipeline`` in a subprocess (what a user sees: stdout, stderr, code)."""
    proc = subprocess.run([sys.executable, "-m", "pipeline", *map(str, args)], cwd=cwd or REPO,
                          capture_output=True, text=True, timeout=600,
                          env=dict(os.environ, PYTHONPATH=str(REPO)))
    return proc.returncode, proc.stdout, proc.stderr
