"""Directly attached catalogue slots: which slots interact (groups), independent groups
searched one by one, a coupled group too large to enumerate screened slot by slot, and a
search that can neither enumerate nor screen refused as an input limit (exit 2)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from counterpoise import load_problem
from counterpoise.cli import main
from counterpoise.designer.minimax import MinimaxDesigner
from counterpoise.errors import ProblemFileError
from counterpoise.selection import direct
from counterpoise.selection.direct import _enumerate, part_parameters, search_direct
from counterpoise.selection.groups import direct_groups
from conftest import ROOT, solved

LAMP = ROOT / "problems" / "lamp_direct.toml"
SHIPPED = ROOT / "src" / "counterpoise" / "data" / "extension_springs.csv"
QUIET = lambda done, total: None  # noqa: E731 - no progress line

HEAD = """
[problem]
name = "{name}"

[gravity]
acceleration = "9.81 m/s^2"
direction = [0, -1, 0]

[parameters]
l_1 = "0.3 m"
m_1 = "0.3 kg"
m_2 = "0.3 kg"

[catalogues.parts]
file = "{catalogue}"
[slots.s_1]
catalogue = "parts"
[slots.s_2]
catalogue = "parts"
"""

VARIABLES = """
[variables.{v}]
lower = "{lo} mm"
upper = "{hi} mm"
initial = "{x0} mm"
"""


def variables(*names: str) -> str:
    """Anchor heights y_* in [30, 300] mm, levers b_* in [20, 150] mm, cables c_* in [0, 300] mm."""
    boxes = {"y": (30, 300, 120), "b": (20, 150, 60), "c": (0, 300, 20)}
    return "".join(VARIABLES.format(v=n, lo=boxes[n[0]][0], hi=boxes[n[0]][1], x0=boxes[n[0]][2]) for n in names)


def spring(name: str, slot: str, anchor: str, frame: str, lever: str, cable: str) -> str:
    return (
        f'\n[springs.{name}]\nslot = "{slot}"\nmount = "direct"\ncable = "{cable}"\n'
        f'from = {{ frame = "ground", point = [0, "{anchor}", 0] }}\nto = {{ frame = "{frame}", point = ["{lever}", 0, 0] }}\n'
    )


#: two 1R arms that move independently (two subsystems)
TWO_ARMS = """
[subsystems.left]
coordinates.theta_1 = { range = ["20 deg", "90 deg"] }
[subsystems.right]
coordinates.theta_2 = { range = ["20 deg", "90 deg"] }
[frames.a]
transforms = [{ rotate = "z", angle = "theta_1" }]
[frames.b]
transforms = [{ rotate = "z", angle = "theta_2" }]
[bodies.a]
frame = "a"
mass = "m_1"
com = ["l_1/2", 0, 0]
[bodies.b]
frame = "b"
mass = "m_2"
com = ["l_1/2", 0, 0]
"""

#: a 2R arm with a relative elbow angle: the upper link's gravity acts on both joints
SERIAL = """
[subsystems.arm]
coordinates.theta_1 = { range = ["30 deg", "90 deg"] }
coordinates.theta_2 = { range = ["-30 deg", "0 deg"] }
[frames.a]
transforms = [{ rotate = "z", angle = "theta_1" }]
[frames.b]
parent = "a"
transforms = [{ translate = ["l_1", 0, 0] }, { rotate = "z", angle = "theta_2" }]
[bodies.a]
frame = "a"
mass = "m_1"
com = ["l_1/2", 0, 0]
[bodies.b]
frame = "b"
mass = "m_2"
com = ["0.15 m", 0, 0]
"""


def write(tmp_path: Path, name: str, body: str, catalogue: str = "shipped", extra: str = "") -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(HEAD.format(name=name, catalogue=catalogue) + body + extra, encoding="utf-8")
    return path


def small_catalogue(tmp_path: Path, parts: list[str]) -> str:
    """These rows of the shipped catalogue, as a catalogue file of their own."""
    with open(SHIPPED, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        rows = [r for r in reader if r["part_number"] in parts]
        fields = reader.fieldnames
    with open(tmp_path / "parts.csv", "w", newline="", encoding="utf-8") as fh:
        out = csv.DictWriter(fh, fieldnames=fields)
        out.writeheader()
        out.writerows(rows)
    return "parts.csv"


def groups_of(path: Path) -> list:
    problem = load_problem(path)
    designer = MinimaxDesigner(problem)
    return direct_groups(problem, designer, lambda rows: part_parameters(problem, rows), problem.settings.seed)


# -- which slots interact ---------------------------------------------------------------


def test_slots_in_different_subsystems_are_independent(tmp_path):
    """Each arm's residual (its own coordinate) involves its own spring only."""
    body = TWO_ARMS + variables("y_1", "b_1", "c_1", "y_2", "b_2", "c_2") + spring("one", "s_1", "y_1", "a", "b_1", "c_1") + spring("two", "s_2", "y_2", "b", "b_2", "c_2")
    groups = {g.slots: g for g in groups_of(write(tmp_path, "two_arms", body))}
    assert set(groups) == {("s_1",), ("s_2",)}
    assert groups[("s_1",)].coordinates == {"theta_1"} and groups[("s_1",)].springs == {"one"}
    assert groups[("s_2",)].variables == {"y_2", "b_2", "c_2"}


