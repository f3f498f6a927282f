"""The fault campaign of issue 13: signals, absurd input, deep chains, overflow (each reproduced)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import PROBLEMS, ROOT

#: how long the signal tests wait for a study's pool workers to start (a loaded machine is slow)
START_WAIT_S = 120


def _children(pid: int) -> list[int]:
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.append(int(entry.name))
    return out


@pytest.mark.skipif(not Path("/proc").exists(), reason="reads /proc")
@pytest.mark.parametrize(("sig", "status", "word"), [(signal.SIGTERM, 143, "terminated"), (signal.SIGINT, 130, "interrupted")])
def test_a_signalled_study_stops_its_workers_and_says_how_to_resume(tmp_path, sig, status, word):
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    args = [sys.executable, "-c", "from counterpoise.cli import main; main()", "study", str(PROBLEMS / "yasir2019_hybrid.toml"),
            "--vary", "m_endo=400 g:1000 g:100000", "--jobs", "2", "--out", str(tmp_path), "--no-plot"]
    process = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + START_WAIT_S
        while len(workers := _children(process.pid)) < 2 and time.monotonic() < deadline and process.poll() is None:
            time.sleep(0.2)
        assert len(workers) == 2
        time.sleep(1.0)  # workers past their set-up
        process.send_signal(sig)
        _, err = process.communicate(timeout=START_WAIT_S)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == status
    last = err.strip().splitlines()[-1]
    assert word in last and "--resume" in last and "study.csv" in last
    assert "Traceback" not in err
    time.sleep(0.5)
    assert [p for p in workers if Path(f"/proc/{p}").exists() and "Z" not in (Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()[0])] == []
