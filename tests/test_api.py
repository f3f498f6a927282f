"""The Python API: the example of docs/api.md runs, and code-built problems equal file-built
ones; the layers import nothing above their own (:data:`LAYERS`)."""

from __future__ import annotations

import pickle
import re

import pytest

from conftest import ROOT

API_PAGE = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")

#: The layers, innermost first: each imports only from those before it. The one statement of
#: the order: docs/development.md names this list, and tests/test_docs.py checks that every
#: other page that writes the order (the package's docstring, docs/layout.md) agrees with it.
# io reads a file into the model and assembles closed loops at home (their homes are
# starting guesses, docs/loops.md), so it sits above mechanics; mechanics never reads files
LAYERS = ["model", "catalogue", "mechanics", "io", "formulation", "solvers", "designer", "verify", "selection", "payload", "robust", "realisation", "pipeline", "report", "plots", "synthesis", "studies", "cli"]


def _api_python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", API_PAGE, flags=re.S)


def test_api_page_example_runs_and_prints_the_documented_design(capsys):
    blocks = _api_python_blocks()
    assert blocks, "docs/api.md has no python example"
    namespace: dict = {}
    exec(compile(blocks[0], "docs/api.md", "exec"), namespace)  # noqa: S102 - our own documentation
    printed = capsys.readouterr().out
    assert printed.startswith("optimal ")
    values = namespace["result"].solution.values
    m, r, w = 0.8, 0.3, 16.0
    b = {s.variable: v for s, v in values.items()}
    assert b["b"] == pytest.approx(1 / w**0.5, rel=1e-7)
    assert b["M"] * b["b"] == pytest.approx(m * r, rel=1e-9)


def test_builder_and_file_give_the_same_problem():
    from builders import pendulum, pendulum_toml
    from counterpoise.io.loader import load_problem_text

    built = pendulum(0.8, 0.3, (0.02, 1.0), 4.0).build("same.toml")
    read = load_problem_text(pendulum_toml(0.8, 0.3, (0.02, 1.0), 4.0), "same.toml")
    assert built == read


def test_builder_errors_name_the_key():
    from builders import pendulum
    from counterpoise.errors import ProblemFileError

    b = pendulum(0.8, 0.3, (0.02, 1.0), 4.0).body("bad", frame="nowhere", mass="1 kg", com=(0, 0, 0))
    with pytest.raises(ProblemFileError) as info:
        b.build("built.toml")
    assert info.value.file == "built.toml" and info.value.key == "bodies.bad.frame"


def test_designer_pickles_as_its_description_and_rebuilds():
    from builders import pendulum
    from counterpoise.designer import Designer
    from counterpoise.formulation import Slot

    designer = Designer(pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build())
    clone = pickle.loads(pickle.dumps(designer))
    assert clone is not designer and clone.backend.solver is not designer.backend.solver
    a, b = designer.solve(), clone.solve()
    assert all(a.values[s] == pytest.approx(b.values[s], rel=1e-10) for s in a.values)
    assert Slot("b", None) in b.values


def test_bounds_per_call_do_not_rebuild():
    from builders import pendulum
    from counterpoise.designer import Designer
    from counterpoise.formulation import Slot

    designer = Designer(pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build())
    solver = designer.backend.solver
    narrowed = designer.solve(bounds={"b": (0.5, 0.6)})
    assert designer.backend.solver is solver
    assert narrowed.values[Slot("b", None)] == 0.5  # b* = 0.2 lies below: the optimum sits on the new lower bound
    free = designer.solve()
    assert free.values[Slot("b", None)] == pytest.approx(0.2, rel=1e-7)  # the next call has the file's bounds again


def test_process_runner_matches_serial():
    from builders import pendulum
    from counterpoise.studies import ProcessRunner, SerialRunner, StudyTask, run

    task = StudyTask(pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build())
    points = [{"m": m} for m in (0.5, 0.8, 1.1, 1.4)]
    serial = run(task, points, SerialRunner(), batch_size=2)
    pooled = run(task, points, ProcessRunner(jobs=2), batch_size=2)
    assert [p.values for p in serial] == [p.values for p in pooled]
    assert all(p.status == "optimal" for p in serial)
    assert [p.values["M"] * p.values["b"] for p in serial] == pytest.approx([m * 0.3 for m in (0.5, 0.8, 1.1, 1.4)], rel=1e-9)