def test_a_shared_variable_joins_slots_of_different_subsystems(tmp_path):
    """Both anchors at the same height y_1: choosing one part moves the other's optimum."""
    body = TWO_ARMS + variables("y_1", "b_1", "c_1", "b_2", "c_2") + spring("one", "s_1", "y_1", "a", "b_1", "c_1") + spring("two", "s_2", "y_1", "b", "b_2", "c_2")
    (group,) = groups_of(write(tmp_path, "shared", body))
    assert set(group.slots) == {"s_1", "s_2"} and group.coordinates == {"theta_1", "theta_2"}


def test_a_reference_link_decouples_the_joints_of_one_subsystem():
    """The lamp: one subsystem, two joints; the upper spring runs from the parallelogram's
    reference link (the base's axes) so its length depends on theta_2 alone, although
    its anchor's position is written through theta_1's frame."""
    groups = {g.slots: g for g in groups_of(LAMP)}
    assert set(groups) == {("shoulder_spring",), ("elbow_spring",)}
    assert groups[("shoulder_spring",)].coordinates == {"theta_1"}
    assert groups[("elbow_spring",)].coordinates == {"theta_2"}
    assert groups[("elbow_spring",)].springs == {"elbow"}


def test_a_turntable_row_that_vanishes_joins_nothing(tmp_path):
    """The lamp on a base that turns about the vertical (psi): gravity and both springs turn
    with it, so psi's residual vanishes (rounding only) and must join neither slot."""
    text = LAMP.read_text(encoding="utf-8")
    for old, new in [
        ('coordinates.theta_1 =', 'coordinates.psi = { range = ["-90 deg", "90 deg"] }\ncoordinates.theta_1 ='),
        ("[frames.lower]\n", '[frames.turntable]\ntransforms = [{ rotate = "y", angle = "psi" }]\n\n[frames.lower]\nparent = "turntable"\n'),
        ('orientation = "ground"', 'orientation = "turntable"'),
        ('from = { frame = "ground", point = ["x_1"', 'from = { frame = "turntable", point = ["x_1"'),
    ]:
        assert old in text
        text = text.replace(old, new, 1)
    path = tmp_path / "turntable.toml"
    path.write_text(text, encoding="utf-8")
    groups = {g.slots: g.coordinates for g in groups_of(path)}
    assert groups == {("shoulder_spring",): {"theta_1"}, ("elbow_spring",): {"theta_2"}}


