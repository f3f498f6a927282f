"""Loader fuzz: mutated problem files must load or fail with the project's own error.

Each example starts from one of the shipped files in ``problems/`` and applies a few
mutations of the kinds a user's editing produces: a line deleted, duplicated, moved or
replaced by a line of another file, a number changed (to zero, a negative, a huge or
non-finite value, a 400-digit integer), a unit changed (to another unit, a wrong one or an
unknown one), a string value replaced by a random expression over the files' names,
operators and functions, odd characters inserted (quotes, brackets, deep nesting, '#',
look-alike letters, control characters). Whatever the text, :func:`load_problem_text` must return a problem
or raise a :class:`~counterpoise.errors.CounterpoiseError` with one short line per error.

The run is bounded (``FUZZ_EXAMPLES``, 150 by default: a few seconds) and deterministic
under ``CI=1`` (the hypothesis profile in ``conftest.py``). For a longer hunt:
``FUZZ_EXAMPLES=5000 pytest tests/test_loader_fuzz.py``.
"""

from __future__ import annotations

import os
import re

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, Phase, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from counterpoise.errors import CounterpoiseError  # noqa: E402
from counterpoise.io.loader import load_problem_text  # noqa: E402
from conftest import PROBLEMS

TEXTS = [p.read_text(encoding="utf-8") for p in sorted(PROBLEMS.glob("*.toml"))]
LINES = [line for text in TEXTS for line in text.splitlines()]
EXAMPLES = int(os.environ.get("FUZZ_EXAMPLES", "150"))

NUMBER = re.compile(r"(?<![A-Za-z_\d.])[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")
UNIT = re.compile(r"(?<=\d )[A-Za-z°µ/^0-9*]+(?=\")")
STRING = re.compile(r'= "([^"\n]*)"')
NUMBERS = ["0", "-0", "-1", "1", "0.0", "1e-320", "1e308", "1e999", "-1e999", "nan", "inf", "1" * 400, "2.5", "1_000", "0x10", "1e", "."]
UNITS = ["mm", "m", "g", "kg", "t", "deg", "rad", "N/mm", "N/m", "m/s^2", "1/m^2", "s", "", "mmm", "°", "degC", "%", "kg*m", "1/0", "m**9999", "N/mm/mm", "inch", "m/s"]
TOKENS = ["M_a", "r_a", "b_b", "k", "rho_side", "m_endo", "theta_a", "x", "pi", "ground", "link_a", "total_mass(leg)", "com_distance(leg)",
          "+", "-", "*", "/", "**", "(", ")", "sqrt(", "log(", "asin(", "exp(", "abs(", "0", "1", "-1", "0.5", "1e308", "1e-308", " mm", " kg", " deg", " ", ","]
ODD = ["[" * 300 + "]" * 300, "#", '"', "'", "\\", "\x00", "\x7f", "\u2113", "\uff4d", "\u200b", "\u00a0", "{", "}", "[", "]", "=", ",", "\n", "\t", "**", "(", ")", "__", "sqrt(", "e", ".", "-", "\u03c0", "1e999", "[x]", "a.b", "lambda:", "\r"]


@st.composite
def mutated(draw: st.DrawFn) -> str:
    text = draw(st.sampled_from(TEXTS))
    for _ in range(draw(st.integers(1, 4))):
        lines = text.split("\n")
        kind = draw(st.sampled_from(["delete", "duplicate", "move", "replace", "number", "unit", "insert", "expression"]))
        i = draw(st.integers(0, len(lines) - 1))
        if kind == "delete":
            del lines[i]
        elif kind == "duplicate":
            lines.insert(i, lines[i])
        elif kind == "move":
            line = lines.pop(i)
            lines.insert(draw(st.integers(0, len(lines))), line)
        elif kind == "replace":
            lines[i] = draw(st.sampled_from(LINES))
        text = "\n".join(lines)
        if kind in ("number", "unit"):
            spans = [m.span() for m in (NUMBER if kind == "number" else UNIT).finditer(text)]
            if spans:
                a, b = draw(st.sampled_from(spans))
                text = text[:a] + draw(st.sampled_from(NUMBERS if kind == "number" else UNITS)) + text[b:]
        elif kind == "insert":
            at = draw(st.integers(0, len(text)))
            text = text[:at] + draw(st.sampled_from(ODD)) + text[at:]
        elif kind == "expression":
            spans = [m.span(1) for m in STRING.finditer(text)]
            if spans:
                a, b = draw(st.sampled_from(spans))
                text = text[:a] + "".join(draw(st.lists(st.sampled_from(TOKENS), min_size=1, max_size=7))) + text[b:]
    return text


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(text=mutated())
def test_mutated_files_load_or_fail_with_one_short_line(text):
    try:
        load_problem_text(text, "fuzz.toml")
    except CounterpoiseError as exc:
        # one line per error (a file with several mistakes gets several), each short
        lines = str(exc).split("\n")
        for line in lines:
            assert line.startswith("fuzz.toml: ") and len(line) <= len("fuzz.toml: ") + 600, line
        assert len(lines) == len(getattr(exc, "errors", (exc,)))


def test_the_mutations_reach_every_stage():
    """The fuzz is only worth something if mutants fail in every pass (TOML, schema,
    resolution) and some still load: check on a fixed sample."""
    from hypothesis import find

    def stage(text: str) -> str:
        try:
            load_problem_text(text, "fuzz.toml")
        except CounterpoiseError as exc:
            if "TOML syntax error" in str(exc):
                return "toml"
            if any(word in str(exc) for word in ("unknown key", "missing required key", "Input should")):
                return "schema"
            return "resolve"
        return "loads"

    # each stage must be reached within the first 500 derandomized mutants; the mutant found
    # is not used, so it is not shrunk (Phase.generate only): shrinking it cost ~97 % of this
    # test's time (9.9 s against 0.3 s CPU) and checks nothing more
    for wanted in ("toml", "schema", "resolve", "loads"):
        find(mutated(), lambda t: stage(t) == wanted, settings=settings(max_examples=500, database=None, derandomize=True, phases=[Phase.generate]))


def test_a_long_key_is_clipped_in_the_message_too():
    """The fuzz found it: a key built from input (a repeated frame's name made of 600
    brackets) was clipped in ``exc.key`` but printed whole in the message's line."""
    from counterpoise.errors import KEY_LIMIT, ProblemFileError

    exc = ProblemFileError("fuzz.toml", "frames.leg" + "[" * 600 + "i_2", "defined twice")
    assert str(exc) == f"fuzz.toml: {exc.key}: defined twice" and len(exc.key) <= KEY_LIMIT + 1
