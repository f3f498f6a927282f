"""Timing benchmark for counterpoise: warm-process phases and the CLI end to end.

Run from anywhere (normally from the repository root, or through ``make bench``)::

    python benchmarks/bench_solve.py              # plain-text tables
    python benchmarks/bench_solve.py --markdown   # Markdown tables (for benchmarks/README.md)

Targets (reported, not asserted):

(a) every problem in ``problems/*.toml`` solves in < 50 ms in a warm process;
(b) ``counterpoise solve FILE`` on one file takes < 2 s end to end in a fresh process.

Part 1, one warm process: for every problem, after one untimed warm-up pass, each phase is
timed on its own ``--repeats`` times (median and min): ``load_problem``; ``Designer(problem)``
(formulation, rank compression, ``nlpsol``); ``designer.solve()`` reusing the built solver;
``verify(solution)`` (10,000 random configurations); the full ``design(problem, designer)``
(solve + verify + report quantities); and ``write_reports`` into a temporary folder.

Part 2, fresh processes: ``counterpoise solve FILE --out TMP`` per problem (one discarded
warm-up run for the OS file cache, then the median of ``--cli-runs``), ``counterpoise --help``,
a bare ``python -c pass`` for interpreter start-up, a per-phase breakdown of one solve in a
fresh interpreter, and ``python -X importtime`` of a full CLI solve, summed by top-level
package to name the big imports.

Only the standard library and numpy are used; warm phases are CPU seconds of the process
(``time.process_time``), fresh processes are wall seconds (``time.perf_counter``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
PROBLEMS = ROOT / "problems"
SRC = ROOT / "src"

TARGET_SOLVE_S = 0.050
TARGET_CLI_S = 2.0

# Measure this checkout's sources (COUNTERPOISE_BENCH_SRC=path to measure others), in the subprocesses too.
SRC = Path(os.environ.get("COUNTERPOISE_BENCH_SRC", SRC)).resolve()
sys.path.insert(0, str(SRC))
FROM_SOURCE = True


# --------------------------------------------------------------------------- helpers


def timed(fn, *args, **kwargs):
    """(CPU seconds of this process, return value) of one call: robust on a shared machine,
    and equal to wall time when nothing else runs (BLAS is limited to one thread)."""
    t0 = time.process_time()
    value = fn(*args, **kwargs)
    return time.process_time() - t0, value


def summary(samples: list[float]) -> dict[str, float]:
    a = np.asarray(samples, dtype=float)
    return {"median": float(np.median(a)), "min": float(a.min()), "max": float(a.max()), "n": int(a.size)}


def ms(seconds: float) -> str:
    return f"{1e3 * seconds:.1f}" if seconds < 10 else f"{1e3 * seconds:.0f}"


def table(headers: list[str], rows: list[list[str]], markdown: bool, right: set[int] | None = None) -> str:
    right = right if right is not None else set(range(1, len(headers)))
    if markdown:
        sep = ["---:" if i in right else "---" for i in range(len(headers))]
        lines = ["| " + " | ".join(headers) + " |", "| " + " | ".join(sep) + " |"]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        return "\n".join(lines)
    widths = [max(len(str(x)) for x in col) for col in zip(headers, *rows)]

    def fmt(r: list[str]) -> str:
        return "  ".join(str(x).rjust(w) if i in right else str(x).ljust(w) for i, (x, w) in enumerate(zip(r, widths)))

    return "\n".join([fmt(headers), "  ".join("-" * w for w in widths)] + [fmt(r) for r in rows])


def cli_command() -> list[str]:
    exe = Path(sys.executable).parent / "counterpoise"
    if exe.exists():
        return [str(exe)]
    found = shutil.which("counterpoise")
    if found:
        return [found]
    return [sys.executable, "-c", "from counterpoise.cli import main; main()"]


def run(cmd: list[str], marks: list[float] | None = None, env: dict[str, str] | None = None) -> tuple[float, subprocess.CompletedProcess]:
    """Wall time of one subprocess; ``marks`` receives its start and end perf_counter values."""
    env = dict(os.environ if env is None else env)
    if FROM_SOURCE:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(SRC), env.get("PYTHONPATH")]))
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env)
    t1 = time.perf_counter()
    if marks is not None:
        marks[:] = [t0, t1]
    return t1 - t0, proc


# --------------------------------------------------------------------------- part 1: warm process


def bench_warm(files: list[Path], repeats: int) -> dict:
    from counterpoise.designer.designer import Designer
    from counterpoise.io.loader import load_problem
    from counterpoise.pipeline import design
    from counterpoise.report.files import write_reports
    from counterpoise.verify.check import verify

    out: dict = {"problems": {}}
    with tempfile.TemporaryDirectory(prefix="counterpoise-bench-") as tmp:
        for path in files:
            rel = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
            # warm-up pass (the first problem's pass also pays pint's registry, CasADi plugin loading, pandas...)
            first = {}
            first["load"], problem = timed(load_problem, path)
            first["build"], designer = timed(Designer, problem)
            first["solve"], solution = timed(designer.solve)
            first["verify"], _ = timed(verify, solution)
            first["design"], result = timed(design, problem, designer)
            first["report"], _ = timed(write_reports, result, tmp)

            t: dict[str, list[float]] = defaultdict(list)
            ipopt_internal, iterations = [], set()
            for _ in range(repeats):
                t["load"].append(timed(load_problem, path)[0])
            for _ in range(repeats):
                t["build"].append(timed(Designer, problem)[0])
            for _ in range(repeats):
                dt, solution = timed(designer.solve)
                t["solve"].append(dt)
                ipopt_internal.append(solution.stats.solve_time)
                iterations.add(solution.stats.iterations)
            for _ in range(repeats):
                t["verify"].append(timed(verify, solution)[0])
            for _ in range(repeats):
                dt, result = timed(design, problem, designer)
                t["design"].append(dt)
            for _ in range(repeats):
                t["report"].append(timed(write_reports, result, tmp)[0])

            out["problems"][str(rel)] = {
                "name": problem.name,
                "status": result.status.value,
                "iterations": sorted(iterations),
                "conditions": solution.stats.conditions,
                "slots": len(designer.formulation.design),
                "configurations": result.verification.configurations,
                "first": first,
                "phases": {k: summary(v) for k, v in t.items()},
                "ipopt_internal": summary(ipopt_internal),
            }
    return out


# --------------------------------------------------------------------------- part 2: fresh processes

BREAKDOWN = r"""
import time
T_START = time.perf_counter()
import json, os, sys, tempfile
t = {}
def step(name, fn, *a):
    t0 = time.perf_counter(); v = fn(*a); t[name] = time.perf_counter() - t0; return v
