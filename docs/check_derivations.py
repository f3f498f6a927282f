"""Re-derive every number quoted in docs/derivations.md from the papers' printed data.

Run:  python docs/check_derivations.py      (needs numpy only; exits 1 if a check fails)

Each check prints the value, the value it must round to, and OK/FAIL. Closed forms are the
ones written in docs/derivations.md; where a number relies on "balance for all q", an
independent brute-force check samples the total potential energy
V = gravity + 1/2 k |a - b|^2 on random configurations and reports its spread.
Units: g, mm, N/mm as in the papers; g = 9.81 m/s^2, so m[g] * 9.81e-3 is a weight in N.
"""

from __future__ import annotations

import sys

import numpy as np

G = 9.81  # m/s^2
W = G * 1e-3  # N per g: weight of 1 g in newton
FAILED: list[str] = []


def check(label: str, value: float, expected: float, tol: float) -> None:
    ok = abs(value - expected) <= tol
    print(
        f"  {'OK  ' if ok else 'FAIL'} {label:<58} {value:>14.6g}   (expect {expected:g} +- {tol:g})"
    )
    if not ok:
        FAILED.append(label)


def rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about a unit axis (Rodrigues)."""
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


X, Y, Z = np.eye(3)
RNG = np.random.default_rng(20240601)


# ----------------------------------------------------------------------------------------
def seed_001() -> None:
    print("001 Yasir 2019")
    m_c, r_a, r_b, r_c, b_a, b_b, b_c = 400.0, 135.0, 195.0, 200.0, 100.0, 80.0, 200.0
    M_c = m_c * r_c / b_c
    M_b = (m_c + M_c) * r_b / b_b
    M_a = (m_c + M_c + M_b) * r_a / b_a
    check("Table 1 M_c [g]", M_c, 400, 1e-9)
    check("Table 1 M_b [g]", M_b, 1950, 1e-9)
    check("Table 1 M_a [g]", M_a, 3712.5, 1e-9)
    check("Table 1 leg total [g]", M_a + M_b + M_c, 6062.5, 1e-9)
    check("Table 1 three legs [g]", 3 * (M_a + M_b + M_c), 18187.5, 1e-9)

    def leg(
        m_a,
        g_a,
        m_b,
        g_b,
        m_c,
        g_c,
        m_p,
        g_p,
        r_b,
        r_a=135.0,
        b_b=80.0,
        b_c=200.0,
        f=78.0,
    ):
        m_ct = m_c + m_p
        g_ct = (m_c * g_c + m_p * g_p) / m_ct
        M_c = m_ct * g_ct / b_c
        M_b = (m_b * g_b + (m_ct + M_c) * r_b) / b_b
        M_a = m_a + m_b + m_c + m_p + M_b + M_c
        g_at = (
            (m_b + m_c + m_p + M_c + M_b) * r_a + m_a * g_a
        ) / M_a  # eq. (5), consistent form
        k = M_a * W * g_at / f**2  # eq. (9): k f^2 = M_a g g_at  -> N/mm
        return {
            "m_ct": m_ct,
            "g_ct": g_ct,
            "M_c": M_c,
            "M_b": M_b,
            "M_a": M_a,
            "g_at": g_at,
            "k": k,
        }

    side_data = (43.5, 79.5, 47.4, 117.8, 63.2, 90.7)
    mid_data = (53.0, 69.1, 54.1, 112.7, 314.0, 126.0)
    s = leg(*side_data, 291.2, 182.1, 195.0)
    check("side m_ct [g]", s["m_ct"], 354.4, 1e-9)
    check("side g_ct [mm]", s["g_ct"], 165.80, 0.005)
    check("side M_c [g]", s["M_c"], 293.80, 0.005)
    check("side M_b [g]", s["M_b"], 1649.78, 0.005)
    check("side M_a [g]", s["M_a"], 2388.88, 0.005)
    check("side g_at [mm]", s["g_at"], 133.99, 0.005)
    check("side k [N/mm]", s["k"], 0.51611, 5e-6)
    literal = ((47.4 + 63.2 + 291.2 + s["M_c"] + s["M_b"]) * 135 + 43.5 + 79.5) / 100
    check("eq. (5) as printed (nonsense) [mm]", literal, 3167.5, 0.05)

    # middle leg: r_b from M_b = 1568.0 g
    m_ct = 314.0 + 109.9
    M_c_mid = (314.0 * 126.0 + 109.9 * 182.1) / 200.0
    r_b_mid = (1568.0 * 80.0 - 54.1 * 112.7) / (m_ct + M_c_mid)
    check("middle r_b implied by M_b = 1568.0 g [mm]", r_b_mid, 165.34, 0.005)
    r_b_rounded = (1568.0 * 80.0 - 54.1 * 112.7) / (m_ct + 298.0)
    check(
        "  same with the printed, rounded M_c = 298.0 g [mm]",
        r_b_rounded,
        165.32,
        0.005,
    )
    m = leg(*mid_data, 109.9, 182.1, r_b_mid)
    check("middle g_ct [mm]", m["g_ct"], 140.54, 0.005)
    check("middle M_c [g]", m["M_c"], 297.88, 0.005)
    check("middle M_b [g]", m["M_b"], 1568.0, 1e-6)
    check("middle M_a [g]", m["M_a"], 2396.88, 0.005)
    check("middle g_at [mm]", m["g_at"], 133.54, 0.005)
    check("middle k [N/mm]", m["k"], 0.51612, 5e-6)

    # same spring for all legs: the leg moment Q = M_a g_at is affine in the payload share
    m_e = 2 * 291.2 + 109.9
    check("endoscope group [g]", m_e, 692.3, 1e-9)

    def q(data, r_b, m_p):
        d = leg(*data, m_p, 182.1, r_b)
        return d["M_a"] * d["g_at"]

    def same_spring(r_b):
        qs0, qm0 = q(side_data, 195.0, 0.0), q(mid_data, r_b, 0.0)
        ds = q(side_data, 195.0, 1.0) - qs0  # = r_a (1 + g_p/b_c)(1 + r_b/b_b) per g
        dm = q(mid_data, r_b, 1.0) - qm0
        rho = (qm0 + m_e * dm - qs0) / (m_e * (ds + 2 * dm))  # Q_side(rho) = Q_mid(rho)
        s = leg(*side_data, rho * m_e, 182.1, 195.0)
        m = leg(*mid_data, (1 - 2 * rho) * m_e, 182.1, r_b)
        return ds, rho, s, m

    ds, rho, s, m = same_spring(r_b_mid)
    check(
        "dQ/dm_pay side = r_a(1+g_p/b_c)(1+r_b/b_b) [mm]",
        ds,
        135 * (1 + 182.1 / 200) * (1 + 195 / 80),
        1e-6,
    )
    check("rho_side (r_b = 165.3444, exact) ", rho, 0.42063, 5e-6)
    check("rho_middle (exact r_b)", 1 - 2 * rho, 0.15874, 5e-6)
    check("shared k [N/mm] (exact r_b)", s["k"], 0.51611, 5e-6)
    check("  middle leg k at that split [N/mm]", m["k"], s["k"], 1e-12)
    check(
        "total M_a of three legs [g] (exact r_b)",
        2 * s["M_a"] + m["M_a"],
        7174.64,
        0.005,
    )
    _, rho, s, m = same_spring(
        165.34
    )  # the value written in problems/yasir2019_hybrid.toml
    check("rho_side (r_b = 165.34 as in the problem file)", rho, 0.420625, 5e-7)
    check("rho_middle (r_b = 165.34)", 1 - 2 * rho, 0.158750, 5e-7)
    check("shared k [N/mm] (r_b = 165.34)", s["k"], 0.516111, 5e-7)
    check(
        "total M_a of three legs [g] (r_b = 165.34)",
        2 * s["M_a"] + m["M_a"],
        7174.60,
        0.005,
    )
    check(
        "paper's 7174.8 = 2 x 2388.9 + 2397.0 (rounded rows) [g]",
        2 * 2388.9 + 2397.0,
        7174.8,
        1e-9,
    )

    ds, rho, s, m = same_spring(r_b_mid)
    # free extensions (problems/yasir2019_free_extensions.toml), side leg data
    k_c = 63.2 * 90.7 + 291.2 * 182.1  # moment M_c b_c [g mm]
    mc_250 = k_c / 250.0
    mb_120 = (47.4 * 117.8 + (354.4 + mc_250) * 195.0) / 120.0
    check(
        "free ext., b_b = 120, b_c = 250: M_b + M_c [g]",
        mc_250 + mb_120,
        1239.41,
        0.005,
    )
    for w, bb_exp, bc_exp in ((200.0, 70.711, 180.49), (40.0, 158.11, 298.37)):
        bb = 1e3 / w**0.5  # optimum of M_b (1 + w b_b^2) at fixed moment M_b b_b
        bbu = min(bb, 120.0) / 1e3  # b_b as bounded by [40, 120] mm, in m
        bc = (
            1e3 * ((1 + (1 + w * bbu**2) * 0.195 / bbu) / w) ** 0.5
        )  # optimum b_c given b_b
        check(
            f"free ext., w = {w:g} 1/m^2: optimal b_b unbounded [mm]", bb, bb_exp, 0.005
        )
        check(
            f"free ext., w = {w:g} 1/m^2: optimal b_c given b_b [mm]", bc, bc_exp, 0.005
        )

    # brute force: the whole side leg (bodies + counter-masses + spring) on random poses
    f, k = 78.0, s["k"]
    pts = [  # (mass, link index, distance along the link from its joint)
        (43.5, 0, 79.5),
        (47.4, 1, 117.8),
        (s["M_b"], 1, -80.0),
        (63.2, 2, 90.7),
        (rho * m_e, 2, 182.1),
        (s["M_c"], 2, -200.0),
    ]
    spread = []
    for _ in range(2000):
        th = np.cumsum(RNG.uniform(-np.pi, np.pi, 3))
        joints = [np.zeros(2), 135.0 * np.array([np.cos(th[0]), np.sin(th[0])])]
        joints.append(joints[1] + 195.0 * np.array([np.cos(th[1]), np.sin(th[1])]))
        v = 0.0
        for mass, i, d in pts:
            v += mass * W * (joints[i][1] + d * np.sin(th[i]))
        a = f * np.array([np.cos(th[0]), np.sin(th[0])])
        v += 0.5 * k * np.sum((a - np.array([0.0, f])) ** 2)
        spread.append(v)
    check(
        "side leg: spread of V over 2000 random poses [N mm]",
        float(np.ptp(spread)),
        0.0,
        1e-8,
    )


# ----------------------------------------------------------------------------------------
def seed_002() -> None:
    print("002 spherical balancing (SI units inside this block)")
    m, k = 0.3, 40.0  # kg, N/m

    def tilted_link(h, alpha, com, t, n=721):
        axis = np.array([0.0, -np.sin(alpha), np.cos(alpha)])
        hp = t * axis + h * Z
        v = [
            0.5 * k * np.sum((rot(axis, th) @ com - hp) ** 2)
            + m * G * (rot(axis, th) @ com)[2]
            for th in np.linspace(0, 2 * np.pi, n)
        ]
        return float(np.ptp(v))

    com = np.array([0.05, 0.02, 0.07])
    check(
        "tilted link, h = m g / k: spread [J]",
        tilted_link(m * G / k, 0.7, com, 0.1),
        0,
        1e-12,
    )
    check(
        "tilted link, h = 1.3 m g / k: spread > 0 [J]",
        tilted_link(1.3 * m * G / k, 0.7, com, 0.1) > 1e-3,
        1,
        0,
    )
    axis = np.array([0.0, -np.sin(0.7), np.cos(0.7)])
    check(
        "CoM on the axis (a = b = 0), any h: spread [J]",
        tilted_link(0.01, 0.7, 0.07 * axis, 0.1),
        0,
        1e-12,
    )
    check(
        "vertical axis (alpha = 0), any h: spread [J]",
        tilted_link(0.01, 0.0, com, 0.1),
        0,
        1e-12,
    )

    r, b, t, qq = 0.12, 0.05, 0.03, -0.02  # appendix B
    h = m * G * r / (k * b)
    v = []
    for th in np.linspace(0, 2 * np.pi, 721):
        p = np.array([r * np.cos(th), r * np.sin(th), 0.0])
        tt = np.array([0.0, 0.0, t])
        bb = tt + (b / r) * (p - tt)
        v.append(0.5 * k * np.sum((bb - np.array([0.0, h, qq])) ** 2) + m * G * p[1])
    check("appendix B, h = m g r/(k b): spread [J]", float(np.ptp(v)), 0, 1e-12)

    n = 3
    twists, masses, ks = (
        RNG.uniform(0.3, 2.5, n),
        RNG.uniform(0.1, 1, n),
        RNG.uniform(10, 100, n),
    )
    coms = RNG.normal(size=(n, 3)) * 0.1
    first_axis = np.array([1.0, 0.3, 0.2])
    v = []
    for _ in range(2000):
        q = RNG.uniform(-np.pi, np.pi, n)
        rr = rot(first_axis, q[0])
        e = 0.0
        for i in range(n):
            if i:
                rr = rr @ rot(X, twists[i - 1]) @ rot(Z, q[i])
            p = rr @ coms[i]
            e += (
                0.5 * ks[i] * np.sum((p - masses[i] * G / ks[i] * Z) ** 2)
                + masses[i] * G * p[2]
            )
        v.append(e)
    check("spherical 3R chain, h_i = m_i g/k_i: spread [J]", float(np.ptp(v)), 0, 1e-12)

    mm, ll = 1.0, 1.0
    check("Bennett: augmented link 1 mass [m]", mm + mm / 2, 1.5, 1e-12)
    check(
        "Bennett: augmented link 1 CoM [fraction of link]",
        (mm * ll / 2 + mm / 2 * ll) / 1.5,
        2 / 3,
        1e-12,
    )
    check("Bennett: augmented link 3 mass [m]", mm / 2 + mm / 2, 1.0, 1e-12)
    check(
        "Bennett: augmented link 3 CoM [fraction of link]",
        (mm / 2 * ll / 2 + mm / 2 * ll) / 1.0,
        0.75,
        1e-12,
    )

    for phi1, expect in (
        (np.pi / 6, (1 / 3, 1 / 3, 1 / 3)),
        (np.pi / 4, (0.29289, 0.29289, 0.41421)),
    ):
        pts = np.array(
            [
                [0, np.cos(phi1), np.sin(phi1)],
                [0, -np.cos(phi1), np.sin(phi1)],
                [0, 0, -1.0],
            ]
        )
        a = np.vstack([np.ones(3), pts.T])
        shares = np.linalg.lstsq(a, np.array([1.0, 0, 0, 0]), rcond=None)[0]
        for j in range(3):
            check(
                f"3-RRS share m_u{j + 1}/m_u, phi1 = {np.degrees(phi1):.0f} deg",
                shares[j],
                expect[j],
                5e-6,
            )


# ----------------------------------------------------------------------------------------
def seed_003() -> None:
    print("003 Woo 2019")
    l1, l3, l5, l7 = 200.0, 200.0, 100.0, 300.0
    m1 = m3 = m6 = m8 = 86.0
    m2 = m5 = 53.0
    m4, m7 = 100.0, 114.0

    def a1(tool):
        return m1 / 2 + m2 + m3 + m4 + m6 / 2 + m7 + m8 / 2 + tool

    def a5(tool):
        return (
            -0.5 * l3 / l5 * m3
            - l3 / l5 * m4
            + 0.5 * m5
            + m6
            + m7
            - 0.5 * l7 / l5 * m7
            - l3 / l5 * tool
        )

    check("A1, tool 1280 g [g]", a1(1280), 1762, 1e-9)
    check("A5, tool 1280 g [g]", a5(1280), -2790.5, 1e-9)
    check("A1, tool 1320 g [g]", a1(1320), 1802, 1e-9)
    check("A5, tool 1320 g [g]", a5(1320), -2870.5, 1e-9)
    check(
        "A1 if link 8 really were 20 mm long [g]",
        a1(1280) - m8 / 2 + m8 / 2 * 20 / l1,
        1723.3,
        1e-9,
    )
    check(
        "lever of m_c1 = 2331 g implied by C1 = 0 [mm]",
        a1(1280) * l1 / 2331,
        151.18,
        0.005,
    )
    check(
        "lever of m_c2 = 139 g implied by C5 = 0 [mm]",
        (-a5(1280) - 2331) * l5 / 139 - l5,
        230.58,
        0.005,
    )
    check(
        "  same with eq. (12)'s printed '+ m_c1' [mm]",
        (-a5(1280) + 2331) * l5 / 139 - l5,
        3584.5,
        0.05,
    )
    check("payload range, m_c2 = 139 g, 50 mm [g]", 139 * 50 / l3, 34.75, 1e-9)
    check("  range allowed by m_c1 = 2331 g, 50 mm [g]", 2331 * 50 / l1, 582.75, 1e-9)
    check("dL_c2 for +31 g [mm]", 31 * l3 / 139, 44.60, 0.005)
    check("hybrid: range, m_c1 = 488 g, 50 mm [g]", 488 * 50 / l1, 122, 1e-9)
    check("hybrid: range allowed by m_c2 = 910 g [g]", 910 * 50 / l3, 227.5, 1e-9)
    check("hybrid: m_c1 needed for 122 g over 50 mm [g]", 122 * l1 / 50, 488, 1e-9)
    check(
        "hybrid: lever of m_c2 = 910 g (tool 1320 g) [mm]",
        (-a5(1320) - 488) * l5 / 910 - l5,
        161.81,
        0.005,
    )
    check("hybrid: dL_c1 for +62 g [mm]", 62 * l1 / 488, 25.41, 0.005)
    check("hybrid: dL_c2 for +62 g [mm]", 62 * l3 / 910, 13.63, 0.005)

    # brute force on the reduced model V = g(C1 l1 sin th1 + C5 l5 sin th5): adjust for +alpha
    alpha, mc1, mc2, lev1, lev2 = 31.0, 2331.0, 139.0, 151.18, 230.58
    dl1, dl2 = alpha * l1 / mc1, alpha * l3 / mc2
    c1 = a1(1280 + alpha) - mc1 * (lev1 + dl1) / l1 - (a1(1280) - mc1 * lev1 / l1)
    c5 = (a5(1280 + alpha) + mc1 + mc2 * (1 + (lev2 + dl2) / l5)) - (
        a5(1280) + mc1 + mc2 * (1 + lev2 / l5)
    )
    check("eq. (21) re-balances C1 after +31 g [g]", c1, 0, 1e-9)
    check("eq. (21) re-balances C5 after +31 g [g]", c5, 0, 1e-9)


# ----------------------------------------------------------------------------------------
def seed_004() -> None:
    print("004 Essomba 2021")
    m_a, m_b, m_c, m_d = 197.48, 197.48, 48.74, 48.52
    a = np.array([80.03, -99.21, 0.0])
    b = np.array([-99.18, 80.28, 0.0])
    c = np.array([72.63, -66.44, 0.0])
    d = np.array([-61.36, 69.72, 0.0])
    k_a = -m_a * W * a[1] / (75 * 20)
    k_b = -m_b * W * b[0] / (75 * 20)
    k_c = -m_c * W * c[1] / (40 * 60)
    k_d = -m_d * W * d[0] / (40 * 60)
    check("k_A [N/mm]", k_a, 0.12813, 5e-6)
    check("k_B [N/mm]", k_b, 0.12809, 5e-6)
    check("k_C [N/mm]", k_c, 0.013236, 5e-7)
    check("k_D [N/mm]", k_d, 0.012169, 5e-7)
    check("a_1 with 0.13 N/mm [mm]", -m_a * W * a[1] / (0.13 * 20), 73.92, 0.005)
    check("b_1 with 0.13 N/mm [mm]", -m_b * W * b[0] / (0.13 * 20), 73.90, 0.005)
    check("c_1 with 0.02 N/mm [mm]", -m_c * W * c[1] / (0.02 * 60), 26.47, 0.005)
    check("d_1 with 0.02 N/mm [mm]", -m_d * W * d[0] / (0.02 * 60), 24.34, 0.005)

    # full centre-of-mass model of eqs. (16)-(19) with the paper's springs
    def rx(t):
        return rot(X, t)

    def ry(t):
        return rot(Y, t)

    def rz(t):
        return rot(Z, t)

    spread_c, spread_d = [], []
    for _ in range(2000):
        ta, tb, tc, td = RNG.uniform(-np.pi, np.pi, 4)
        hc = (rx(ta) @ rz(-np.pi / 2) @ rx(tc) @ c)[2]
        hd = (ry(tb) @ rz(np.pi / 2) @ ry(td) @ d)[2]
        spread_c.append(
            m_c * W * hc
            + k_c / 2 * (40**2 + 60**2 + 2 * 40 * 60 * np.cos(ta) * np.sin(tc))
        )
        spread_d.append(
            m_d * W * hd
            + k_d / 2 * (40**2 + 60**2 - 2 * 40 * 60 * np.cos(tb) * np.sin(td))
        )
    check(
        "linkage C full CoM: spread of V = 2 m_C g c_x [N mm]",
        float(np.ptp(spread_c)),
        2 * m_c * W * c[0],
        0.5,
    )
    check(
        "linkage D full CoM: spread of V = 2 m_D g d_y [N mm]",
        float(np.ptp(spread_d)),
        2 * m_d * W * d[1],
        0.5,
    )
    check(
        "k_A if A also carries m_C c_x (eq. 18 as printed) [N/mm]",
        (m_a * W * 99.21 + m_c * W * c[0]) / 1500,
        0.15128,
        5e-6,
    )
    check(
        "k_B if B also carries m_D d_y (eq. 19 as printed) [N/mm]",
        (m_b * W * 99.18 + m_d * W * d[1]) / 1500,
        0.15022,
        5e-6,
    )

    ll, l11, l12, m_l1, m_l2, m_s = 540.0, 50.0, 95.0, 537.34, 575.29, 815.47
    l21, l22 = 50.0, 95.0
    k1_printed = ll * W * (m_l1 + 2 * m_l2 + 2 * m_s) / (l11 * l12)
    k2_printed = ll * W * (m_l2 + 2 * m_s) / (l21 * l22)
    k1 = W * ll * (m_l1 / 2 + m_l2 + m_s) / (l11 * l12)
    k2 = W * ll * (m_l2 / 2 + m_s) / (l21 * l22)
    check("k1, eq. (36) as printed [N/mm]", k1_printed, 3.7013, 5e-5)
    check("k2, eq. (37) with m_L2 [N/mm]", k2_printed, 2.4605, 5e-5)
    check(
        "k2, eq. (37) literally with m_L1 [N/mm]",
        ll * W * (m_l1 + 2 * m_s) / (l21 * l22),
        2.4182,
        5e-5,
    )
    check("k1, energy (eqs. 8-15 + m_S) [N/mm]", k1, 1.8507, 5e-5)
    check("k2, energy (eqs. 8-15 + m_S) [N/mm]", k2, 1.2302, 5e-5)
    check("printed / energy, k1", k1_printed / k1, 2.0, 1e-12)
    check("printed / energy, k2", k2_printed / k2, 2.0, 1e-12)
    check(
        "l12 refined for 3.73 N/mm, paper's convention [mm]",
        l12 * k1_printed / 3.73,
        94.27,
        0.005,
    )
    check(
        "l22 refined for 2.39 N/mm, paper's convention [mm]",
        l22 * k2_printed / 2.39,
        97.80,
        0.005,
    )
    check("l12 for 3.73 N/mm, energy [mm]", l12 * k1 / 3.73, 47.13, 0.005)
    check("l22 for 2.39 N/mm, energy [mm]", l22 * k2 / 2.39, 48.90, 0.005)
    check(
        "payload 500 g: l12 with k1 = 1.8507 kept [mm]",
        l12 * (m_l1 / 2 + m_l2 + m_s + 500) / (m_l1 / 2 + m_l2 + m_s),
        123.62,
        0.005,
    )
    check(
        "payload 500 g: l22 with k2 = 1.2302 kept [mm]",
        l22 * (m_l2 / 2 + m_s + 500) / (m_l2 / 2 + m_s),
        138.06,
        0.005,
    )

    for theta_l, name in ((-np.pi / 2, "down"), (0.0, "horizontal"), (np.pi / 2, "up")):
        up = rx(theta_l).T @ Z  # world vertical seen in the mechanism's plane frame
        v = []
        for _ in range(2000):
            t1, t2 = RNG.uniform(-np.pi, np.pi, 2)
            e1, e2 = (
                np.array([0, np.cos(t1), np.sin(t1)]),
                np.array([0, np.cos(t2), np.sin(t2)]),
            )
            v.append(
                W
                * (
                    m_l1 * (ll / 2 * e1) @ up
                    + m_l2 * (ll * e1 + ll / 2 * e2) @ up
                    + m_s * (ll * (e1 + e2)) @ up
                )
                + 0.5 * k1 * np.sum((l11 * e1 - l12 * up) ** 2)
                + 0.5 * k2 * np.sum((l21 * e2 - l22 * up) ** 2)
            )
        check(
            f"position mechanism, mode {name}: spread of V [N mm]",
            float(np.ptp(v)),
            0,
            1e-8,
        )


if __name__ == "__main__":
    seed_001()
    seed_002()
    seed_003()
    seed_004()
    print("all checks passed" if not FAILED else f"{len(FAILED)} FAILED: {FAILED}")
    sys.exit(1 if FAILED else 0)