def test_a_spring_spanning_both_joints_couples_them(tmp_path):
    """Spring two runs from the ground to the upper link: its length depends on both joint
    angles, so it enters the shoulder's row, as spring one does."""
    body = SERIAL + variables("y_1", "b_1", "c_1", "y_2", "b_2", "c_2") + spring("one", "s_1", "y_1", "a", "b_1", "c_1") + spring("two", "s_2", "y_2", "b", "b_2", "c_2")
    (group,) = groups_of(write(tmp_path, "serial", body))
    assert set(group.slots) == {"s_1", "s_2"}


# -- searches ---------------------------------------------------------------------------


def test_independent_groups_find_the_best_combination_with_fewer_designs(tmp_path):
    """Two arms, three parts each: the groups' searches (3 + 3 designs) find a combination
    whose worst ratio is that of designing all 9 combinations with the whole designer (the
    worst ratio is the larger of the arms', each minimised by its own part)."""
    catalogue = small_catalogue(tmp_path, ["CP-EXT-0025", "CP-EXT-0125", "CP-EXT-0318"])
    body = TWO_ARMS + variables("y_1", "b_1", "c_1", "y_2", "b_2", "c_2") + spring("one", "s_1", "y_1", "a", "b_1", "c_1") + spring("two", "s_2", "y_2", "b", "b_2", "c_2")
    problem = load_problem(write(tmp_path, "two_arms", body, catalogue))
    designer = MinimaxDesigner(problem)
    result = search_direct(problem, designer, QUIET)
    brute = _enumerate(problem, designer, QUIET, 0.0, "test")
    assert len(result.groups) == 2 and result.solves == 6 and brute.solves == 9
    assert result.choice is not None and brute.choice is not None
    assert result.choice.robust == pytest.approx(brute.choice.robust, rel=1e-3)
    assert "searched one by one" in result.text()


def test_rows_no_part_can_change_are_left_out_of_the_search(tmp_path):
    """Two coupled slots (a shared anchor height) and a third, heavier arm with no spring:
    its residual, the same for every part, would be the worst ratio of every combination
    (1: it sets the reference torque) and tie them all. The group's search leaves its row
    out: the combinations' ratios are those of the sprung arms, below 1, and differ."""
    catalogue = small_catalogue(tmp_path, ["CP-EXT-0125", "CP-EXT-0318"])
    idle = '[subsystems.idle]\ncoordinates.theta_3 = { range = ["0 deg", "60 deg"] }\n[frames.c]\ntransforms = [{ rotate = "z", angle = "theta_3" }]\n[bodies.c]\nframe = "c"\nmass = "3 kg"\ncom = ["l_1", 0, 0]\n'
    body = TWO_ARMS + idle + variables("y_1", "b_1", "c_1", "b_2", "c_2") + spring("one", "s_1", "y_1", "a", "b_1", "c_1") + spring("two", "s_2", "y_1", "b", "b_2", "c_2")
    problem = load_problem(write(tmp_path, "idle", body, catalogue))
    (group,) = direct_groups(problem, MinimaxDesigner(problem), lambda rows: part_parameters(problem, rows), 3)
    assert group.coordinates == {"theta_1", "theta_2"}
    result = search_direct(problem, MinimaxDesigner(problem), QUIET)
    ratios = [c.robust for c in result.candidates]
    assert ratios and max(ratios) < 0.99 and len(set(ratios)) > 1


def test_coupled_group_too_large_is_screened_slot_by_slot(tmp_path, monkeypatch):
    """Coupled slots whose combinations exceed the enumeration limit (lowered here to 10,
    below the 4 × 4 = 16 combinations): each slot is screened, then only the combinations of
    each slot's best screened parts (2 × 2 = 4 with a budget of 4) are designed."""
    monkeypatch.setattr(direct, "MAX_COMBINATIONS", 10)
    monkeypatch.setattr(direct, "COUPLED_COMBINATIONS", 4)
    catalogue = small_catalogue(tmp_path, ["CP-EXT-0025", "CP-EXT-0100", "CP-EXT-0125", "CP-EXT-0318"])
    body = SERIAL + variables("y_1", "b_1", "c_1", "y_2", "b_2", "c_2") + spring("one", "s_1", "y_1", "a", "b_1", "c_1") + spring("two", "s_2", "y_2", "b", "b_2", "c_2")
    problem = load_problem(write(tmp_path, "serial", body, catalogue))
    result = search_direct(problem, MinimaxDesigner(problem), QUIET)
    assert result.methods == ["screened combinations"] and result.solves == 4
    assert result.choice is not None and math.isfinite(result.choice.robust)
    assert result.choice.robust == min(c.robust for c in result.candidates)
    assert "screening of slot s_1" in result.text() and "screening of slot s_2" in result.text()


