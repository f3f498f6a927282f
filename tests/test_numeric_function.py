"""The buffered CasADi evaluation (counterpoise.numeric) gives the ordinary call's numbers, bit for bit."""

import threading

import casadi as ca
import numpy as np
import pytest

from counterpoise.numeric import NumericFunction


@pytest.fixture(scope="module")
def function():
    """A function with a dense and a sparse output, a matrix output and a scalar one."""
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 2)
    g = ca.vertcat(ca.sin(x[0]) * p[0], x[1] * x[2] - p[1], ca.exp(-x[2]))
    return ca.Function("f", [x, p], [g, ca.jacobian(g, x), ca.sumsqr(x) * p[1]])


def _ordinary(function, *args):
    return [np.array(v) for v in function.call(list(args))]


def test_same_numbers_as_the_ordinary_call(function):
    fast = NumericFunction(function)
    rng = np.random.default_rng(3)
    for _ in range(5):
        x, p = rng.normal(size=3), rng.normal(size=2)
        got, want = fast(x, p), _ordinary(function, x, p)
        assert len(got) == 3
        for a, b in zip(got, want):
            assert a.shape == b.shape  # 2-D, as DM.full() gives: (3, 1), (3, 3) and (1, 1)
            assert np.array_equal(a, b)  # identical arithmetic: no tolerance
            assert a.flags["C_CONTIGUOUS"] and b.flags["C_CONTIGUOUS"]  # the memory order too: a product rounds by it
    assert function.sparsity_out(1).nnz() < 9  # the Jacobian is sparse: structural zeros are 0.0 in the dense output


def test_results_are_copies_and_inputs_any_shape(function):
    fast = NumericFunction(function)
    first = fast(np.ones((3, 1)), [1.0, 2.0])[0]
    fast(np.zeros(3), [1.0, 2.0])
    assert np.array_equal(first, _ordinary(function, np.ones(3), np.array([1.0, 2.0]))[0])  # not overwritten by the next call


def test_wrong_sizes_raise_as_casadi_does(function):
    fast = NumericFunction(function)
    with pytest.raises(RuntimeError):
        fast(np.ones(4), np.ones(2))


def test_each_thread_its_own_buffers(function):
    """Threads evaluating at once each get their own work memory (and the right answers)."""
    fast = NumericFunction(function)
    rng = np.random.default_rng(5)
    inputs = [(rng.normal(size=3), rng.normal(size=2)) for _ in range(4)]
    wrong: list[int] = []

    def work(i: int) -> None:
        x, p = inputs[i]
        want = _ordinary(function, x, p)
        for _ in range(200):
            if not all(np.array_equal(a, b) for a, b in zip(fast(x, p), want)):
                wrong.append(i)
                return

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not wrong


def _small_nlp():
    """min (x0 - p)² + x1² s.t. x0 + x1 = 0, x in [-1, 1]²: x = (p/2, -p/2) for |p| ≤ 2."""
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p", 1)
    return {"x": x, "p": p, "f": (x[0] - p) ** 2 + x[1] ** 2, "g": x[0] + x[1]}


def test_ipopt_through_its_buffers_is_the_ordinary_solve():
    """IpoptBackend evaluates nlpsol through its buffers: the same iterate, multipliers,
    status and iteration count as the ordinary keyword call, bit for bit; an infeasible
    problem and an ill-posed one (lower bound above upper) behave as before."""
    from counterpoise.solvers.base import Bounds
    from counterpoise.solvers.ipopt import IPOPT_DEFAULTS, IpoptBackend

    backend = IpoptBackend(_small_nlp(), IPOPT_DEFAULTS)
    solver = backend.solver
    box = (np.array([-1.0, -1.0]), np.array([1.0, 1.0]))
    for p, (lbg, ubg) in [(0.5, (0.0, 0.0)), (-1.3, (0.0, 0.0)), (0.5, (5.0, 5.0))]:  # the last: x0 + x1 = 5 in the box is infeasible
        bounds = Bounds(*box, np.array([lbg]), np.array([ubg]))
        out = backend.solve(np.zeros(2), np.array([p]), bounds)
        want = solver(x0=np.zeros(2), p=p, lbx=box[0], ubx=box[1], lbg=lbg, ubg=ubg)
        stats = solver.stats()
        assert np.array_equal(out.z, np.array(want["x"]).reshape(-1))
        assert np.array_equal(out.multipliers, np.array(want["lam_g"]).reshape(-1))
        assert (out.solver_status, out.iterations) == (stats["return_status"], stats["iter_count"])
    assert out.solver_status == "Infeasible_Problem_Detected"
    with pytest.raises(RuntimeError):
        backend.solve(np.zeros(2), np.array([0.5]), Bounds(np.array([1.0, -1.0]), np.array([0.0, 1.0]), np.zeros(1), np.zeros(1)))


def test_remembered_outputs_are_the_evaluations_and_copies(function):
    """``remember``: the same inputs give the outputs of their evaluation again (as copies a
    caller may change), only the latest distinct inputs are kept, and -0.0 is not 0.0."""
    fast = NumericFunction(function, remember=2)
    calls = []
    evaluate = fast._evaluate
    fast._evaluate = lambda values: calls.append(1) or evaluate(values)
    x, p = np.array([0.3, -1.2, 0.7]), np.array([2.0, 0.5])
    first = fast(x, p)
    first[0][:] = 99.0  # the caller's copy
    again = fast(x.copy(), p.copy())
    assert len(calls) == 1
    for a, b in zip(again, _ordinary(function, x, p)):
        assert np.array_equal(a, b)
    fast(x + 1, p)
    fast(x + 2, p)  # x is now the third latest: evaluated again
    fast(x, p)
    assert len(calls) == 4
    fast(np.array([-0.0, -1.2, 0.7]), p)
    fast(np.array([0.0, -1.2, 0.7]), p)
    assert len(calls) == 6
