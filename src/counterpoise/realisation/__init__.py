"""The realisation layer: springs that can be built as specified and balance as built.

- :mod:`.limits`: the realisation limits of a design's springs over its workspace
  (clearance, slack, wrap, plane, the spring itself) and the constraints that keep them;
- :mod:`.method`: :class:`~.method.RealisationMethod`, the design method that adds those
  constraints in rounds, re-solves for the wound rates and judges what is buildable.

See docs/build.md#realisation-limits.
"""