def test_layers_do_not_import_upwards():
    """model imports nothing above it; mechanics nothing from io and beyond; io nothing from
    formulation and beyond; and so on: not at run time, not inside a function, not for
    annotations (an outer layer's result is an extra of the design, reached by its own
    type: docs/development.md, "Typed, immutable results")."""
    order = LAYERS
    src = ROOT / "src" / "counterpoise"
    rank = {name: i for i, name in enumerate(order)}
    offenders = []
    for path in src.rglob("*.py"):
        rel = path.relative_to(src)
        layer = rel.parts[0].removesuffix(".py")
        if layer not in rank:
            continue
        text = path.read_text(encoding="utf-8")
        for match in re.finditer(r"^\s*from \.+(\w+)", text, flags=re.M):
            target = match.group(1)
            depth = len(re.match(r"^\s*from (\.+)", match.group(0)).group(1))
            if depth == 1 and len(rel.parts) > 1:
                continue  # a sibling inside the same layer
            if target in rank and rank[target] > rank[layer]:
                offenders.append(f"{rel}: imports {target}")
    assert not offenders, offenders


def _import_graph(annotations: bool = False) -> dict[str, dict[str, set[str]]]:
    """Modules of src/counterpoise -> {imported module: names imported, prefixed "def:" when
    the import runs inside a function}. Imports under ``if TYPE_CHECKING`` never run: left
    out, unless ``annotations`` (then their names are prefixed "type:")."""
    import ast

    src = ROOT / "src"
    files = {}
    for path in (src / "counterpoise").rglob("*.py"):
        parts = list(path.relative_to(src).with_suffix("").parts)
        package = parts[-1] == "__init__"
        files[".".join(parts[:-1] if package else parts)] = (path, package)
    graph: dict[str, dict[str, set[str]]] = {m: {} for m in files}
    for module, (path, package) in files.items():
        here = module.split(".") if package else module.split(".")[:-1]

        def visit(node, in_function, module=module, here=here, typing=False):
            for child in ast.iter_child_nodes(node):
                inner = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
                if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                    if annotations:
                        visit(child, inner, typing=True)
                    continue
                targets = []
                if isinstance(child, ast.ImportFrom):
                    base = here[: len(here) - child.level + 1] if child.level else []
                    target = ".".join(base + (child.module.split(".") if child.module else []))
                    for alias in child.names:  # `from . import parts` imports the module parts
                        sub = f"{target}.{alias.name}"
                        targets.append((sub, "*") if sub in files else (target, alias.name))
                elif isinstance(child, ast.Import):
                    targets = [(alias.name, "*") for alias in child.names]
                for target, name in targets:
                    if target in files and target != module:
                        graph[module].setdefault(target, set()).add(f"def:{name}" if inner else f"type:{name}" if typing else name)
                visit(child, inner, typing=typing)

        visit(ast.parse(path.read_text(encoding="utf-8")), False)
    return graph


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges[v]:
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in edges:
        if v not in index:
            strong(v)
    return out


def test_no_circle_of_imports():
    """No two modules import each other at module level, directly or round a longer circle;
    an import inside a function may close a circle (a lazy import), but not one that takes a
    private name (``_x``): a helper that two modules share belongs in a module both import."""
    graph = _import_graph()
    module_level = {m: {t for t, names in targets.items() if any(not n.startswith("def:") for n in names)} for m, targets in graph.items()}
    assert _cycles(module_level) == []
    private = []
    for component in _cycles({m: set(targets) for m, targets in graph.items()}):
        for m in component:
            for target, names in graph[m].items():
                taken = sorted(n.removeprefix("def:") for n in names if n.removeprefix("def:").startswith("_"))
                if target in component and taken:
                    private.append(f"{m} imports {', '.join(taken)} from {target} (a circle: {' '.join(component)})")
    assert private == []


def test_no_circle_of_imports_even_for_annotations():
    """Counting the imports made for annotations only (``if TYPE_CHECKING:``), there is no
    circle of module-level imports either: the core result names no outer layer's type
    (its layers' results are extras reached by their own types; issue 33: a 19-file circle
    through ``designer/solution.py``), and the designer's parts take the designer as a
    protocol (``designer/built.py``), not by its class."""
    graph = _import_graph(annotations=True)
    module_level = {m: {t for t, names in targets.items() if any(not n.startswith("def:") for n in names)} for m, targets in graph.items()}
    assert _cycles(module_level) == []


def test_kept_builds_once_per_key_and_drops_the_least_recently_used():
    """What workers keep (design methods, part-search models, adjusters) is built once per
    key; beyond its size the least recently used goes first, and is built again if asked."""
    from counterpoise.kept import Kept

    built: list[str] = []
    kept: Kept[str, str] = Kept(2)

    def get(key: str) -> str:
        return kept.get(key, lambda: built.append(key) or key.upper())

    assert [get("a"), get("b"), get("a")] == ["A", "B", "A"]
    assert built == ["a", "b"]
    get("c")  # drops b, the least recently used ("a" was used after it)
    assert len(kept) == 2
    get("a")
    get("b")
    assert built == ["a", "b", "c", "b"]
    with pytest.raises(ValueError):
        Kept(0)