def test_a_search_that_can_neither_enumerate_nor_screen_is_an_input_limit(tmp_path, capsys):
    """Coupled slots over the shipped catalogue (572 × 572 = 327184 combinations), spring
    one's cable an expression (the screening needs a cable variable of its own): exit 2,
    one line naming the file and the slot's catalogue key and saying what to change;
    nothing written; never 'infeasible'."""
    body = SERIAL + variables("y_1", "b_1", "c_1", "y_2", "b_2", "c_2") + spring("one", "s_1", "y_1", "a", "b_1", "c_1 + 5 mm") + spring("two", "s_2", "y_2", "b", "b_2", "c_2")
    path = write(tmp_path, "refused", body)
    with pytest.raises(ProblemFileError) as info:
        search_direct(load_problem(path), MinimaxDesigner(load_problem(path)), QUIET)
    assert info.value.key == "slots.s_1.catalogue"
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exited:
        main(["solve", str(path), "--out", str(out)])
    assert exited.value.code == 2
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"{path}: slots.s_1.catalogue: 327184 combinations")
    assert "cannot be screened" in lines[0] and "use a smaller catalogue" in lines[0] and "infeasible" not in lines[0]
    assert not (out / "refused").exists()


def test_a_slot_over_several_scenarios_is_screened(tmp_path):
    """One arm, its link's mass in two scenarios (a payload range): every part is screened
    on both scenarios' configurations at once (not designed one by one); the design found
    keeps its spring within its lengths in both."""
    catalogue = small_catalogue(tmp_path, [f"CP-EXT-{i:04d}" for i in (25, 100, 125, 200, 318, 343, 363, 400)])
    extra = '[scenarios.light]\nparameters = { m_1 = "0.2 kg" }\n[scenarios.heavy]\nparameters = { m_1 = "0.4 kg" }\n'
    body = TWO_ARMS.split("[subsystems.right]")[0] + '[frames.a]\ntransforms = [{ rotate = "z", angle = "theta_1" }]\n[bodies.a]\nframe = "a"\nmass = "m_1"\ncom = ["l_1/2", 0, 0]\n'
    text = (HEAD.format(name="payload", catalogue=catalogue).split("[slots.s_2]")[0] + body + variables("y_1", "b_1", "c_1") + spring("one", "s_1", "y_1", "a", "b_1", "c_1") + extra)
    path = tmp_path / "payload.toml"
    path.write_text(text, encoding="utf-8")
    problem = load_problem(path)
    result = search_direct(problem, MinimaxDesigner(problem), QUIET)
    assert result.methods == ["screening"], result.text()
    assert result.choice is not None and result.solves <= len(problem.slots[0].catalogue)


