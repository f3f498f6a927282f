"""Design layers as extensions (issue 33): one registry (``counterpoise/registry.py``) that
building a design method, the verdict sources, the report files and the problem-file
checks loop over; a new layer is its package and one registry line."""

from __future__ import annotations

import ast
import subprocess
import sys
import textwrap

import pytest

from builders import pendulum
from conftest import PROBLEMS, ROOT
from counterpoise import registry
from counterpoise.designer.layers import BaseLayer, build_stack, layers
from counterpoise.designer.solution import VERDICT_SOURCES, Verdict, verdict_sources
from counterpoise.errors import ProblemFileError
from counterpoise.io.loader import load_problem
from counterpoise.solvers.base import Status


def test_the_registry_imports_nothing_so_any_layer_may_read_it():
    """registry.py is data: it imports no module of the package (io reads it, and it names
    the layers only by their module's dotted path)."""
    tree = ast.parse((ROOT / "src" / "counterpoise" / "registry.py").read_text(encoding="utf-8"))
    imported = [n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)] + [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    assert set(imported) <= {"__future__", "dataclasses"}


def test_every_registered_layer_answers_to_its_entry_and_gives_its_verdict_source():
    assert [layer.name for layer in layers()] == list(registry.names()) == ["payload", "robust", "parts", "realisation"]
    assert VERDICT_SOURCES == verdict_sources() == ("check", "constraints", "minimax", "payload", "robust", "parts", "realisation")


def test_reading_the_layers_imports_none_of_their_methods():
    """A layer module holds its hooks and result records; its design method, search or
    counterpart (cvxpy) is imported only when the layer wraps a problem: a report of a plain
    design, which asks every layer, pays for none of them."""
    code = (
        "import sys\n"
        "from counterpoise.designer.layers import layers\n"
        "layers()\n"
        "heavy = ['counterpoise.robust.method', 'counterpoise.selection.search', 'counterpoise.payload.schedule', 'counterpoise.realisation.method', 'cvxpy']\n"
        "print(sorted(m for m in heavy if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


class _Recording(BaseLayer):
    """A layer that accepts the problems named in ``names`` and records how it was nested."""

    def __init__(self, name: str, names: set[str]) -> None:
        self.name = name
        self.names = names

    def accepts(self, problem):
        return problem in self.names

    def wrap(self, problem, inner):
        return (self.name, inner(problem), inner)


def test_the_stack_nests_the_layers_innermost_first_and_each_inner_builds_the_layers_inside_it():
    """``build_stack`` wraps the core with every layer that accepts the problem, the first of
    the registry innermost (the realisation layer, last, is outermost); a layer's ``inner``
    builds the stack below it for another problem (a payload range's samples, a problem
    with added constraints)."""
    stack = [_Recording("payload", {"p"}), _Recording("robust", set()), _Recording("parts", {"p", "q"}), _Recording("realisation", {"p", "q"})]
    method = build_stack("p", lambda problem: ("core", problem), stack)
    names = []
    while isinstance(method, tuple) and len(method) == 3:
        names.append(method[0])
        method = method[1]
    assert names == ["realisation", "parts", "payload"] and method == ("core", "p")
    outer_inner = build_stack("p", lambda problem: ("core", problem), stack)[2]
    assert outer_inner("q")[0] == "parts" and outer_inner("q")[1] == ("core", "q")  # parts alone accepts q below the realisation layer


LAYER_MODULE = '''
"""A layer that stamps a design: its method, its result record and its report hooks."""

from dataclasses import dataclass

from counterpoise.designer.layers import BaseLayer, Page, Table
from counterpoise.designer.methods import DesignMethod


@dataclass(frozen=True)
class Stamp:
    text: str


class Stamped(DesignMethod):
    def __init__(self, problem, inner):
        self._problem, self.inner = problem, inner

    @property
    def problem(self):
        return self._problem

    def solve_with(self, options):
        solution = self.inner.solve_with(options)
        return solution.with_extra(Stamp("stamped")).judged(solution.status, solution.message + "; stamped", "stamp")


class StampLayer(BaseLayer):
    name = "stamp"

    def accepts(self, problem):
        return problem.name == "pendulum"

    def wrap(self, problem, inner):
        return Stamped(problem, inner(problem))

    def summary_cells(self, result):
        stamp = result.extra(Stamp)
        return {"stamp": stamp.text} if stamp is not None else {}

    def status_notes(self, result):
        stamp = result.extra(Stamp)
        return f"stamp: {stamp.text}\\n" if stamp is not None else ""

    def tables(self, result):
        stamp = result.extra(Stamp)
        return {"stamp.csv": Table([{"stamp": stamp.text}], ["stamp"], page=Page("stamp", "Stamp", "stamp.csv: the stamp"))} if stamp is not None else {}


LAYER = StampLayer()
'''


@pytest.fixture
def stamp_layer(tmp_path, monkeypatch):
    """A new layer: its package (``stamp_layer``) and one registry line, nothing else."""
    package = tmp_path / "stamp_layer"
    package.mkdir()
    (package / "__init__.py").write_text("", encoding="utf-8")
    (package / "layer.py").write_text(textwrap.dedent(LAYER_MODULE), encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "REGISTRY", (*registry.REGISTRY, registry.Entry("stamp", "stamp_layer.layer")))
    layers.cache_clear()
    yield
    monkeypatch.undo()
    layers.cache_clear()
    sys.modules.pop("stamp_layer.layer", None)
    sys.modules.pop("stamp_layer", None)


def test_a_new_layer_is_its_package_and_one_registry_line(stamp_layer, tmp_path):
    """Registered, the stamp layer wraps the pendulum's method, its verdict is a valid one,
    and the reports take its summary cell (after the listed columns), its status line, its
    file and that file's section of report.html: no other module was edited."""
    from counterpoise.pipeline import build_method, run
    from counterpoise.report.files import report_texts, write_reports

    problem = pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build()
    method = build_method(problem)
    assert type(method).__name__ == "Stamped" and type(method.inner).__name__ == "Plain"
    result = run(method)
    assert result.optimal and result.verdict.source == "stamp" and result.message.endswith("; stamped")
    texts = report_texts(result, warnings=())
    assert texts["stamp.csv"] == "stamp\nstamped\n"
    assert texts["summary.csv"].splitlines()[0].endswith(",certificate,stamp") and texts["summary.csv"].splitlines()[1].endswith(",stamped")
    assert texts["status.txt"].endswith("stamp: stamped\n")
    assert Verdict(Status.OPTIMAL, "x", "stamp").source == "stamp"
    page = (write_reports(result, tmp_path / "out", html=True, warnings=()) / "report.html").read_text(encoding="utf-8")
    assert '<section id="stamp"><h2>Stamp</h2>' in page and "stamp.csv: the stamp" in page


def test_a_layers_table_cannot_yet_be_combined_with_another_as_its_entry_says(tmp_path, monkeypatch):
    """The registry's ``not_with`` is the one list of the tables a layer cannot take yet: an
    entry naming [slots] (no registered layer does now: [robust] with [slots] combines,
    tests/test_robust_slots.py) makes [robust] with [slots] an input error naming [robust]
    (io/resolve/context.combinations); without it the file reads."""
    text = (PROBLEMS / "lamp_catalogue.toml").read_text(encoding="utf-8") + '\n[robust]\nmode = "none"\ntolerances.rate = "10 %"\n'
    path = tmp_path / "lamp_catalogue_robust.toml"
    path.write_text(text, encoding="utf-8")
    assert load_problem(path).robust is not None
    refusing = tuple(registry.Entry(e.name, e.module, e.table, ("slots",), "docs/robust.md#not-done") if e.name == "robust" else e for e in registry.REGISTRY)
    monkeypatch.setattr(registry, "REGISTRY", refusing)
    with pytest.raises(ProblemFileError) as error:
        load_problem(path)
    assert error.value.key == "robust"
    assert error.value.message == "not combinable yet: [robust] with [slots] (docs/robust.md#not-done)"
