"""The poses kept between designs by the residual evaluator (verify/residuals.py, _ChunkInputs)
change nothing: one evaluator used for many designs that move a link's length, the
counter-masses' offsets and a mass gives, bit for bit, what a fresh evaluator gives for each
design; and what it keeps stays bounded."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import PROBLEMS
from counterpoise.io.loader import load_problem
from counterpoise.verify import residuals as R


@pytest.fixture(scope="module")
def leg():
    """The free-extensions leg (r_b moves link_c; b_b and b_c move the counter-masses) on 40
    seeded configurations of its box."""
    problem = load_problem(PROBLEMS / "yasir2019_free_extensions.toml")
    q = R.configurations(problem, "leg", 40, np.random.default_rng(7))
    return problem, q


def _designs(problem, count):
    rng = np.random.default_rng(11)
    base = {p.name: float(p.value) for p in problem.base_parameters}
    variables = {v.name: float(v.initial) for v in problem.variables}
    for k in range(count):
        b = dict(base, r_b=base["r_b"] * (0.9 + 0.2 * rng.random()), m_pay=base["m_pay"] * (0.5 + rng.random()))
        v = dict(variables, M_b=1.2 * rng.random(), M_c=0.3 * rng.random())
        if k % 3:  # the offsets at their upper bounds (as an optimum has them) or anywhere
            v.update(b_b=0.04 + 0.08 * rng.random(), b_c=0.1 + 0.15 * rng.random())
        yield v, b


def test_kept_poses_give_the_fresh_evaluators_numbers(leg):
    problem, q = leg
    kept = R.SubsystemResiduals(problem, "leg", q)
    gravity = (0.0, -9.81, 0.0)
    for variables, base in _designs(problem, 12):
        got = kept.evaluate(variables, base, gravity)
        want = R.SubsystemResiduals(problem, "leg", q).evaluate(variables, base, gravity)
        for a, b in zip(got, want):
            assert np.array_equal(a, b)  # the same arithmetic: no tolerance


def test_kept_poses_are_bounded(leg, monkeypatch):
    problem, q = leg
    monkeypatch.setattr(R, "POSE_ENTRIES", 5)
    evaluator = R.SubsystemResiduals(problem, "leg", q)
    for variables, base in _designs(problem, 10):
        evaluator.evaluate(variables, base, (0.0, -9.81, 0.0))
    (chunk,) = evaluator._chunk_inputs.values()
    assert 0 < len(chunk._poses) <= 5
    assert chunk._bytes == sum(size for _, size in chunk._poses.values())


def test_remembered_rotations_are_bounded(leg):
    """The rotation memo shared by a chunk's designs (``Mechanics.rotation`` and
    ``Mechanics._rotated``) keeps at most ROTATIONS_KEPT angles and PRODUCTS_KEPT products
    per transform, however many designs move a length; and it does remember products (a
    design that changes r_b finds link_c's rotations)."""
    from counterpoise.mechanics import energy as E

    problem, q = leg
    evaluator = R.SubsystemResiduals(problem, "leg", q)
    for variables, base in _designs(problem, 20):
        evaluator.evaluate(variables, base, (0.0, -9.81, 0.0))
    (chunk,) = evaluator._chunk_inputs.values()
    products = {k: v for k, v in chunk.rotations.items() if k[0] == "product"}
    angles = {k: v for k, v in chunk.rotations.items() if k[0] != "product"}
    assert products and angles
    assert all(len(v) <= E.PRODUCTS_KEPT for v in products.values())
    assert all(len(v) <= E.ROTATIONS_KEPT for v in angles.values())


def test_products_not_remembered_for_large_chunks(leg, monkeypatch):
    """Above PRODUCT_SIZE values per array (a dense check's chunk) no product is kept."""
    from counterpoise.mechanics import energy as E

    problem, q = leg
    monkeypatch.setattr(E, "PRODUCT_SIZE", len(q) - 1)
    evaluator = R.SubsystemResiduals(problem, "leg", q)
    for variables, base in _designs(problem, 4):
        evaluator.evaluate(variables, base, (0.0, -9.81, 0.0))
    (chunk,) = evaluator._chunk_inputs.values()
    assert not any(k[0] == "product" for k in chunk.rotations)
