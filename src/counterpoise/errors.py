"""The project's own error classes.

Every error a user can cause by writing a problem file is a :class:`ProblemFileError`,
whose ``str()`` is one line: ``<file>: <key>: <message>``. The CLI prints that line and
exits with status 2. What a message repeats of the input is clipped (:func:`clip`), so a
line stays short however long the offending value is.
"""

from __future__ import annotations

import re

#: Longest piece of user input an error message repeats (longer input is cut, with '…').
ECHO_LIMIT = 200
#: Longest key and message of an error line.
KEY_LIMIT = 150
MESSAGE_LIMIT = 440

#: a quoted piece of input longer than ECHO_LIMIT (compiled on first use: only messages need it)
_QUOTED = r"'([^']{%d,})'" % (ECHO_LIMIT + 1)


def clip(text: str, limit: int = ECHO_LIMIT) -> str:
    """``text`` cut to ``limit`` characters, ending in '…' when cut."""
    return text if len(text) <= limit else text[: limit - 1] + "…"


def clip_quoted(message: str) -> str:
    """Every quoted piece of input in ``message`` ('...') cut to :data:`ECHO_LIMIT`."""
    return re.sub(_QUOTED, lambda m: f"'{clip(m.group(1))}'", message)


class CounterpoiseError(Exception):
    """Base class of every error raised on purpose by counterpoise."""


class ProblemFileError(CounterpoiseError):
    """A problem file is unreadable or invalid.

    ``key`` is the dotted path of the offending entry (``frames.link_b.parent``) or, for a
    TOML syntax error, ``line N``.
    """

    def __init__(self, file: str, key: str, message: str) -> None:
        self.file = file
        # always one line, and bounded: input echoed in a message is clipped
        self.key = clip(" ".join(str(key).split()), KEY_LIMIT)
        self.message = clip(clip_quoted(" ".join(str(message).split())), MESSAGE_LIMIT)
        super().__init__(f"{file}: {self.key}: {self.message}")


class InputError(CounterpoiseError):
    """A value found while resolving a problem is invalid; the loader adds file and key.

    Raised by the layers below the loader (units, expressions), which know neither the
    file nor the key; :mod:`counterpoise.io.loader` turns it into a :class:`ProblemFileError`.
    """


class ExpressionError(InputError):
    """An expression uses forbidden syntax, an unknown name or inconsistent units."""


class UnitError(InputError):
    """A quantity has an unknown unit or the wrong dimension."""


class SolverError(CounterpoiseError):
    """The numerical machinery failed in a way that is not a property of the design."""


class ProblemFileErrors(ProblemFileError):
    """Several independent errors of one file, one line each.

    ``key`` and ``message`` are the first error's (so code that handles one
    :class:`ProblemFileError` keeps working); ``errors`` holds them all and ``str()`` is
    one line per error. Use :func:`raise_errors` to raise a list of errors.
    """

    def __init__(self, errors: "list[ProblemFileError] | tuple[ProblemFileError, ...]") -> None:
        first = errors[0]
        super().__init__(first.file, first.key, first.message)
        self.errors = tuple(errors)

    def __str__(self) -> str:
        return "\n".join(str(e) for e in self.errors)


def raise_errors(errors: "list[ProblemFileError]") -> None:
    """Raise nothing for no error, the error itself for one, :class:`ProblemFileErrors` for more.

    The same line is reported once.
    """
    flat = [inner for e in errors for inner in (e.errors if isinstance(e, ProblemFileErrors) else (e,))]
    unique = list({str(e): e for e in flat}.values())
    if len(unique) == 1:
        raise unique[0]
    if unique:
        raise ProblemFileErrors(unique)
