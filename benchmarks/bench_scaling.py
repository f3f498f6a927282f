"""Scaling benchmark: planar chains of 1 to 24 links, a counter-mass per link.

Run from anywhere::

    python benchmarks/bench_scaling.py                 # sizes 1 2 4 8 12 16 24, 3 runs each
    python benchmarks/bench_scaling.py --sizes 24 --runs 5 --markdown
    python benchmarks/bench_scaling.py --one 24        # one chain in this process (time it from outside)

Each (size, run) is a fresh Python process, so that its peak memory (``ru_maxrss``) is the
chain's own. In it: the problem is built in code (:class:`counterpoise.ProblemBuilder`),
then ``Designer(problem)`` (formulation, rank compression, IPOPT set-up), ``solve()``,
the first ``verify`` (which builds the per-problem residual arrays) and a second
``verify`` of the same design (what a study pays per design). Times are CPU seconds of
the process (``time.process_time``: robust on a shared machine) and wall seconds; the
table shows medians over the runs.

The chain: link i (0 at the base) is 0.2 m long and carries a body of 0.7^i kg at 0.1 m
from its joint; its counter-mass sits 0.12 m behind the joint, mass variable in
[0, 4 × the mass that balances it] (:func:`required_masses`). The balancing masses of the
24-link chain span ten orders of magnitude (1.9e10 from the base to the tip). ``--taper 1``
gives the uniform chain (every body 1 kg; span 1.4e10 at 24 links), whose balancers'
forces exceed the gravity load they cancel by 5e7: double rounding of the design itself
then leaves a residual ratio of about 2e-8 (see ``docs/performance.md``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LENGTH, COM, ARM = 0.2, 0.1, 0.12
TAPER = float(os.environ.get("COUNTERPOISE_BENCH_TAPER", "0.7"))  # --taper, passed to the child processes
DEFAULT_TAPER = TAPER

CHILD = r"""
import sys
sys.path.insert(0, sys.argv[2])
from bench_scaling import measure
measure(int(sys.argv[1]))
"""


def measure(n: int) -> None:
    """Build, solve and verify the n-link chain in this process; print one JSON line."""
    import json
    import resource
    import time

    from counterpoise.designer.designer import Designer
    from counterpoise.verify import judge, verify

    def timed(fn, *args):
        c0, w0 = time.process_time(), time.perf_counter()
        value = fn(*args)
        return value, time.process_time() - c0, time.perf_counter() - w0

    problem, build_cpu, build_wall = timed(lambda: chain_problem(n))
    designer, d_cpu, d_wall = timed(Designer, problem)
    solution, s_cpu, s_wall = timed(designer.solve)
    verification, v_cpu, v_wall = timed(verify, solution)
    _, v2_cpu, v2_wall = timed(verify, solution)
    status, message = judge(solution, verification)
    masses = [solution.values[k] for k in sorted(solution.values, key=lambda k: int(k.variable[1:]))]
    error = max(abs(m - r) / r for m, r in zip(masses, required_masses(n)))
    print(json.dumps({
        "n": n, "status": status.value, "message": message, "conditions": solution.stats.conditions,
        "iterations": solution.stats.iterations, "ratio": verification.residual_ratio, "mass_error": error,
        "span": max(required_masses(n)) / min(required_masses(n)),
        "cpu": {"problem": build_cpu, "build": d_cpu, "solve": s_cpu, "verify": v_cpu, "verify_again": v2_cpu},
        "wall": {"problem": build_wall, "build": d_wall, "solve": s_wall, "verify": v_wall, "verify_again": v2_wall},
        "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }))


def required_masses(n: int) -> list[float]:
    """Counter-mass of each link that puts its subtree's centre of mass on its joint (from
    the tip inwards: M_i·ARM = m_i·COM + W_{i+1}·LENGTH, W_{i+1} everything beyond joint i+1)."""
    out, carried = [0.0] * n, 0.0
    for i in range(n - 1, -1, -1):
        out[i] = (TAPER**i * COM + carried * LENGTH) / ARM
        carried += TAPER**i + out[i]
    return out


def chain_problem(n: int):
    """The n-link chain as a :class:`counterpoise.ProblemBuilder` problem."""
    from counterpoise import ProblemBuilder, rotate, translate

    b = ProblemBuilder(f"chain{n}", gravity="9.81 m/s^2", direction=(0, -1, 0))
    b.subsystem("arm", **{f"q{i}": ("-180 deg", "180 deg") for i in range(n)})
    parent = None
    for i, need in enumerate(required_masses(n)):
        steps = [rotate("z", f"q{i}")] if i == 0 else [translate(f"{LENGTH} m"), rotate("z", f"q{i}")]
        b.frame(f"l{i}", *steps, **({"parent": parent} if parent else {}))
        parent = f"l{i}"
        b.body(f"b{i}", frame=f"l{i}", mass=f"{TAPER**i!r} kg", com=(f"{COM} m", 0, 0))
        b.variable(f"M{i}", "0 kg", f"{4 * need!r} kg", initial=f"{2 * need!r} kg")
        b.counter_mass(f"c{i}", frame=f"l{i}", mass=f"M{i}", position=(f"-{ARM} m", 0, 0))
    b.objective(mass_weight=1, inertia_weight="0 1/m^2")
    return b.build(f"chain{n}.toml")


def run(n: int, src: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(src), env.get("PYTHONPATH")]))
    proc = subprocess.run([sys.executable, "-c", CHILD, str(n), str(Path(__file__).parent)], capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise RuntimeError(f"{n} links: {proc.stderr.strip()[-500:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1, 2, 4, 8, 12, 16, 24])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--taper", type=float, default=DEFAULT_TAPER, help="body mass ratio of consecutive links (default 0.7; 1 = uniform chain)")
    ap.add_argument("--src", type=Path, default=ROOT / "src", help="package sources to measure (default: this checkout's src)")
    ap.add_argument("--one", type=int, metavar="N", help="build, solve and verify the N-link chain in this process, print its JSON line")
    args = ap.parse_args(argv)
    os.environ["COUNTERPOISE_BENCH_TAPER"] = repr(args.taper)
    if args.one is not None:
        global TAPER
        TAPER = args.taper
        sys.path.insert(0, str(args.src))
        measure(args.one)
        return 0
    head = ["links", "status", "conditions", "IPOPT iter", "mass span", "build", "solve", "verify (first)", "verify (again)",
            "build+solve+verify", "wall", "peak MiB", "residual ratio"]
    rows = []
    for n in args.sizes:
        runs = [run(n, args.src) for _ in range(args.runs)]
        med = lambda kind, key: statistics.median(r[kind][key] for r in runs)  # noqa: E731
        total = med("cpu", "build") + med("cpu", "solve") + med("cpu", "verify")
        wall = statistics.median(r["wall"]["build"] + r["wall"]["solve"] + r["wall"]["verify"] for r in runs)
        r0 = runs[0]
        rows.append([str(n), r0["status"], str(r0["conditions"]), str(r0["iterations"]), f"{r0['span']:.1e}",
                     f"{med('cpu', 'build'):.3f}", f"{med('cpu', 'solve'):.3f}", f"{med('cpu', 'verify'):.3f}",
                     f"{med('cpu', 'verify_again'):.4f}", f"{total:.3f}", f"{wall:.3f}",
                     f"{statistics.median(r['peak_mib'] for r in runs):.0f}", f"{r0['ratio']:.1e}"])
        if r0["status"] != "optimal":
            rows[-1][1] += f" ({r0['message'][:60]})"
    if args.markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "|".join(["---"] * 2 + ["---:"] * (len(head) - 2)) + "|")
        for r in rows:
            print("| " + " | ".join(r) + " |")
    else:
        widths = [max(len(x) for x in col) for col in zip(head, *rows)]
        for r in [head, *rows]:
            print("  ".join(x.rjust(w) for x, w in zip(r, widths)))
    print(f"\ntimes: CPU seconds, median of {args.runs} fresh processes; wall = build+solve+verify wall seconds (median)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
