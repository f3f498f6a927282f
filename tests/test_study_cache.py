"""Designer caches are keyed on the problem's content, never on its name or path (issue 13)."""

from __future__ import annotations

import dataclasses

import pytest

from conftest import PROBLEMS
from counterpoise.io.loader import load_problem
from counterpoise.model.digest import content_key
from counterpoise.studies.runners import StudyTask
from counterpoise.studies.spec import plan_study
from counterpoise.studies.study import read_rows, run_study

FILE = PROBLEMS / "yasir2019_counter_mass.toml"


def test_content_key_differs_for_a_set_value_and_matches_for_equal_content():
    a = load_problem(FILE, {"parameters.m_c": "400 g"})
    b = load_problem(FILE, {"parameters.m_c": "800 g"})
    again = load_problem(FILE, {"parameters.m_c": "400 g"})
    assert (a.name, a.path) == (b.name, b.path)
    assert content_key(a) != content_key(b)
    assert content_key(a) == content_key(again)
    assert StudyTask(a).key != StudyTask(b).key
    assert StudyTask(a).key == StudyTask(again).key
    edited = dataclasses.replace(a, settings=dataclasses.replace(a.settings, verify_samples=a.settings.verify_samples + 1))
    assert content_key(edited) != content_key(a)


def test_two_studies_of_one_file_with_different_set_values_on_one_cluster(tmp_path):
    distributed = pytest.importorskip("distributed")
    from counterpoise.studies.cluster import DaskRunner

    rows = {}
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        for grams in (400, 800):
            problem = load_problem(FILE, {"parameters.m_c": f"{grams} g"})
            plan = plan_study(problem, ["r_a=130 mm:140 mm:3"], "f")
            runner = DaskRunner(cluster.scheduler_address, 1)
            try:
                outcome = run_study(problem, plan, tmp_path / str(grams), runner, batch_size=3)
            finally:
                runner.close()
            rows[grams] = read_rows(outcome.folder / "study.csv")
    for grams, found in rows.items():
        assert [r["status"] for r in found] == ["optimal"] * 3
        # the tip mass is balanced by M_c (seed 001's design: M_c equals the tip mass)
        assert [float(r["M_c [g]"]) for r in found] == pytest.approx([grams] * 3, rel=1e-6)


@pytest.mark.parametrize("name, vary", [("yasir2019_hybrid_catalogue.toml", "m_endo=680 g:700 g:3"), ("woo2019_counterweight.toml", "m1=80 g:90 g:3")])
def test_a_slot_or_payload_problem_builds_its_method_once_per_worker(tmp_path, monkeypatch, name, vary):
    # issue 13 §3: slot problems build their relaxed designer (the part search's) once per worker;
    # issue 19 §4: so do payload problems their schedule's adjustment designer. Two designers
    # per worker: the slot problem's own and its search's; the payload problem's sampled one
    # and its adjustments' (the varied values are parameters: one content for all points)
    import counterpoise.pipeline as pipeline
    from counterpoise.designer.designer import Designer
    from counterpoise.studies.runners import SerialRunner, _WORKER

    builds = []
    original = pipeline.build_method

    def counting(problem, *args, **kwargs):
        builds.append(problem.name)
        return original(problem, *args, **kwargs)

    designers = []
    constructor = Designer.__init__

    def counting_designers(self, problem, *args, **kwargs):
        designers.append(problem.name)
        return constructor(self, problem, *args, **kwargs)

    monkeypatch.setattr(pipeline, "build_method", counting)
    monkeypatch.setattr(Designer, "__init__", counting_designers)
    monkeypatch.delattr(_WORKER, "methods", raising=False)  # a fresh worker
    problem = load_problem(PROBLEMS / name)
    plan = plan_study(problem, [vary], "f")
    outcome = run_study(problem, plan, tmp_path, SerialRunner(), batch_size=2)
    assert outcome.counts.get("optimal", 0) == 3
    assert builds == [problem.name]
    assert len(designers) == 2, designers


def _constructions(monkeypatch, problem, vary, folder):
    """How many of each solver-holding object a study of ``problem`` builds in a fresh worker
    (this process: SerialRunner), counted at their constructors."""
    from counterpoise.designer.designer import Designer
    from counterpoise.designer.minimax import MinimaxDesigner
    from counterpoise.selection.search import SearchModel
    from counterpoise.solvers.ipopt import IpoptBackend
    from counterpoise.studies.runners import SerialRunner, _WORKER

    counts = {cls.__name__: 0 for cls in (Designer, MinimaxDesigner, SearchModel, IpoptBackend)}
    for cls in (Designer, MinimaxDesigner, SearchModel, IpoptBackend):
        original = cls.__init__

        def counting(self, *args, _original=original, _name=cls.__name__, **kwargs):
            counts[_name] += 1
            return _original(self, *args, **kwargs)

        monkeypatch.setattr(cls, "__init__", counting)
    monkeypatch.delattr(_WORKER, "methods", raising=False)  # a fresh worker
    plan = plan_study(problem, [vary], "f")
    outcome = run_study(problem, plan, folder, SerialRunner(), batch_size=8)
    monkeypatch.undo()
    return outcome, counts


def test_a_slot_problem_builds_its_search_designer_once_in_a_20_point_study(tmp_path, monkeypatch):
    # issue 19 §4: the part search's designer (of the relaxed problem) is built once per
    # problem content and worker, not once per solve; the varied mass is a parameter, so
    # all 20 points share one problem content. Expected, per worker: 1 SearchModel; 2
    # Designers (the problem's own, for the solve with the chosen parts, and the relaxed
    # one of the search); no MinimaxDesigner (no directly attached spring); and the same
    # number of solver builds (IpoptBackend) for 20 points as for 2.
    problem = load_problem(PROBLEMS / "essomba2021_orientation_catalogue.toml")
    few, few_counts = _constructions(monkeypatch, problem, "m_A=190 g:200 g:2", tmp_path / "two")
    many, counts = _constructions(monkeypatch, problem, "m_A=190 g:200 g:20", tmp_path / "twenty")
    assert few.counts.get("optimal", 0) == 2
    assert many.counts.get("optimal", 0) == 20
    assert counts["SearchModel"] == 1
    assert counts["Designer"] == 2
    assert counts["MinimaxDesigner"] == 0
    assert counts == few_counts
