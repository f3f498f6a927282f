"""Directly attached springs under tolerances: their lengths at every corner.

A spring attached directly (no pulley) pulls F0 + k (d − c − L0) while its length stays
within L0 + slack margin ≤ d − c ≤ L_max (:class:`counterpoise.model.elements.DirectMount`); the minimax
designer holds those rows on its samples (:mod:`counterpoise.designer.minimax`). Of the
tolerances, only a ``point`` tolerance of the spring moves its ends and so its length (a
rate, an initial tension or a mass does not), so the rows are written at every corner of
the spring's own point deviations (six per spring: 64 corners), as CasADi expressions of the
formulation's z and p for the robust minimax NLP (:mod:`.minimax`), and evaluated on the
dense sample after the design: a robust design never leaves a spring slack or stretched
beyond its longest length at a corner without saying so (docs/robust.md).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

from .affine import Decomposition
from .perturb import corner_text


@dataclass(frozen=True)
class LengthMargin:
    """The least margin of one spring's length limit over the corners and configurations."""

    spring: str
    limit: str  # "slack" (d − c ≥ L0 + slack margin) or "length" (d − c ≤ L_max)
    margin: float  # m; < 0: broken
    corner: str  # the corner's deviations ("nominal" when no point of the spring is toleranced)


class DirectLengths:
    """The length rows of a decomposition's directly attached springs (none: :attr:`springs` empty)."""

    def __init__(self, decomposition: Decomposition) -> None:
        import casadi as ca

        from ..mechanics import Mechanics, casadi_functions
        from ..mechanics.kinematics import dot, sub

        self.decomposition = decomposition
        problem = decomposition.problem
        f = decomposition.formulation
        self.springs = [s for s in problem.springs if s.direct is not None and s.subsystem is not None]
        #: per spring: its point deviations (indices) and the corners of them (signs over every deviation)
        self.corners: dict[str, list[tuple[int, ...]]] = {}
        n_dev = len(decomposition.deviations)
        for s in self.springs:
            own = [i for i, d in enumerate(decomposition.deviations) if d.tolerance.kind == "point" and d.tolerance.item == s.name]
            corners = []
            for signs in itertools.product((-1, 1), repeat=len(own)):
                full = [0] * n_dev
                for i, sign in zip(own, signs):
                    full[i] = sign
                corners.append(tuple(full))
            self.corners[s.name] = corners
        #: per (spring, block index): the function (coordinates, z, p) -> [d − c − L0, L_max − (d − c)]
        self.functions: dict[tuple[str, int], Any] = {}
        self.has_max = {s.name: s.direct is not None and s.direct.max_length is not None for s in self.springs}
        functions = casadi_functions()
        for b, block in enumerate(f.blocks):
            c = [sc.name for sc in problem.scenarios].index(block.scenario)
            gravity, base = f.parameters.split(f.p, c)
            variables = f.design.symbols(f.x, block.scenario)
            names = [k.name for k in problem.subsystem_coordinates(block.subsystem)]
            q = ca.SX.sym("q", len(names))
            mech = None
            for s in self.springs:
                m = s.direct
                if m is None or s.subsystem != block.subsystem:
                    continue
                if mech is None:
                    mech = Mechanics(problem, base, variables, {n: q[i] for i, n in enumerate(names)}, gravity, functions)
                v = sub(mech.position(s.ends[0]), mech.position(s.ends[1]))
                length = ca.sqrt(dot(v, v)) - mech.value(m.cable)
                rows = [length - mech.value(m.free_length)]
                if m.max_length is not None:
                    rows.append(mech.value(m.max_length) - length)
                self.functions[(s.name, b)] = ca.Function(f"direct_length_{s.name}", [q, f.z, f.p], [ca.vertcat(*rows)])
        #: the scale of the NLP's rows (the designer's: the largest bound of a design variable)
        self.scale = max(float(np.max(np.abs(f.design.upper), initial=0.0)), 1e-3)

    def symbolic(self, q: list[np.ndarray]) -> list[Any]:
        """The NLP's rows (each ≥ 0), at configurations ``q`` (one array per block) and every
        corner of each spring's point deviations: d − c − L0 − slack margin, L_max − (d − c)."""
        import casadi as ca

        f = self.decomposition.formulation
        zero = np.zeros(f.p.numel())
        rows: list[Any] = []
        for s in self.springs:
            margin = np.array([[s.slack_margin], [0.0]])[: 2 if self.has_max[s.name] else 1]
            for b in range(len(f.blocks)):
                fn = self.functions.get((s.name, b))
                if fn is None:
                    continue
                mapped = fn.map(len(q[b]))
                for corner in self.corners[s.name]:
                    values = mapped(ca.DM(q[b].T), f.z, f.p + ca.DM(self.decomposition.p_at(zero, corner)))  # (rows, N)
                    for i in range(values.shape[0]):
                        rows.append((values[i, :].T - float(margin[i, 0])) / self.scale)
        return rows

    def worst(self, z: np.ndarray, p: np.ndarray, q: list[np.ndarray]) -> list[LengthMargin]:
        """Each spring's least margin to each of its limits over the corners and ``q``:
        d − c − L0 − slack margin and L_max − (d − c)."""
        out = []
        devs = self.decomposition.deviations
        for s in self.springs:
            margin = (s.slack_margin, 0.0)
            least: dict[str, tuple[float, str]] = {}
            for b in range(len(self.decomposition.formulation.blocks)):
                fn = self.functions.get((s.name, b))
                if fn is None:
                    continue
                mapped = fn.map(len(q[b]))
                for corner in self.corners[s.name]:
                    values = np.array(mapped(q[b].T, z, self.decomposition.p_at(p, corner)))
                    for i, limit in enumerate(("slack", "length")[: values.shape[0]]):
                        low = float(values[i].min(initial=np.inf)) - margin[i]
                        if limit not in least or low < least[limit][0]:
                            least[limit] = (low, corner_text(devs, corner))
            out += [LengthMargin(s.name, limit, margin, corner) for limit, (margin, corner) in least.items()]
        return out
