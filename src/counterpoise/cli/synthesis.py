"""``counterpoise synthesise FILE``: load the file, check its ``[synthesis]`` table and the
output folder, synthesise (:func:`counterpoise.synthesis.synthesise`), write the folder
and print what was found and proven. Exit status: 0 every minimal topology found and
verified; 1 the superstructure cannot balance exactly (the unbalanced terms are named),
a search hit its time limit, or a topology failed the engine's verification; 2 bad input."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

Err = Callable[[str], None]


def run_synthesise(file: Path, out: Path, overrides: Mapping[str, object], refine: bool, html: bool, err: Err, say: Err) -> int:
    from ..errors import CounterpoiseError, ProblemFileError
    from ..io.loader import apply_overrides
    from .run import load_all, out_error

    problems = load_all([file], overrides, err)
    if problems is None:
        return 2
    (problem,) = problems
    if problem.synthesis is None:
        err(f"{file}: synthesis: missing: add a [synthesis] table (the elements a balancer may be made of, docs/synthesis.md)")
        return 2
    wrong = out_error(out)
    if wrong is not None:
        err(wrong)
        return 2
    import sys

    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    raw = apply_overrides(tomllib.loads(file.read_text(encoding="utf-8")), overrides, str(file))
    from ..synthesis import synthesise, write_synthesis

    try:
        result = synthesise(problem, raw, refine)
    except ProblemFileError as exc:
        err(str(exc))
        return 2
    except CounterpoiseError as exc:
        err(f"{problem.path}: {exc}")
        return 1
    try:
        folder = write_synthesis(result, out, html=html)
    except OSError as exc:
        err(f"{problem.path}: cannot write the synthesis to {out}: {exc.strerror or exc}")
        return 1
    say(f"{problem.name}: {result.status}: {result.message}")
    say(f"{problem.name}: {result.proof}")
    for t in result.topologies:
        say(f"  {t.rank}. {', '.join(t.labels)}: {t.result.status.value}, added mass {t.result.solution.added_mass:.6g} kg, residual ratio {t.result.verification.residual_ratio:.2e} ({t.note})")
    for name, value in result.unbalanced:
        say(f"  unbalanced: {name}: {value:+.6g} J")
    say(f"synthesis in {folder}/ ({result.seconds:.1f} s)")
    return 0 if result.status == "optimal" else 1
