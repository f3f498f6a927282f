"""Long chains, the reusable dense check, the start-up of the command line and BLAS threads.

Speed itself is measured in ``benchmarks/`` (no timed tests); these tests pin what the
speed-ups must not change.
"""

from __future__ import annotations

import numpy as np
import pytest

from builders import Chain, Link
from conftest import PROBLEMS, fresh_python
from counterpoise.designer.designer import Designer
from counterpoise.io.loader import load_problem
from counterpoise.pipeline import design
from counterpoise.solvers.base import Status
from counterpoise.verify import verify
from counterpoise.verify.residuals import SubsystemResiduals, configurations


def tapered_chain(n: int) -> Chain:
    """n links of 0.2 m, body 0.7^i kg at 0.1 m, counter-mass 0.12 m behind each joint.

    Each counter-mass carries everything beyond its joint (``Chain.required_masses``), so
    the balancing masses grow inwards by about (1 + 0.2/0.12)·(its share): for 24 links
    they span 1.9e10 (base 4.2e6 kg, tip 2.3e-4 kg).
    """
    return Chain([Link(0.2, 0.7**i, (0.1, 0.0), 0.12) for i in range(n)])


def test_24_link_chain_is_optimal_and_verified():
    """The balancing masses span ten orders of magnitude. Before each coordinate's sampled
    residual rows were scaled, a rank tolerance relative to the largest singular value
    could not see the outer joints' conditions next to the base's; now all 24 are kept
    and the design is the unique one that puts every subtree's centre of mass on its
    joint, to rounding."""
    chain = tapered_chain(24)
    required = chain.required_masses()
    assert max(required) / min(required) > 1e10
    result = design(chain.problem())
    assert result.status is Status.OPTIMAL, result.message
    assert result.solution.stats.conditions == 24
    assert result.verification.residual_ratio <= 1e-9
    found = [result.solution.values[s] for s in sorted(result.solution.values, key=lambda s: int(s.variable[1:]))]
    np.testing.assert_allclose(found, required, rtol=1e-9)


@pytest.mark.parametrize("name", ["yasir2019_hybrid", "yasir2019_free_extensions"])
def test_cached_arrays_match_complex_step_per_design(name):
    """The dense check evaluates an element as factor(design) × a complex-step array
    computed once; the same elements evaluated by complex step on their whole energy for
    each design must agree (the hybrid: masses that depend on a variable; free extensions:
    counter-masses at variable distances, always evaluated per design)."""
    problem = load_problem(PROBLEMS / f"{name}.toml")
    solution = Designer(problem).solve()
    scenario = problem.scenarios[0]
    gravity, base = solution.scenario_parameters[scenario.name]
    rng = np.random.default_rng(3)
    variables = {v.name: rng.uniform(v.lower, v.upper) for v in problem.variables}
    for sub in problem.subsystems:
        q = configurations(problem, sub.name, 500, rng)
        fast = SubsystemResiduals(problem, sub.name, q)
        slow = SubsystemResiduals(problem, sub.name, q, cache=False)
        slow.per_design, slow.constant, slow.separable = slow.elements, [], []
        for got, want in zip(fast.evaluate(variables, base, gravity), slow.evaluate(variables, base, gravity)):
            np.testing.assert_allclose(got, want, rtol=1e-11, atol=1e-12 * np.abs(want).max())


def test_repeated_verification_reuses_and_matches():
    """A second check of the same problem reuses the evaluators and gives the same figures;
    other parameter values (a study point) get their own."""
    problem = load_problem(PROBLEMS / "yasir2019_counter_mass.toml")
    designer = Designer(problem)
    solution = designer.solve()  # one solution checked twice (an LP re-solve may differ in the last bit)
    first = verify(solution)
    again = verify(solution)
    assert first == again
    name = problem.base_parameters[0].name
    other = designer.solve(parameters={name: 1.1 * problem.base_parameters[0].value})
    assert verify(other).checks != first.checks


def test_a_study_of_masses_reuses_the_arrays_and_matches_a_fresh_check():
    """Changing a mass parameter keeps the geometry, so the arrays are reused; changing a
    length rebuilds them. Either way the figures equal those of a one-off evaluation."""
    from counterpoise.verify.check import evaluators
    from counterpoise.verify.residuals import residuals

    problem = load_problem(PROBLEMS / "yasir2019_hybrid.toml")
    designer = Designer(problem)
    verify(designer.solve())
    evaluator = evaluators(designer.solve())[0][2]
    arrays = evaluator._arrays
    for parameters, reused in (({"m_endo": 0.8}, True), ({"r_a": 0.14}, False)):
        solution = designer.solve(parameters=parameters)
        verification = verify(solution)
        assert (evaluator._arrays is arrays) is reused
        scenario, subsystem, _ = evaluators(solution)[0]
        gravity, base = solution.scenario_parameters[scenario]
        r, t = residuals(problem, subsystem, evaluator.q, solution.variable_values(scenario), base, gravity)
        check = verification.checks[0]
        assert check.max_residual == pytest.approx(float(np.abs(r[:, 0]).max()), rel=1e-9, abs=1e-14)
        # the sampled maximum, refined to the box maximum (verify.checks): never below it, and close
        assert float(np.abs(t[:, 0]).max()) <= check.max_gravity_torque <= float(np.abs(t[:, 0]).max()) * (1 + 1e-2)


