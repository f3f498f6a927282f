"""The superstructure: element classes (a spring between two bodies, a counter-mass at a
site) and the features each class's energy is a linear combination of.

A zero-free-length spring between point a of frame A and point b of frame B stores

    ½ k |o_A + R_A a − o_B − R_B b|²
      = k ½|d|² + (k a)·(R_Aᵀ d) − (k b)·(R_Bᵀ d) − Σ_ij (k a_i b_j) (R_Aᵀ R_B)_ij + const,

with d = o_A − o_B (the constant ½k(|a|² + |b|²) never changes the balance). So its energy
is Σ_f w_f φ_f(q) over the 16 *features* φ = (½|d|², R_Aᵀ d, R_Bᵀ d, R_Aᵀ R_B) of the pair,
with weights w = (k, k a, −k b, −k a bᵀ): linear in (k, k a) once b is fixed, and in
(k, k b) once a is. A counter-mass M at s on frame A stores −M g·(o_A + R_A s): the four
features (−g·o_A, −R_Aᵀ g) with weights (M, M s), linear in (M, M s). The poses come
from the engine's own mechanics (:class:`~counterpoise.mechanics.energy.Mechanics`),
evaluated on whatever configurations the conditions need (:mod:`.conditions`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mechanics.energy import Mechanics
from ..model.mechanism import GROUND
from ..model.synthesis import Region, SynthesisSpec, pair_label

SPRING, MASS = "spring", "counter-mass"
#: features of a spring class: ½|d|², R_Aᵀd (3), R_Bᵀd (3), R_AᵀR_B (9, row-major)
SPRING_FEATURES = 16
#: features of a counter-mass class: −g·o_A, −R_Aᵀg (3)
MASS_FEATURES = 4


@dataclass(frozen=True)
class ElementClass:
    """A kind of element the balancer may contain once: a spring between two bodies
    (``frames`` = (A, B)) or a counter-mass at a site (``frames`` = (A,))."""

    index: int
    kind: str
    name: str  # 'ground-link_a' or the site's name
    frames: tuple[str, ...]
    regions: tuple[Region, ...]
    subsystem: str
    cost: float

    @property
    def features(self) -> int:
        return SPRING_FEATURES if self.kind == SPRING else MASS_FEATURES

    @property
    def label(self) -> str:
        """'spring ground-link_a', 'counter-mass cm_b'."""
        return f"{self.kind} {self.name}"


def element_classes(spec: SynthesisSpec) -> tuple[ElementClass, ...]:
    """Every class of the superstructure: the springs' pairs, then the sites."""
    out: list[ElementClass] = []
    for a, b in spec.pairs:
        first, second = spec.attachment(a), spec.attachment(b)
        sub = first.subsystem or second.subsystem or ""
        out.append(ElementClass(len(out), SPRING, pair_label((a, b)), (a, b), (first.region, second.region), sub, spec.spring_cost))
    for site in spec.sites:
        out.append(ElementClass(len(out), MASS, site.name, (site.frame,), (site.region,), site.subsystem or "", spec.mass_cost))
    return tuple(out)


def _pose(mech: Mechanics, frame: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """World rotation (n, 3, 3) and origin (n, 3) of ``frame`` at ``n`` configurations."""
    if frame == GROUND:
        return np.broadcast_to(np.eye(3), (n, 3, 3)), np.zeros((n, 3))
    rot, origin = mech.pose(frame)
    r = np.empty((n, 3, 3))
    for i in range(3):
        for j in range(3):
            r[:, i, j] = np.real(np.broadcast_to(np.asarray(rot[i][j], dtype=float), (n,)))
    o = np.stack([np.broadcast_to(np.asarray(v, dtype=float), (n,)) for v in origin], axis=1)
    return r, o


def class_features(mech: Mechanics, cls: ElementClass, n: int, gravity: np.ndarray) -> np.ndarray:
    """The features of ``cls`` at the ``n`` configurations ``mech`` holds: (n, features)."""
    if cls.kind == SPRING:
        ra, oa = _pose(mech, cls.frames[0], n)
        rb, ob = _pose(mech, cls.frames[1], n)
        d = oa - ob
        out = np.empty((n, SPRING_FEATURES))
        out[:, 0] = 0.5 * np.einsum("ni,ni->n", d, d)
        out[:, 1:4] = np.einsum("nji,nj->ni", ra, d)
        out[:, 4:7] = np.einsum("nji,nj->ni", rb, d)
        out[:, 7:16] = np.einsum("nki,nkj->nij", ra, rb).reshape(n, 9)
        return out
    ra, oa = _pose(mech, cls.frames[0], n)
    out = np.empty((n, MASS_FEATURES))
    out[:, 0] = -oa @ gravity
    out[:, 1:4] = -np.einsum("nji,j->ni", ra, gravity)
    return out


def feature_scales(features: np.ndarray, cls: ElementClass, gravity: np.ndarray) -> np.ndarray:
    """The size of each feature of ``cls`` (its largest value, but at least the size its
    kind of feature has: a length squared, a length, a rotation's 1), against which a
    coefficient counts as rounding noise."""
    g = max(float(np.linalg.norm(gravity)), 1.0)
    if cls.kind == SPRING:
        length = max(float(np.sqrt(2.0 * np.abs(features[:, 0]).max())) if len(features) else 0.0, 1e-3)
        floor = np.array([length**2] + [length] * 6 + [1.0] * 9)
    else:
        floor = np.array([g * max(float(np.abs(features[:, 0]).max()) / g if len(features) else 0.0, 1e-3)] + [g] * 3)
    return np.maximum(np.abs(features).max(axis=0) if len(features) else 0.0, floor)


def spring_weights(k: float, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The 16 weights of a spring of rate ``k`` from ``a`` (in A) to ``b`` (in B)."""
    return np.concatenate([[k], k * a, -k * b, -k * np.outer(a, b).ravel()])


def mass_weights(m: float, s: np.ndarray) -> np.ndarray:
    """The 4 weights of a counter-mass ``m`` at ``s``."""
    return np.concatenate([[m], m * s])


def region_arrays(region: Region) -> tuple[np.ndarray, np.ndarray]:
    """(origin (3,), axes as columns (3, m)) of a convex region."""
    origin = np.array(region.origin, dtype=float)
    axes = np.array(region.axes, dtype=float).reshape(-1, 3).T
    return origin, axes