def _cli():
    import counterpoise.cli
def _modules():
    from counterpoise.threads import limit_blas_environment
    limit_blas_environment()  # as the command line does before numpy is imported
    import counterpoise.cli.app, counterpoise.pipeline, counterpoise.io.loader, counterpoise.report.files
step('import counterpoise.cli (light entry point)', _cli)
step('import solve modules (typer, rich, numpy, pydantic, schema...)', _modules)
from counterpoise.model import units
from counterpoise.designer.quantities import evaluate_quantities
from counterpoise.pipeline import design
from counterpoise.io.loader import load_problem
from counterpoise.designer.designer import Designer
from counterpoise.report.files import write_reports
from counterpoise.verify.check import verify
# one-time costs that the phases below would otherwise pay on first use
step('import pint + build unit registry', getattr(units, 'ureg', lambda: None))
step('import casadi', lambda: __import__('casadi'))
problem = step('load_problem', load_problem, sys.argv[1])
designer = step('Designer build', Designer, problem)
solution = step('designer.solve()', designer.solve)
step('verify', verify, solution)
step('report quantities', evaluate_quantities, solution)
t0 = time.perf_counter()
result = design(problem, designer)  # repeats solve + verify + quantities only to get a DesignResult
duplicate = time.perf_counter() - t0
with tempfile.TemporaryDirectory() as tmp:
    step('write_reports', write_reports, result, tmp)
