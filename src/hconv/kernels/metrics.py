"""How far one vector is from another: the relative error and the angle, row by row.

Every figure hconv reports of this kind (the ``residual`` column, ``diagnose``'s and
``compare``'s differences, the stability sweeps, the bench's accuracy) comes from here.
Vectors are component-major, shape ``(3, N)``; results are ``(N,)``.
"""

from __future__ import annotations

import numpy as np

from hconv.kernels.inertia import max_abs, sum_sq


def relative_error(x: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """‖x − ref‖ / ‖ref‖ per row (2-norms), safe from overflow and underflow at any scale.

    Both norms are taken in units of ref's largest component, so that neither the squares of
    1e200 nor those of 1e-200 leave the range (the ratio is unchanged). Where ref is 0, an x of
    0 is exact (0) and anything else infinitely off (inf). A NaN in x gives NaN; a ref that is not
    finite gives inf or NaN (callers that hold such rows leave them out).
    """
    d = x - ref
    unit = max_abs(ref)
    unit = np.where((unit > 0) & np.isfinite(unit), unit, 1.0)
    d, ref = d / unit, ref / unit
    num = np.sqrt(sum_sq(d))
    den = np.sqrt(sum_sq(ref))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.where(num == 0, 0.0, num * np.inf))


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The angle between a and b per row [degrees]; NaN where either is zero (or not finite).

    From atan2(|a × b|, a·b), which keeps small angles accurate where acos of the cosine loses
    them; both vectors are first scaled by their largest component, so any magnitude is safe.
    """
    ua, ub = max_abs(a), max_abs(b)
    defined = (ua > 0) & (ub > 0) & np.isfinite(ua) & np.isfinite(ub)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        a = a / np.where(defined, ua, 1.0)
        b = b / np.where(defined, ub, 1.0)
        cross = np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
        dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
        ang = np.degrees(np.arctan2(np.sqrt(sum_sq(cross)), dot))
    return np.where(defined, ang, np.nan)
