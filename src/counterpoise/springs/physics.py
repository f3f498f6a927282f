"""The formulas of a helical extension spring with machine hooks (SI units, numpy-vectorised).

Shigley's Mechanical Engineering Design, ch. 10 (§10-2 stresses, §10-3 deflection,
§10-4 materials, §10-11 extension springs); each function names its equation (S1)-(S12)
as numbered and derived in docs/springs.md. d wire diameter, D mean coil diameter,
C = D/d the spring index, N_b body coils, N_a active coils, F force.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .materials import Material

#: the winding rules: spring index range
C_MIN, C_MAX = 4.0, 12.0


def tensile_strength(mat: Material, d: Any) -> Any:
    """Sut (Pa) of wire of diameter d (m): Sut = A / d^m, d in mm (S1; Shigley table 10-4)."""
    return mat.A / (d * 1e3) ** mat.m * 1e6


def bergstrasser(C: Any) -> Any:
    """Curvature and direct-shear correction K_B = (4C + 2) / (4C − 3) (S2)."""
    return (4.0 * C + 2.0) / (4.0 * C - 3.0)


def hook_bending_factor(C1: Any) -> Any:
    """(K)_A = (4C1² − C1 − 1) / (4 C1 (C1 − 1)), C1 = 2 r1 / d (S8)."""
    return (4.0 * C1**2 - C1 - 1.0) / (4.0 * C1 * (C1 - 1.0))


def hook_torsion_factor(C2: Any) -> Any:
    """(K)_B = (4C2 − 1) / (4C2 − 4), C2 = 2 r2 / d (S9)."""
    return (4.0 * C2 - 1.0) / (4.0 * C2 - 4.0)


#: standard machine-hook proportions: bend radius r1 = D/2 (C1 = C), side bend r2 = 2d (C2 = 4); docs/springs.md
HOOK_R2_PER_D = 2.0


def active_coils(mat: Material, d: Any, body_coils: Any) -> Any:
    """N_a = N_b + G/E: the hooks add G/E of a coil (S5), G and E of the wire's size (S1)."""
    return body_coils + mat.shear_modulus(d) / mat.youngs_modulus(d)


def rate(mat: Material, d: Any, D: Any, Na: Any) -> Any:
    """k = G d⁴ / (8 D³ N_a) (S4), G of the wire's size (S1)."""
    return mat.shear_modulus(d) * d**4 / (8.0 * D**3 * Na)


def shear_stress(F: Any, d: Any, D: Any) -> Any:
    """Largest body shear stress τ = K_B · 8 F D / (π d³) (S3)."""
    return bergstrasser(D / d) * 8.0 * F * D / (math.pi * d**3)


def force_at_shear(tau: Any, d: Any, D: Any, C: Any) -> Any:
    """The force at which the body shear stress reaches ``tau`` (S3 solved for F)."""
    return tau * math.pi * d**3 / (8.0 * bergstrasser(C) * D)


def hook_bending_stress(F: Any, d: Any, D: Any) -> Any:
    """Bending plus tension at the hook's bend, r1 = D/2: σ_A = F [(K)_A 16 D/(π d³) + 4/(π d²)] (S8)."""
    return F * (hook_bending_factor(D / d) * 16.0 * D / (math.pi * d**3) + 4.0 / (math.pi * d**2))


def hook_torsion_stress(F: Any, d: Any, D: Any) -> Any:
    """Torsion at the hook's side bend, r2 = 2d: τ_B = (K)_B 8 F D / (π d³) (S9)."""
    return hook_torsion_factor(2.0 * HOOK_R2_PER_D) * 8.0 * F * D / (math.pi * d**3)


def initial_stress_mid(C: Any) -> Any:
    """Middle of the preferred (windable) band of uncorrected initial stress, Pa (S7):
    τ_i = 231 / exp(0.105 C) ± 6.9 (4 − (C − 3)/6.5) MPa; the band is symmetric."""
    return 231.0e6 * np.exp(-0.105 * C)


def initial_stress_half_band(C: Any) -> Any:
    """Half-width of the preferred initial-stress band, Pa (S7)."""
    return 6.9e6 * (4.0 - (C - 3.0) / 6.5)


def tension_of_stress(tau: Any, d: Any, D: Any) -> Any:
    """Force of an uncorrected shear stress: F = π d³ τ / (8 D) (S7)."""
    return math.pi * d**3 * tau / (8.0 * D)


def body_length(d: Any, body_coils: Any) -> Any:
    """Close-wound body: L_b = (N_b + 1) d (S6)."""
    return (body_coils + 1.0) * d


def free_length(d: Any, D: Any, body_coils: Any) -> Any:
    """Inside the two machine hooks: L0 = (N_b + 1) d + 2 (D − d) (S6)."""
    return (body_coils + 1.0) * d + 2.0 * (D - d)


def mass(mat: Material, d: Any, D: Any, body_coils: Any) -> Any:
    """The spring's own mass: body coils plus each hook counted as one coil of diameter D (S11)."""
    wire_length = math.pi * D * (body_coils + 2.0)
    return mat.density * math.pi * d**2 / 4.0 * wire_length