print(json.dumps({"phases": t, "duplicate": duplicate, "t_start": T_START, "t_end": time.perf_counter()}))
sys.stdout.flush()
os._exit(0)  # as the command line ends after solve (counterpoise.cli)
"""

IMPORT_LINE = re.compile(r"^import time:\s+(\d+)\s*\|\s*(\d+)\s*\|( *)(\S+)\s*$")


def parse_importtime(stderr: str) -> dict:
    """Total import time and self-time per top-level package from ``-X importtime`` output."""
    by_root: dict[str, float] = defaultdict(float)
    total = 0.0
    for line in stderr.splitlines():
        m = IMPORT_LINE.match(line)
        if not m:
            continue
        self_us, cum_us, indent, name = int(m[1]), int(m[2]), len(m[3]), m[4]
        by_root[name.split(".")[0].lstrip("_") or name] += self_us * 1e-6
        if indent <= 1:  # top level of the import tree
            total += cum_us * 1e-6
    ranked = sorted(by_root.items(), key=lambda kv: -kv[1])
    return {"total": total, "by_package": ranked}


def bench_cli(files: list[Path], runs: int) -> dict:
    cmd = cli_command()
    out: dict = {"command": cmd, "solve": {}, "failures": []}
    with tempfile.TemporaryDirectory(prefix="counterpoise-bench-cli-") as tmp:
        for path in files:
            rel = str(path.relative_to(ROOT) if path.is_relative_to(ROOT) else path)
            run(cmd + ["solve", str(path), "--out", tmp])  # warm-up: OS file cache, .pyc files
            samples = []
            for _ in range(runs):
                dt, proc = run(cmd + ["solve", str(path), "--out", tmp])
                samples.append(dt)
                if proc.returncode != 0:
                    out["failures"].append(f"{rel}: exit {proc.returncode}: {(proc.stderr or proc.stdout).strip()[-300:]}")
            out["solve"][rel] = summary(samples)

        # The same with a bytecode cache for every module (PYTHONDONTWRITEBYTECODE=1 in the
        # environment, or a source tree without __pycache__, recompiles counterpoise each run).
        target = files[-1]
        rel = str(target.relative_to(ROOT) if target.is_relative_to(ROOT) else target)
        with tempfile.TemporaryDirectory(prefix="counterpoise-bench-pyc-") as pyc:
            env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
            env["PYTHONPYCACHEPREFIX"] = pyc
            run(cmd + ["solve", str(target), "--out", tmp], env=env)  # warm-up fills the cache
            out["solve_pyc"] = (rel, summary([run(cmd + ["solve", str(target), "--out", tmp], env=env)[0] for _ in range(runs)]))

        out["help"] = summary([run(cmd + ["--help"])[0] for _ in range(runs)])
        out["python"] = summary([run([sys.executable, "-c", "pass"])[0] for _ in range(runs)])

        # where a fresh process spends its time (last file; hybrid = slowest verify)
        out["breakdown_file"] = str(target.relative_to(ROOT) if target.is_relative_to(ROOT) else target)
        steps = []
        for _ in range(3):
            marks: list[float] = []
            dt, proc = run([sys.executable, "-c", BREAKDOWN, str(target)], marks)
            if proc.returncode != 0:
                out["failures"].append(f"breakdown: {proc.stderr.strip()[-300:]}")
                continue
            data = json.loads(proc.stdout.strip().splitlines()[-1])
            # perf_counter is CLOCK_MONOTONIC on Linux, shared between processes: start-up and
            # exit can be read off directly; elsewhere they are lumped into one remainder.
            startup, shutdown = data["t_start"] - marks[0], marks[1] - data["t_end"]
            if not (0 <= startup <= dt and 0 <= shutdown <= dt):
                startup = shutdown = None
            steps.append({"wall": dt, "phases": data["phases"], "duplicate": data["duplicate"], "startup": startup, "shutdown": shutdown})
        if steps:
            out["breakdown"] = sorted(steps, key=lambda s: s["wall"])[len(steps) // 2]

        # -X importtime of `import counterpoise.cli` and of a whole CLI solve (incl. lazy imports)
        _, proc = run([sys.executable, "-X", "importtime", "-c", "import counterpoise.cli"])
        out["import_cli"] = parse_importtime(proc.stderr)
        code = "import sys; from counterpoise.cli import main; sys.argv = ['counterpoise'] + sys.argv[1:]; main()"
        _, proc = run([sys.executable, "-X", "importtime", "-c", code, "solve", str(target), "--out", tmp])
        out["import_solve"] = parse_importtime(proc.stderr)
    return out


# --------------------------------------------------------------------------- report


def machine() -> dict[str, str]:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    info = {"cpu": cpu, "cores": str(os.cpu_count()), "python": platform.python_version(), "platform": platform.platform(),
            "PYTHONDONTWRITEBYTECODE": os.environ.get("PYTHONDONTWRITEBYTECODE", "")}
    from importlib.metadata import PackageNotFoundError, version

    for dist in ("casadi", "numpy", "pandas", "pint", "pydantic", "typer"):
        try:  # metadata only: importing them here would hide their import cost from the first calls
            info[dist] = version(dist)
        except PackageNotFoundError:
            info[dist] = "?"
    return info


def render(warm: dict, cli: dict | None, info: dict, markdown: bool, repeats: int, runs: int) -> str:
    h = (lambda s: f"\n### {s}\n") if markdown else (lambda s: f"\n== {s} ==\n")
    parts = []
    parts.append(
        ("" if markdown else "counterpoise benchmark\n")
        + f"machine: {info['cpu']}, {info['cores']} cores; Python {info['python']}; casadi {info['casadi']}, "
        f"numpy {info['numpy']}, pandas {info['pandas']}, pint {info['pint']}, pydantic {info['pydantic']}, typer {info['typer']}; "
        f"PYTHONDONTWRITEBYTECODE={info['PYTHONDONTWRITEBYTECODE'] or '(unset)'}"
    )

    parts.append(h(f"Warm process: median / min over {repeats} repeats, ms"))
    phases = [("load", "load_problem"), ("build", "Designer(...) build"), ("solve", "designer.solve()"),
              ("verify", "verify"), ("design", "design(p, d)"), ("report", "write_reports")]
    rows = []
    for rel, r in warm["problems"].items():
        p = r["phases"]
        rows.append([r["name"]] + [f"{ms(p[k]['median'])} / {ms(p[k]['min'])}" for k, _ in phases]
                    + [f"{ms(p['build']['median'] + p['design']['median'])}", f"{1 / p['design']['median']:.0f}",
                       ", ".join(map(str, r["iterations"])), r["status"]])
    parts.append(table(["problem"] + [label for _, label in phases] + ["build + design", "designs/s", "IPOPT iter", "status"], rows, markdown,
                       right=set(range(1, len(phases) + 4))))
    parts.append(
        ("\n" if markdown else "")
        + "design(p, d) = designer.solve() + verify + report quantities, with the prebuilt designer (designs/s = 1 / its median, one core); "
        "'build + design' (sum of medians) is what a warm process pays for a problem it has not built yet."
    )

    parts.append(h("First call in the process (warm-up pass), ms"))
    rows = [[r["name"]] + [ms(r["first"][k]) for k, _ in phases] for r in warm["problems"].values()]
    parts.append(table(["problem"] + [label for _, label in phases], rows, markdown))
    parts.append(("\n" if markdown else "") + "The first problem's first calls include one-time costs "
                 "(pint unit registry, CasADi/IPOPT plugin loading, lazy pandas import).")

    if cli:
        parts.append(h(f"Fresh process, wall time: median (min-max) of {runs} runs, s"))
        rows = []
        for rel, s in cli["solve"].items():
            rows.append([f"counterpoise solve {rel}", f"{s['median']:.3f}", f"{s['min']:.3f}-{s['max']:.3f}"])
        rel, s = cli["solve_pyc"]
        rows.append([f"counterpoise solve {rel}, with bytecode cache (PYTHONPYCACHEPREFIX)", f"{s['median']:.3f}", f"{s['min']:.3f}-{s['max']:.3f}"])
        rows.append(["counterpoise --help", f"{cli['help']['median']:.3f}", f"{cli['help']['min']:.3f}-{cli['help']['max']:.3f}"])
        rows.append(["python -c pass (interpreter start-up)", f"{cli['python']['median']:.3f}", f"{cli['python']['min']:.3f}-{cli['python']['max']:.3f}"])
        parts.append(table(["command", "median", "range"], rows, markdown))

        if "breakdown" in cli:
            b = cli["breakdown"]
            parts.append(h(f"Fresh-process breakdown of one solve ({cli['breakdown_file']}), ms"))
            rows = [[k, ms(v)] for k, v in b["phases"].items()]
            accounted = sum(b["phases"].values()) + b["duplicate"]
            if b["startup"] is not None:
                rows.insert(0, ["interpreter start-up (to first line of script)", ms(b["startup"])])
                rows.append(["interpreter exit (after last line)", ms(b["shutdown"])])
                accounted += b["startup"] + b["shutdown"]
            rows.append(["(not accounted for)", ms(b["wall"] - accounted)])
            rows.append(["wall (without the duplicate design() call)", ms(b["wall"] - b["duplicate"])])
            parts.append(table(["phase", "ms"], rows, markdown))

        for key, label in (("import_cli", "`import counterpoise.cli`"), ("import_solve", "whole `counterpoise solve` run")):
            imp = cli[key]
            top = ", ".join(f"{name} {ms(sec)}" for name, sec in imp["by_package"][:8])
            parts.append(("\n" if markdown else "") + f"-X importtime, {label}: {ms(imp['total'])} ms of imports; "
                         f"self time by package (ms): {top}")
        for f in cli["failures"]:
            parts.append(f"FAILURE: {f}")

    parts.append(h("Targets"))
    lines = []
    for r in warm["problems"].values():
        s = r["phases"]["solve"]["median"]
        d = r["phases"]["design"]["median"]
        bd = r["phases"]["build"]["median"] + d
        if s < TARGET_SOLVE_S:
            verdict = f"met, {ms(TARGET_SOLVE_S - s)} ms ({TARGET_SOLVE_S / s:.0f}x) under 50 ms"
        else:
            verdict = f"NOT met, {ms(s - TARGET_SOLVE_S)} ms over 50 ms"
        lines.append(
            f"(a) {r['name']}: designer.solve() {ms(s)} ms -> {verdict}; for comparison design(p, d) {ms(d)} ms "
            f"({'<' if d < TARGET_SOLVE_S else '>'} 50 ms), build + design {ms(bd)} ms ({'<' if bd < TARGET_SOLVE_S else '>'} 50 ms)"
        )
    if cli:
        for rel, s in cli["solve"].items():
            m = s["median"]
            verdict = f"met, {TARGET_CLI_S - m:.2f} s ({TARGET_CLI_S / m:.1f}x) under" if m < TARGET_CLI_S else f"NOT met, {m - TARGET_CLI_S:.2f} s over"
            lines.append(f"(b) counterpoise solve {rel}: {m:.3f} s -> {verdict} 2 s")
    parts.append("\n".join(("- " + ln if markdown else ln) for ln in lines))
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--markdown", action="store_true", help="print Markdown tables")
    ap.add_argument("--repeats", type=int, default=20, help="timed repeats per warm phase (default 20)")
    ap.add_argument("--cli-runs", type=int, default=5, help="fresh-process runs per CLI command (default 5)")
    ap.add_argument("--no-cli", action="store_true", help="skip the fresh-process (CLI) part")
    ap.add_argument("--json", type=Path, help="also write the raw figures to this JSON file")
    ap.add_argument("files", nargs="*", type=Path, help="problem files (default: problems/*.toml)")
    args = ap.parse_args(argv)

    files = [f.resolve() for f in args.files] or sorted(PROBLEMS.glob("*.toml"))
    if not files:
        print(f"no problem files in {PROBLEMS}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    info = machine()
    warm = bench_warm(files, args.repeats)
    cli = None if args.no_cli else bench_cli(files, args.cli_runs)
    print(render(warm, cli, info, args.markdown, args.repeats, args.cli_runs))
    print(f"\n(benchmark took {time.perf_counter() - t0:.0f} s)")
    if args.json:
        args.json.write_text(json.dumps({"machine": info, "warm": warm, "cli": cli}, indent=2, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
