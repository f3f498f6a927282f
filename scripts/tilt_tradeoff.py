"""How much counter-mass buys how much base tilt: the trade-off study of docs/tilt.md.

Run:  .venv/bin/python scripts/tilt_tradeoff.py [OUT]     (default OUT: results/tilt_hybrid_arm-tradeoff)

The hybrid arm of ``problems/tilt_hybrid_arm.toml`` (counter-masses M1, M2 and springs k1,
k2) on a base that rolls and pitches by ±φ. Exact balance over any tilt range needs the full
counter-masses (the engine's design of the file, 16.95 kg). With less, the springs can only
come close: for each tilt range φ and each share s of the full counter-masses (M1 and M2
fixed at s × their full values), the engine designs the springs (its closest design: least
squares over the tilt grid) and the dense check (each configuration at its worst tilt) gives the worst residual
ratio. Writes ``tradeoff.csv`` (one row per φ and s) and ``tradeoff.png``: the added mass
needed against the tilt range for a few residual budgets, and the residual against the
added mass for a few tilt ranges. Every figure comes from the engine; nothing is fitted.
"""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FILE = ROOT / "problems" / "tilt_hybrid_arm.toml"
TILTS_DEG = (0.0, 1.0, 2.0, 3.0, 5.0, 7.5, 10.0, 12.5, 15.0, 20.0)
SHARES = tuple(np.round(np.linspace(0.0, 1.0, 21), 3))
BUDGETS = (0.01, 0.02, 0.05, 0.10)  # worst residual ratio accepted
SAMPLES = 2000  # dense-check configurations per point (the committed designs use 10,000)


def problem_text(phi_deg: float) -> str:
    text = FILE.read_text(encoding="utf-8")
    start = text.index("tilt = [")
    end = text.index("]\n\n", start) + 2
    tilt = (
        f'tilt = [{{ axis = [1, 0, 0], range = ["{-phi_deg} deg", "{phi_deg} deg"] }}, '
        f'{{ axis = [0, 0, 1], range = ["{-phi_deg} deg", "{phi_deg} deg"] }}]\n\n'
    )
    return text[:start] + tilt + text[end:] + f"\n[settings]\nverify_samples = {SAMPLES}\n"


def main(out: Path) -> None:
    from counterpoise.io.loader import load_problem_text
    from counterpoise.pipeline import build_method, run
    from counterpoise.plots._mpl import pyplot, save
    from counterpoise.report.files import atomic_write_text

    full = {}
    rows = []
    for phi in TILTS_DEG:
        problem = load_problem_text(problem_text(phi), str(FILE))
        method = build_method(problem)
        exact = run(method)
        values = {slot.variable: v for slot, v in exact.solution.values.items()}
        if phi > 0:
            full = {"M1": values["M1"], "M2": values["M2"]}
        rows.append({"tilt_deg": phi, "share": "exact", "added_mass_kg": values["M1"] + values["M2"],
                     "k1_N_per_m": values["k1"], "k2_N_per_m": values["k2"], "residual_ratio": exact.verification.residual_ratio,
                     "status": exact.status.value})
    for phi in TILTS_DEG:
        problem = load_problem_text(problem_text(phi), str(FILE))
        method = build_method(problem)
        for s in SHARES:
            pinned = {name: (s * full[name], s * full[name]) for name in ("M1", "M2")}
            r = run(method, bounds=pinned)
            values = {slot.variable: v for slot, v in r.solution.values.items()}
            rows.append({"tilt_deg": phi, "share": float(s), "added_mass_kg": values["M1"] + values["M2"],
                         "k1_N_per_m": values["k1"], "k2_N_per_m": values["k2"], "residual_ratio": r.verification.residual_ratio,
                         "status": r.status.value})
        print(f"tilt ±{phi:g} deg: done", file=sys.stderr)
    out.mkdir(parents=True, exist_ok=True)
    columns = list(rows[0])
    lines = [",".join(columns)] + [",".join(f"{row[c]:.9g}" if isinstance(row[c], float) else str(row[c]) for c in columns) for row in rows]
    atomic_write_text(out / "tradeoff.csv", "\n".join(lines) + "\n")

    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    swept = [r for r in rows if r["share"] != "exact"]
    for budget in BUDGETS:
        needed = []
        for phi in TILTS_DEG:
            ok = [r["added_mass_kg"] for r in swept if r["tilt_deg"] == phi and r["residual_ratio"] <= budget]
            needed.append(min(ok) if ok else math.nan)
        left.plot(TILTS_DEG, needed, marker="o", label=f"worst residual ≤ {100 * budget:g} %")
    exact_rows = [r for r in rows if r["share"] == "exact"]
    left.step([r["tilt_deg"] for r in exact_rows], [r["added_mass_kg"] for r in exact_rows], where="pre", color="black", linestyle="--", label="exact balance")
    left.set_xlabel("tilt range ±φ about both horizontal axes [deg]")
    left.set_ylabel("added counter-mass needed [kg]")
    left.set_title("counter-mass needed against the tilt range")
    left.legend(fontsize=8)
    left.grid(alpha=0.3)
    for phi in (2.0, 5.0, 10.0, 15.0):
        pts = sorted((r["added_mass_kg"], r["residual_ratio"]) for r in swept if r["tilt_deg"] == phi)
        right.semilogy([p[0] for p in pts], [max(p[1], 1e-16) for p in pts], marker=".", label=f"±{phi:g}°")
    right.set_xlabel("added counter-mass [kg] (springs designed for the rest)")
    right.set_ylabel("worst residual ratio over the tilt range")
    right.set_title("what each kilogram buys")
    right.legend(fontsize=8, title="tilt range")
    right.grid(alpha=0.3, which="both")
    fig.suptitle("tilt_hybrid_arm: counter-masses against springs on a tilting base", fontsize=10)
    fig.tight_layout()
    save(fig, out / "tradeoff.png")
    print(f"wrote {out / 'tradeoff.csv'} and {out / 'tradeoff.png'}", file=sys.stderr)


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "results" / "tilt_hybrid_arm-tradeoff")
