"""Whether a catalogue's parts can be steel extension springs at all (its units' last check).

The column medians and the two ratios of :mod:`.columns` (``PLAUSIBLE``, ``DERIVED``) catch a
file read in the wrong units when its numbers land outside wide bands. An inch/lbf file of
weak springs read as N-mm does not: 0.114 lbf/in over 1.18 in read as 0.114 N/mm over
1.18 mm is a stiff, tiny spring, yet every median is in its band. What gives it away is the
relation of rate, free length and load that every helical extension spring obeys (Shigley,
Mechanical Engineering Design, ch. 10; docs/catalogues.md):

- rate k = G d / (8 C³ n) for wire diameter d, spring index C = D/d and n active coils;
- free length L0 ≥ (n + 1) d + 2 h (C − 1) d: the close-wound body and two hooks of at
  least ``HOOK`` times the coil's inner diameter each;
- load: the body's shear stress 8 K_W C F / (π d²) at the max load F at most
  ``LOAD_STRESS`` × Sut(d), Sut = A / d^m (the material's fit);
- initial tension F0 at most ``INITIAL_STRESS`` times the upper end of Shigley's preferred
  initial stress (eq. 10-41) times π d² / (8 C).

For a part's k and L0 the body and hooks leave room for a wire no thicker than d*(C) (the
root of G d² / (8 C³ k) + (1 + 2 h (C − 1)) d = L0); the thickest wire carries the most.
:func:`implausibility` is, for each part, the smallest over index, material and wire of the
largest of F / (what that spring carries), F0 / (its largest initial tension), d_min / d*
and n_min / n: ≤ 1 where some steel spring has the part's numbers, > 1 where none has.
Every bound is generous (index 3-20, two active coils, half hooks, 0.6 Sut where Shigley
allows 0.45, twice the preferred initial stress), so a real part stays well below 1 (the
shipped catalogue: at most 0.49) while a file in lbf and inch read as N and mm is 2-4
times beyond (its force per area is 145 times too high).
"""

from __future__ import annotations

import math
from typing import Any

#: the spring index C = D/d searched (Shigley recommends 4-12 for extension springs)
INDEX = (3.0, 20.0)
INDEX_STEPS = 69
#: the fewest active coils of a spring
MIN_ACTIVE_COILS = 2.0
#: each hook at least this fraction of the coil's inner diameter (a half loop)
HOOK = 0.5
#: the body stress at the max load at most this fraction of Sut (Shigley's static allowable: 0.45)
LOAD_STRESS = 0.6
#: the initial tension at most this multiple of Shigley's preferred upper initial stress
INITIAL_STRESS = 2.0
#: the wire diameters considered (m): the finest spring wire to the band's top (columns.PLAUSIBLE)
WIRE = (5e-5, 0.03)
#: psi in Pa (Shigley's initial-stress fit is in psi)
PSI = 6894.757293168
#: at most this many parts are judged (evenly spread over the file): the median is what counts
SAMPLE = 2000


def implausibility(rate: Any, free_length: Any, initial_tension: Any, max_load: Any) -> Any:
    """Per part (numpy arrays, SI): the smallest, over index, material and wire, of the
    largest ratio of what the part asks to what a steel extension spring of its rate and
    free length can give (see the module docstring); > 1: no such spring exists."""
    import numpy as np

    from ..springs.materials import materials

    k = np.asarray(rate, dtype=float)[:, None]
    length = np.asarray(free_length, dtype=float)[:, None]
    f0 = np.asarray(initial_tension, dtype=float)[:, None]
    load = np.asarray(max_load, dtype=float)[:, None]
    c = np.linspace(INDEX[0], INDEX[1], INDEX_STEPS)[None, :]
    wahl = (4 * c - 1) / (4 * c - 4) + 0.615 / c
    preferred = (33500 / np.exp(0.105 * c) + 1000 * (4 - (c - 3) / 6.5)) * PSI  # Shigley eq. 10-41, upper end
    best = np.full(k.shape[0], math.inf)
    for m in materials().values():
        a = m.shear_modulus(1e-3) / (8 * c**3 * k)  # n = a d (G of a 1 mm wire: a plausibility check)
        b = 1 + 2 * HOOK * (c - 1)
        d = np.minimum((-b + np.sqrt(b * b + 4 * a * length)) / (2 * a), WIRE[1])
        sut = m.A * 1e6 / (d * 1e3) ** m.m
        carries = np.pi * d * d * LOAD_STRESS * sut / (8 * c * wahl)
        tension = np.pi * d * d * INITIAL_STRESS * preferred / (8 * c)
        ratio = np.maximum.reduce([load / carries, f0 / tension, WIRE[0] / d, MIN_ACTIVE_COILS / (a * d)])
        best = np.minimum(best, ratio.min(axis=1))
    return best


def sample(count: int) -> list[int]:
    """At most :data:`SAMPLE` row indices, evenly spread over ``count`` rows."""
    if count <= SAMPLE:
        return list(range(count))
    return sorted({round(i * (count - 1) / (SAMPLE - 1)) for i in range(SAMPLE)})