def test_a_groups_part_bounds_are_below_every_design_of_it(tmp_path):
    """The lamp's elbow group (its rows: theta_2 alone, the shoulder spring left out): the
    certified per-part lower bound on the group's rows is at most the worst ratio of every
    design of that part by the group's own designer (brute force over a few parts)."""
    from counterpoise.selection.bounds import certifiable, part_bounds
    from counterpoise.selection.screening import screen

    catalogue = small_catalogue(tmp_path, [f"CP-EXT-{i:04d}" for i in (300, 318, 330, 343, 350, 363)])
    text = LAMP.read_text(encoding="utf-8").replace('file = "shipped"', f'file = "{catalogue}"')
    (tmp_path / "lamp.toml").write_text(text, encoding="utf-8")
    problem = load_problem(tmp_path / "lamp.toml")
    designer = MinimaxDesigner(problem)
    group = next(g for g in direct_groups(problem, designer, lambda rows: part_parameters(problem, rows), 3) if g.slots == ("elbow_spring",))
    restricted = designer.restricted(group.coordinates, group.springs)
    slot = next(s for s in problem.slots if s.name == "elbow_spring")
    brute = _enumerate(problem, restricted, QUIET, 0.0, "test", [slot])
    ratio = {c.parts["elbow_spring"]: c.robust for c in brute.candidates}
    assert ratio, "no part fits: the test checks nothing"
    screened = screen(problem, restricted, part_parameters(problem, {"elbow_spring": 0}), "elbow_spring", group.coordinates, frozenset({"shoulder"}), group.variables)
    assert screened.supported and certifiable(screened.context) == ""
    bounds = part_bounds(screened.context, restricted, 1.0, math.inf, max_depth=2)
    for row, value in ratio.items():
        assert bounds.value[row] <= value


# -- the lamp (acceptance) ----------------------------------------------------------------


@pytest.fixture(scope="module")
def lamp_run(tmp_path_factory):
    """(exit status of ``counterpoise solve``, its report folder) for problems/lamp_direct.toml:
    the reports written from the design the test run shares (``conftest.solved``: the
    shipped file is not designed again here), the exit status the one the solve gives it."""
    from counterpoise.report.files import write_reports

    result = solved("lamp_direct")
    return (0 if result.optimal else 1), write_reports(result, tmp_path_factory.mktemp("lamp"))


def test_lamp_with_two_direct_slots_is_searched_and_verified(lamp_run):
    """Two direct slots on independent joints over the shipped catalogue: a design, verified
    densely, every spring within its part's limits; the two slots searched separately."""
    code, folder = lamp_run
    assert code == 0
    status = (folder / "status.txt").read_text(encoding="utf-8")
    assert "status: optimal" in status
    assert "2 groups of directly attached slots that do not interact" in status
    with open(folder / "springs.csv", newline="", encoding="utf-8") as fh:
        springs = [r for r in csv.DictReader(fh) if r["kind"] == "spring"]
    assert {r["slot"] for r in springs} == {"shoulder_spring", "elbow_spring"}
    for r in springs:
        for margin in ("margin_slack_mm", "margin_length_mm", "margin_load_N"):
            assert float(r[margin]) >= 0, (r["spring"], margin)
    with open(folder / "summary.csv", newline="", encoding="utf-8") as fh:
        (summary,) = list(csv.DictReader(fh))
    # a real spring cannot balance exactly; the gravity torque is 2.4 N m at most (the
    # problem file's hand figures): a worst residual below 10 % of it is a working lamp
    assert 0 < float(summary["residual_ratio"]) < 0.1


def test_minimax_designer_builds_without_design_variables(tmp_path):
    """A payload range's adjustment problem with nothing adjustable has no design variable:
    the minimax designer's length rows were scaled by the largest bound of none (a
    ValueError after the part search of a lamp with a payload range)."""
    text = (
        '[problem]\nname = "fixed"\n[gravity]\nacceleration = "9.81 m/s^2"\ndirection = [0, -1, 0]\n'
        '[subsystems.arm]\ncoordinates.phi = { range = ["0 deg", "60 deg"] }\n'
        '[frames.link]\ntransforms = [{ rotate = "z", angle = "phi" }]\n'
        '[bodies.link]\nframe = "link"\nmass = "0.5 kg"\ncom = ["0.2 m", 0, 0]\n'
        '[springs.s]\nstiffness = "300 N/m"\nmount = "direct"\nfree_length = "20 mm"\ncable = "10 mm"\n'
        'from = { frame = "ground", point = [0, "0.1 m", 0] }\nto = { frame = "link", point = ["0.05 m", 0, 0] }\n'
    )
    path = tmp_path / "fixed.toml"
    path.write_text(text, encoding="utf-8")
    designer = MinimaxDesigner(load_problem(path))
    assert designer.n_rows > 0
