"""The project's own error classes.

Every error a user can cause by writing a problem file is a :class:`ProblemFileError`,
whose ``str()`` is one line: ``<file>: <key>: <message>``. The CLI prints that line and
exits with status 2.
"""

from __future__ import annotations


class CounterpoiseError(Exception):
    """Base class of every error raised on purpose by counterpoise."""


class ProblemFileError(CounterpoiseError):
    """A problem file is unreadable or invalid.

    ``key`` is the dotted path of the offending entry (``frames.link_b.parent``) or, for a
    TOML syntax error, ``line N``.
    """

    def __init__(self, file: str, key: str, message: str) -> None:
        self.file = file
        self.key = key
        self.message = " ".join(str(message).split())  # always one line
        super().__init__(f"{file}: {key}: {self.message}")


class InputError(CounterpoiseError):
    """A value found while resolving a problem is invalid; the loader adds file and key.

    Raised by the layers below the loader (units, expressions), which know neither the
    file nor the key; :mod:`counterpoise.loader` turns it into a :class:`ProblemFileError`.
    """


class ExpressionError(InputError):
    """An expression uses forbidden syntax, an unknown name or inconsistent units."""


class UnitError(InputError):
    """A quantity has an unknown unit or the wrong dimension."""


class SolverError(CounterpoiseError):
    """The numerical machinery failed in a way that is not a property of the design."""
