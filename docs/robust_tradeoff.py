"""The trade-off between added mass and the worst-case residual (docs/robust.md#trade-off).

Designs problems/lamp_robust.toml in ``limit`` mode for a range of limits, from the nominal
design's band down to what the exact counter-masses cannot remove (the arms' own mass
tolerance), and plots the added mass against the worst-case residual ratio. The robust
counterpart is built once (:meth:`counterpoise.robust.RobustMethod.with_spec`); each point
is one LP. Run: ``python docs/robust_tradeoff.py [--out docs/robust_tradeoff.png]``.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from counterpoise.designer.methods import core_method
from counterpoise.io.loader import load_problem
from counterpoise.robust import RobustMethod, RobustReport

HERE = Path(__file__).resolve().parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default=str(HERE / "robust_tradeoff.png"))
    parser.add_argument("--points", type=int, default=12)
    args = parser.parse_args()
    problem = load_problem(HERE.parent / "problems" / "lamp_robust.toml")
    spec = replace(problem.robust, tune=())
    problem = replace(problem, robust=spec)
    method = RobustMethod(problem, core_method(problem))
    rows = []
    for limit in np.linspace(0.12, 0.024, args.points):
        solution = method.with_spec(replace(spec, limit=float(limit))).solve()
        report = solution.extra(RobustReport)
        band = report.bands.get("robust", report.bands["nominal"])
        rows.append((float(limit), band["all"], band["rate"], band["mass"], report.added_mass.get("robust", float("nan")), (solution.verdict.status if solution.verdict is not None else solution.status).value))
    print("limit,worst_case_ratio,rate_part,mass_part,added_mass_kg,status")
    for r in rows:
        print(",".join(f"{x:.4g}" if isinstance(x, float) else str(x) for x in r))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r[5] == "optimal"]
    fig, ax = plt.subplots(figsize=(5.0, 3.4), dpi=100)
    ax.plot([r[1] for r in ok], [r[4] for r in ok], "o-", label="robust designs (limit mode)")
    nominal = method.solve().extra(RobustReport).bands["nominal"]["all"]
    ax.plot([nominal], [0.0], "s", label="nominal design (springs only)")
    ax.axvline(ok[-1][3], color="grey", ls=":", label="arm-mass tolerance alone")
    ax.set_xlabel("worst-case residual ratio over the tolerance box")
    ax.set_ylabel("added mass (kg)")
    ax.set_title("lamp_robust: rates ±10 %, arm masses ±5 %", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
