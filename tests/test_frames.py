"""Frames and points (hconv.kernels.frames): a free body's momentum about its centre of mass,
against the same difference taken in 50-digit arithmetic."""

from __future__ import annotations

import warnings

import mpmath
import numpy as np
from helpers import EPS

from hconv.kernels.frames import momentum_about_com


def orbital_inputs(rng, n):
    """Satellites 7,000 km out at 7.5 km/s, 1e3 kg, whose spin adds about 1 kg·m²/s to
    r × m·v ≈ 5e13: float64 H_P ``(3, n)``, m ``(n,)``, r and v ``(3, n)``."""
    r = rng.normal(size=(3, n)) * 4e6
    v = rng.normal(size=(3, n)) * 4e3
    m = rng.uniform(500, 2000, n)
    H_P = np.cross(r.T, (m * v).T).T + rng.normal(size=(3, n))
    return H_P, m, r, v


def mp_momentum(H_P, m, r, v):
    """H_P − r × (m·v) of the float64 numbers as given, exactly (50 digits), rounded once."""
    out = np.empty_like(H_P)
    with mpmath.workdps(50):
        for k in range(H_P.shape[1]):
            h = [mpmath.mpf(float(x)) for x in H_P[:, k]]
            a = [mpmath.mpf(float(x)) for x in r[:, k]]
            b = [mpmath.mpf(float(m[k])) * mpmath.mpf(float(x)) for x in v[:, k]]
            c = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
            out[:, k] = [float(h[i] - c[i]) for i in range(3)]
    return out


def test_momentum_about_com_within_a_rounding_of_the_exact_difference(rng):
    # The plain subtraction lost 13 digits to its own roundings here (errors up to 1e-2 of H_C);
    # compensated, the computation adds one rounding of H_C and nothing more.
    H_P, m, r, v = orbital_inputs(rng, 300)
    H_C, _ = momentum_about_com(H_P, m, r, v)
    exact = mp_momentum(H_P, m, r, v)
    assert (np.abs(H_C - exact) <= EPS * np.abs(exact)).all()


def test_momentum_about_com_bound_covers_the_inputs_rounding(rng):
    # Exact states rounded to float64: H_C of the rounded inputs is off from the exact H_C by what
    # their rounding lost, and the bound ε_C holds it without being wildly loose.
    n = 300
    H_C_exact, got, bound = np.empty((3, n)), np.empty((3, n)), np.empty(n)
    with mpmath.workdps(50):
        for k in range(n):

            def near(x):
                return mpmath.mpf(float(x)) * (1 + mpmath.mpf(float(rng.uniform(-1, 1))) * mpmath.mpf(2) ** -52)

            r = [near(x) for x in rng.normal(size=3) * 4e6]
            v = [near(x) for x in rng.normal(size=3) * 4e3]
            m = near(rng.uniform(500, 2000))
            spin = [near(x) for x in rng.normal(size=3) * 10 ** rng.uniform(0, 8)]
            mv = [m * x for x in v]
            H = [
                spin[0] + r[1] * mv[2] - r[2] * mv[1],
                spin[1] + r[2] * mv[0] - r[0] * mv[2],
                spin[2] + r[0] * mv[1] - r[1] * mv[0],
            ]
            H_C_exact[:, k] = [float(x) for x in spin]
            f = (
                np.array([[float(x)] for x in H]),
                np.array([float(m)]),
                np.array([[float(x)] for x in r]),
                np.array([[float(x)] for x in v]),
            )
            h, e = momentum_about_com(*f)
            got[:, k], bound[k] = h[:, 0], e[0]
    err = np.linalg.norm(got - H_C_exact, axis=0) / np.linalg.norm(H_C_exact, axis=0)
    assert (err <= bound).all()
    assert np.median(err / bound) > 0.03
    assert bound.max() > 1e-4 and bound.min() < 1e-10  # spins of 1 to 1e8 kg·m²/s on 5e13


def test_momentum_about_com_at_the_edges():
    # At rest at the origin nothing is lost (ε 0); a total cancellation leaves nothing known (inf);
    # beyond 1e300 the compensation's splits overflow and the plain result is kept, quietly.
    H_P = np.array([[0.0, 5.25e13, 1e300], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    r = np.array([[0.0, 0.0, 0.0], [0.0, 7e6, 0.0], [0.0, 0.0, 0.0]])
    v = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 7500.0, 0.0]])
    m = np.array([1.0, 1e3, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        H_C, eps_C = momentum_about_com(H_P, m, r, v)
    assert H_C[:, 0].tolist() == [0.0, 0.0, 0.0] and eps_C[0] == 0.0
    assert H_C[:, 1].tolist() == [0.0, 0.0, 0.0] and eps_C[1] == np.inf
    assert H_C[:, 2].tolist() == [1e300, 0.0, 0.0] and 0 < eps_C[2] < 4 * EPS
