"""Balancer synthesis: from a superstructure of candidate springs and counter-masses
(a problem's ``[synthesis]`` table), the fewest (cheapest) elements that balance exactly,
proven minimal on the grid, every minimal topology, refined and verified by the engine
(docs/synthesis.md).

Its own layer, above the report layer: it builds ordinary problems and designs them with
:func:`counterpoise.pipeline.design`. cvxpy (and HiGHS through it) is imported here only,
inside the solves: ``counterpoise solve`` never loads it.

    from counterpoise import load_problem
    from counterpoise.synthesis import synthesise, write_synthesis

    result = synthesise(load_problem("problems/synthesis/arm2_springs.toml"))
    print(result.cost, [t.labels for t in result.topologies], result.proof)
    write_synthesis(result, "results")
"""

from __future__ import annotations

from .report import write_synthesis
from .run import ParetoPoint, SynthesisResult, Topology, synthesise

__all__ = ["ParetoPoint", "SynthesisResult", "Topology", "synthesise", "write_synthesis"]