def test_blas_is_single_threaded_after_a_designer_is_built():
    from threadpoolctl import threadpool_info

    Designer(Chain([Link(0.3, 1.0, (0.1, 0.0), 0.1)]).problem())
    assert all(pool["num_threads"] == 1 for pool in threadpool_info())


def test_top_level_help_imports_no_heavy_module():
    """``counterpoise --help`` imports typer and rich, not the library: every command
    imports what it needs inside its function (``cli/app.py``)."""
    out = fresh_python(
        "import sys\n"
        "from counterpoise.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit as e:\n    code = e.code\n"
        "heavy = sorted(m for m in ('numpy', 'pint', 'pydantic', 'casadi', 'pandas', 'counterpoise.model', 'counterpoise.io.cache') if m in sys.modules)\n"
        "print(code, heavy, 'typer' in sys.modules)\n"
    )
    assert out.strip().splitlines()[-1] == "0 [] True"


def test_units_without_dask_and_without_a_usable_cache():
    """pint is imported without probing dask (which stays importable), and a cache folder
    that cannot be created falls back to building the registry from pint's definitions."""
    out = fresh_python(
        "import sys, importlib.util\n"
        "from counterpoise.model import units\n"
        "q = units.ureg().Quantity(1, 'N/mm').to_base_units()\n"
        "print(round(q.magnitude), 'dask' in sys.modules, units.ureg().cache_folder, importlib.util.find_spec('dask') is not None)\n",
        COUNTERPOISE_PINT_CACHE="/dev/null/not-a-folder",
    )
    import importlib.util

    has_dask = importlib.util.find_spec("dask") is not None
    assert out.split() == ["1000", "False", "None", str(has_dask)]


# -- the convex path: Clarabel's own API -----------------------------------------------------


def _lp_backend(quadratic: float = 0.0):
    """min x0 + 2 x1 (+ quadratic·x1²) s.t. x0 + x1 = p, x0 - x1 ≥ -1 (g), 0 ≤ x ≤ 10."""
    import casadi as ca

    from counterpoise.solvers.convex import ConvexBackend

    x, p = ca.SX.sym("x", 2), ca.SX.sym("p")
    nlp = {"x": x, "p": p, "f": x[0] + 2 * x[1] + quadratic * x[1] ** 2, "g": ca.vertcat(x[0] + x[1] - p, x[0] - x[1])}
    return ConvexBackend(nlp, [0, 1])


def _bounds(lbz=(0.0, 0.0), ubz=(10.0, 10.0)):
    from counterpoise.solvers.base import Bounds

    return Bounds(np.array(lbz, float), np.array(ubz, float), np.array([0.0, -1.0]), np.array([0.0, np.inf]))


def test_convex_backend_solves_with_clarabel_and_maps_statuses():
    """The LP's optimum (x1 as small as the constraint x0 - x1 ≥ -1 allows: none), with p
    entering the constant terms per call; an infeasible and an unbounded-below problem map
    to INFEASIBLE and FAILED; NaN/inf coefficients are a FAILED call, not an exception
    (before: cvxpy's ValueError, an internal error of the CLI)."""
    lp = _lp_backend()
    out = lp.solve(np.zeros(2), np.array([3.0]), _bounds())
    assert out.status is Status.OPTIMAL and out.solver == "clarabel" and out.solver_status == "Solved"
    np.testing.assert_allclose(out.z, [3.0, 0.0], atol=1e-9)
    assert lp.solve(np.zeros(2), np.array([30.0]), _bounds()).status is Status.INFEASIBLE  # x0 + x1 ≤ 20
    free = lp.solve(np.zeros(2), np.array([3.0]), _bounds((-np.inf, -np.inf), (np.inf, np.inf)))
    assert free.status is Status.FAILED and free.solver_status == "DualInfeasible"  # x1 → -inf
    bad = lp.solve(np.zeros(2), np.array([np.inf]), _bounds())
    assert bad.status is Status.FAILED and bad.solver_status.startswith("invalid_data")


