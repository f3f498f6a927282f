"""The realisation layer: springs that can be built as specified and balance as built.

- :mod:`.limits`: the realisation limits of a design's springs over its workspace
  (clearance, slack, wrap, plane, the spring itself) and the constraints that keep them;
- :mod:`.method`: :class:`~.method.RealisationMethod`, the design method that adds those
  constraints in rounds, re-solves for the wound rates and judges what is buildable;
- :mod:`.sheet` and :mod:`.asbuilt`: the build sheet and the balancer rebuilt from it;
- :mod:`.result`: what the layer finds (:class:`~.result.RealisationReport`,
  :class:`~.result.BuildCheck`, extras of the design); :mod:`.report`: ``springs.csv``,
  ``build.csv`` and its lines of ``status.txt``; :mod:`.layer`: its entry in the registry
  of layers (the build sheet and the verdict as built once a design is finished).

See docs/build.md#realisation-limits.
"""
