"""What the single-solve and robot-validate speed-ups (issue 19, part 5) must not change.

Speed itself is measured in ``benchmarks/`` (no timed tests). These tests pin that the
faster paths give the same answers: a URDF read without running trimesh's ``__init__``
gives the same model as with the whole package, and trimesh stays whole afterwards.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import PROBLEMS

ROOT = Path(__file__).resolve().parent.parent
URDFS = sorted((PROBLEMS / "robots").glob("*.urdf")) + sorted((ROOT / "tests" / "bad_problems" / "robots").glob("*.urdf"))


def _fresh(code: str) -> str:
    """Run ``code`` in a fresh interpreter with this checkout's sources; return its stdout
    (a fresh process: whether a module gets imported is the point)."""
    environ = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH")]))}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=environ, cwd=ROOT)
    assert run.returncode == 0, run.stderr
    return run.stdout


_READ_ALL = (
    "from pathlib import Path\n"
    "from counterpoise.errors import InputError\n"
    "from counterpoise.io.robot import read_robot\n"
    "for f in {files!r}:\n"
    "    try:\n"
    "        print(repr(read_robot(Path(f), 'urdf')))\n"
    "    except InputError as exc:\n"
    "        print('error:', exc)\n"
)


def test_urdf_is_read_without_trimesh_and_reads_the_same():
    """Every URDF of the problems and of the bad-problem files (their error messages too)
    reads to the same model whether yourdfpy was imported with trimesh's stand-in or after
    the whole of trimesh; the stand-in imports neither trimesh's ``__init__`` nor scipy nor
    networkx, and ``import trimesh`` afterwards gives the whole package, which yourdfpy
    then uses too."""
    pytest.importorskip("yourdfpy")
    files = [str(f) for f in URDFS]
    assert any("ur5" in f for f in files)
    read = _READ_ALL.format(files=files)
    light = _fresh(
        "import sys\n" + read + "print('heavy', sorted(m for m in ('trimesh', 'scipy', 'networkx', 'rtree', 'shapely') if m in sys.modules))\n"
        "import trimesh, yourdfpy\n"
        "print('whole', hasattr(trimesh, 'Trimesh') and yourdfpy.urdf.trimesh.Scene is trimesh.Scene and yourdfpy.urdf.tra is trimesh.transformations)\n"
    ).splitlines()
    whole = _fresh("import trimesh\n" + read).splitlines()
    assert light[: len(whole)] == whole
    assert light[len(whole) :] == ["heavy []", "whole True"]