def test_convex_backend_qp_and_fixed_variables():
    """A convex quadratic objective, and a variable fixed by its bounds (an equality row)."""
    qp = _lp_backend(quadratic=1.0)
    out = qp.solve(np.zeros(2), np.array([3.0]), _bounds((0.0, 0.0), (10.0, 10.0)))
    np.testing.assert_allclose(out.z, [3.0, 0.0], atol=1e-8)
    pinned = qp.solve(np.zeros(2), np.array([3.0]), _bounds((0.0, 1.5), (10.0, 1.5)))
    assert pinned.status is Status.OPTIMAL
    np.testing.assert_allclose(pinned.z, [1.5, 1.5], atol=1e-9)


def test_light_csc_matrix_is_scipys_and_clarabel_accepts_both():
    """Clarabel reads SciPy's CSC attributes; :class:`CscMatrix` has the same arrays, and
    a cone program solved with either gives the same answer (so a Clarabel that would
    insist on SciPy's own type still gets the same problem through the fallback)."""
    import clarabel
    from scipy.sparse import csc_matrix

    from counterpoise.solvers.convex import CLARABEL_DEFAULTS, ConeProgram, CscMatrix, solve_cone_program

    rng = np.random.default_rng(5)
    dense = rng.normal(size=(7, 4)) * (rng.random((7, 4)) < 0.5)
    mine, theirs = CscMatrix.from_dense(dense), csc_matrix(dense)
    for name in ("data", "indices", "indptr"):
        np.testing.assert_array_equal(getattr(mine, name), getattr(theirs, name))
    assert mine.shape == theirs.shape and mine.nnz == theirs.nnz and theirs.has_canonical_format
    program = ConeProgram(np.zeros((4, 4)), np.ones(4), np.vstack([np.ones((1, 4)), -np.eye(4)]), np.array([1.0, 0, 0, 0, 0]), 1, 4)
    y, status, _ = solve_cone_program(program, CLARABEL_DEFAULTS)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    for key, value in CLARABEL_DEFAULTS.items():
        setattr(settings, key, value)
    cones = [clarabel.ZeroConeT(1), clarabel.NonnegativeConeT(4)]
    ref = clarabel.DefaultSolver(csc_matrix((4, 4)), program.q, csc_matrix(program.A), program.b, cones, settings).solve()
    assert status == str(ref.status) == "Solved"
    np.testing.assert_allclose(y, ref.x, atol=1e-12)


def test_solve_imports_no_cvxpy(tmp_path):
    """A solve in a fresh process: an LP design through Clarabel's own API, and no cvxpy,
    scipy, pandas, matplotlib or dask on the way; without a [robot] table, not the robot
    reader either (nor yourdfpy, trimesh, MuJoCo)."""
    out = fresh_python(
        "import sys\n"
        "from counterpoise.cli import main\n"
        f"try:\n    main(['solve', {str(PROBLEMS / 'yasir2019_hybrid.toml')!r}, '--out', {str(tmp_path)!r}])\n"
        "except SystemExit as e:\n    code = e.code\n"
        "heavy = sorted(m for m in ('cvxpy', 'scipy', 'pandas', 'matplotlib', 'dask', 'counterpoise.io.robot', 'yourdfpy', 'trimesh', 'mujoco') if m in sys.modules)\n"
        "print(code, heavy, 'clarabel' in sys.modules)\n"
    )
    assert out.strip().splitlines()[-1] == "0 [] True"


def test_validate_imports_no_solver_library(tmp_path):
    """``validate`` reads and checks: no cvxpy, pandas or matplotlib."""
    out = fresh_python(
        "import sys\n"
        "from counterpoise.cli import main\n"
        f"try:\n    main(['validate', {str(PROBLEMS / 'yasir2019_hybrid.toml')!r}])\n"
        "except SystemExit as e:\n    code = e.code\n"
        "print(code, sorted(m for m in ('cvxpy', 'pandas', 'matplotlib') if m in sys.modules))\n"
    )
    assert out.strip().splitlines()[-1] == "0 []"


def test_quantity_pattern_unchanged_by_its_faster_form():
    """The quantity-literal pattern with Ω as an alternative of its own (13 ms less to
    compile) accepts exactly what the character class [A-Za-z°µΩ%] accepted."""
    import re

    from counterpoise.model import units

    before = re.compile(rf"^\s*{units._NUMBER}(?:\s*[A-Za-z°µΩ%]|\s+1\s*/)")
    samples = ["135 mm", "5 Ω", "5Ω", "5 Ωm", "5 Ω_it", "0.5 N/mm", "57.2deg", "3 1/m", "x + 1", "1e3 g", "2 %", "5 µm", "5 μm",
               "-1.5e-3 kg", "1e", "3 ·", "3 °", ".5 g", "5.", "5 Ω", "r_a * 2", "2 * r_a", "+3 Z", "3 _", "3\tkg", "3 ω"]
    for text in samples:
        assert bool(re.match(units._QUANTITY, text)) == bool(before.match(text)), text
