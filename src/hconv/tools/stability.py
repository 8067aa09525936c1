"""Where each method fails: sweeps of hard inputs, each scored against an exact reference.

Every sweep point is a small batch of bodies. Each method runs on it in float64 and float32 and
is scored by the relative error ‖ω − I⁻¹H‖ / ‖I⁻¹H‖ (norm-wise) against I⁻¹H solved in exact
rational arithmetic from the same float64 inputs (Cramer's rule on :class:`fractions.Fraction`,
then rounded once): independent of every method, and exact at any scale. Rows without an answer
(NaN ω) are left out of the error and show in the share flagged. The document methods are scored
against I⁻¹H like the rest: their error is their distance from the physics, not rounding.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from fractions import Fraction

import numpy as np

from hconv.kernels.metrics import relative_error
from hconv.solve import convert as core
from hconv.solve import methods
from hconv.tools.scene import random_rotations, rotate_tensors

#: A sweep point's bodies: I (n, 3, 3) [kg·m²], H (n, 3) [kg·m²/s], r (n, 3) [m].
Bodies = tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class Sweep:
    """A family of inputs indexed by one parameter; ``make(rng, n, p)`` gives (I (n,3,3), H (n,3), r (n,3))."""

    name: str
    title: str
    xlabel: str
    params: np.ndarray
    make: Callable
    log_x: bool = True


def _bodies(
    rng: np.random.Generator, moments: np.ndarray, *, rotate: bool = True, r: np.ndarray | None = None
) -> Bodies:
    n = moments.shape[0]
    I = rotate_tensors(random_rotations(rng, n), moments) if rotate else np.stack([np.diag(m) for m in moments])
    H = rng.normal(size=(n, 3))
    r = rng.uniform(-1, 1, (n, 3)) if r is None else r
    return I, H, r


def slender_bodies(rng: np.random.Generator, n: int, c: float) -> Bodies:
    """Physical rods and plates with cond(I) ≈ c: moments (1/c, 1, 1 + t/c), t in [0, 1);
    (I (n,3,3), H (n,3), r (n,3))."""
    e = np.full(n, 1.0 / c)
    return _bodies(rng, np.stack([e, np.ones(n), 1 + rng.random(n) * e], axis=1))


def _scale(rng: np.random.Generator, n: int, s: float) -> Bodies:
    I, H, r = _bodies(rng, np.stack([np.full(n, 1.0), np.full(n, 2.0), np.full(n, 2.5)], axis=1))
    return I * s, H * s, r


def _equal(rng: np.random.Generator, n: int, gap: float) -> Bodies:
    """Two moments approach each other: a symmetric top in the limit."""
    return _bodies(rng, np.stack([np.full(n, 1.0), np.full(n, 1.0 + gap), np.full(n, 1.5)], axis=1))


def _axis(rng: np.random.Generator, n: int, d: float) -> Bodies:
    """R approaches a principal axis; I is diagonal so the given axes are principal."""
    moments = np.stack([np.full(n, 1.0), np.full(n, 1.5), np.full(n, 2.0)], axis=1)
    r = np.stack([d * rng.uniform(0.5, 1, n), d * rng.uniform(0.5, 1, n), np.ones(n)], axis=1)
    return _bodies(rng, moments, rotate=False, r=r)


def _triangle(rng: np.random.Generator, n: int, ratio: float) -> Bodies:
    """I3 = ratio · (I1 + I2): physical for ratio <= 1."""
    a, b = rng.uniform(0.5, 1, n), rng.uniform(0.5, 1, n)
    return _bodies(rng, np.stack([a, b, ratio * (a + b)], axis=1))


def _zero(rng: np.random.Generator, n: int, e: float) -> Bodies:
    """One moment goes to zero: a rod in the limit (e = 0 exactly)."""
    return _bodies(rng, np.stack([np.full(n, e), np.ones(n), np.ones(n) + e], axis=1))


SWEEPS = (
    Sweep("cond", "condition number", "cond(I)", 10.0 ** np.arange(0, 17), slender_bodies),
    Sweep("scale", "overall scale of I and H", "scale factor", 10.0 ** np.arange(-200, 201, 25), _scale),
    Sweep("equal", "two moments approach equality", "(I2 − I1) / I1", 10.0 ** np.arange(0, -17, -1), _equal),
    Sweep("axis", "r approaches a principal axis", "|r⊥| / |r|", 10.0 ** np.arange(0, -17, -1), _axis),
    Sweep(
        "triangle",
        "triangle inequality broken",
        "I3 / (I1 + I2)",
        np.array([0.5, 0.8, 0.95, 0.999, 1.0, 1.001, 1.05, 1.2, 1.5, 2, 3, 5]),
        _triangle,
        log_x=False,
    ),
    Sweep("zero", "a moment goes to zero (rod)", "I1 / I2", np.append(10.0 ** np.arange(0, -21, -2), 0.0), _zero),
)


def exact_solve(I: np.ndarray, H: np.ndarray) -> np.ndarray:
    """I⁻¹H for ``(n, 3, 3)``, ``(n, 3)`` in exact rational arithmetic, rounded once; NaN if singular."""
    out = np.full(H.shape, np.nan)
    for k in range(H.shape[0]):
        a = [[Fraction(float(v)) for v in row] for row in I[k]]
        h = [Fraction(float(v)) for v in H[k]]

        def det(m: list[list[Fraction]]) -> Fraction:
            return (
                m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
            )

        d = det(a)
        if d != 0:
            for i in range(3):
                m = [[h[r] if c == i else a[r][c] for c in range(3)] for r in range(3)]
                out[k, i] = float(det(m) / d)
    return out


@dataclass
class Point:
    """One method at one sweep point and precision."""

    sweep: str
    param: float
    method: str
    precision: int
    median_error: float
    worst_error: float
    flagged: float  #: share of rows whose status is not ok


def run(
    rows: int = 48, seed: int = 0, sweeps: tuple[Sweep, ...] = SWEEPS, precisions: tuple[int, ...] = (64, 32)
) -> list[Point]:
    """Run every method over every sweep; one :class:`Point` per (sweep point, method, precision)."""
    rng = np.random.default_rng(seed)
    points = []
    for sw in sweeps:
        for p in sw.params:
            I, H, r = sw.make(rng, rows, float(p))
            ref = exact_solve(I, H).T
            for name in methods.METHODS:
                for prec in precisions:
                    with np.errstate(all="ignore"):
                        res = core.convert(H, I, r, method=name, precision=prec, diagnostics=False)
                        err = relative_error(res.w.T.astype(float), ref)
                    err = err[np.isfinite(err)]
                    points.append(
                        Point(
                            sw.name,
                            float(p),
                            name,
                            prec,
                            float(np.median(err)) if err.size else float("nan"),
                            float(err.max()) if err.size else float("nan"),
                            float(np.mean(res.status_code != 0)),
                        )
                    )
    return points


def to_json(points: list[Point]) -> list[dict]:
    """Every sweep point as ``hconv stability --json`` prints it; None (JSON's null, as standard
    JSON has no NaN) where no row had an answer."""
    return [
        {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in asdict(p).items()}
        for p in points
    ]
