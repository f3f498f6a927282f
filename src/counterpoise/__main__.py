"""``python -m counterpoise``: the console script ``counterpoise`` (see :mod:`counterpoise.cli`)."""

from .cli import main

if __name__ == "__main__":
    main()
