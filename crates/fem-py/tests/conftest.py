"""Shared fixtures: the ``fem2d`` command line the results are compared with."""

import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="session")
def fem2d():
    """A function running ``fem2d ARGS...``; the completed process.

    The binary is ``$FEM2D_BIN`` when set, else the workspace's release build (built here when
    missing; ``cargo xtask python`` builds the package in release, so both share the crates).
    """
    binary = os.environ.get("FEM2D_BIN")
    if not binary:
        cargo = os.environ.get("CARGO", "cargo")
        subprocess.run(
            [cargo, "build", "--release", "-q", "-p", "fem2d"], cwd=ROOT, check=True
        )
        meta = subprocess.run(
            [cargo, "metadata", "--format-version", "1", "--no-deps"],
            cwd=ROOT,
            check=True,
            capture_output=True,
            text=True,
        )
        target = Path(json.loads(meta.stdout)["target_directory"])
        binary = str(target / "release" / "fem2d")

    def run(*args, check=True):
        return subprocess.run(
            [binary, *args], capture_output=True, text=True, check=check, cwd=ROOT
        )

    return run
