"""The type checking stays part of `make test` at the strictness docs/development.md states.

mypy itself runs in `make test` (before pytest, over all of src/: about a minute), not
here; these tests only read files, so that the set-up cannot drift silently.
"""

from __future__ import annotations

import re
import sys

from conftest import ROOT

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

IGNORE = re.compile(r"#\s*type:\s*ignore(?P<codes>\[[^\]]*\])?(?P<rest>.*)$")


def _pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))


def test_mypy_settings_are_the_stated_strictness():
    mypy = _pyproject()["tool"]["mypy"]
    assert mypy["files"] == ["src"]
    assert mypy["python_version"] == "3.10"  # the oldest Python the package supports
    for flag in ("disallow_untyped_defs", "disallow_incomplete_defs", "no_implicit_optional", "warn_unused_ignores", "strict_equality"):
        assert mypy[flag] is True, flag
    assert "ignore_missing_imports" not in mypy  # only per third-party module without types
    for override in mypy.get("overrides", []):
        assert all(not m.startswith("counterpoise") for m in override["module"])


def test_make_test_runs_mypy_before_pytest_and_the_test_extra_installs_it():
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    recipe = makefile.split("\ntest:", 1)[1].split("\n\n", 1)[0]
    assert "-m mypy" in recipe and "-m pytest" in recipe
    assert recipe.index("-m mypy") < recipe.index("-m pytest")
    extra = _pyproject()["project"]["optional-dependencies"]["test"]
    assert any(req.split(">")[0].split("=")[0].strip() == "mypy" for req in extra)


def test_every_type_ignore_names_its_error_code_and_a_reason():
    """A bare ``# type: ignore`` hides every error of its line; one without a reason cannot
    be judged; ``no-untyped-def`` would hide a missing annotation from disallow_untyped_defs."""
    bad = []
    for path in sorted((ROOT / "src").rglob("*.py")):
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            m = IGNORE.search(line)
            if m is None:
                continue
            where = f"{path.relative_to(ROOT)}:{number}"
            if not m.group("codes"):
                bad.append(f"{where}: no error code")
            elif "no-untyped-def" in m.group("codes"):
                bad.append(f"{where}: hides a missing annotation")
            elif not m.group("rest").strip().lstrip("#").strip():
                bad.append(f"{where}: no reason")
    assert not bad, "\n".join(bad)
