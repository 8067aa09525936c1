"""The fast principal moments against LAPACK's eigvalsh: cond and every status decision agree."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import physical_bodies, random_rotations, six, slender_bodies, spd_bodies

from hconv.kernels.inertia import Sym3
from hconv.kernels.spectrum import eigenvalues
from hconv.solve.status import TRIANGLE_RTOL
from hconv.tools.scene import cylinder_moments, rotate_tensors


def _sym(M):
    return Sym3(*(np.ascontiguousarray(c) for c in six(M).T))


def _bodies(name, rng, n=3000):
    R = random_rotations(rng, n)
    if name == "physical":
        return physical_bodies(rng, n)
    if name == "rods":
        return slender_bodies(rng, n, 1e6)
    if name == "ill":
        return spd_bodies(rng, n, 1e12)
    if name == "cylinders":  # two equal moments: the closed form's hard case
        return rotate_tensors(R, cylinder_moments(1.0, rng.uniform(0.01, 1, n), rng.uniform(0.01, 2, n)))
    if name == "plates":  # exactly on the triangle boundary
        a, b = rng.uniform(0.5, 2, n), rng.uniform(0.5, 2, n)
        return rotate_tensors(R, np.stack([a, b, a + b], axis=1))
    if name == "spheres":
        return np.tile(np.eye(3) * 3.0, (n, 1, 1))
    if name == "indefinite":
        return rotate_tensors(R, np.tile([-1.0, 2.0, 3.0], (n, 1)))
    if name == "tiny":
        return physical_bodies(rng, n) * 1e-150
    if name == "huge":
        return physical_bodies(rng, n) * 1e150
    raise ValueError(name)


@pytest.mark.parametrize(
    "name", ["physical", "rods", "ill", "cylinders", "plates", "spheres", "indefinite", "tiny", "huge"]
)
def test_eigenvalues_agree_with_lapack_where_statuses_need_it(name, rng):
    M = _bodies(name, rng)
    lam, ref = eigenvalues(_sym(M)).T, np.linalg.eigvalsh(M)
    scale = np.abs(ref).max(axis=1)
    # cond = |λ|max/|λ|min to LAPACK's own accuracy, about cond·eps relative, or √eps where the
    # two smaller moments nearly coincide (cylinders): the documented price of the closed form
    eps = np.finfo(float).eps
    cond, cond_ref = (np.abs(x).max(axis=1) / np.abs(x).min(axis=1) for x in (lam, ref))
    assert np.all(np.abs(cond / cond_ref - 1) <= 4 * np.sqrt(eps) + 64 * cond_ref * eps)
    if name != "cylinders":
        assert np.all(np.abs(cond / cond_ref - 1) <= 1e-10 + 64 * cond_ref * eps)
    # the sign of the smallest moment and the triangle decision are identical
    assert np.array_equal(lam[:, 0] < 0, ref[:, 0] < 0)
    tri = lambda x: x[:, 2] - x[:, 1] - x[:, 0] > TRIANGLE_RTOL * np.abs(x).sum(axis=1)  # noqa: E731
    assert np.array_equal(tri(lam), tri(ref))
    # each moment to within √eps of the largest (the closed form's documented worst case)
    assert np.all(np.abs(lam - ref).max(axis=1) <= 4 * np.sqrt(np.finfo(float).eps) * scale)


def test_eigenvalues_empty():
    assert eigenvalues(_sym(np.zeros((0, 3, 3)))).shape == (3, 0)


def test_largest_root_within_rounding_of_mpmath_on_every_r():
    """The trig-free root c = cos(acos(r)/3) against a 40-digit one, over r in [-1, 1] and near its
    ends, with the tensor built so that its r is exactly the one asked for."""
    import mpmath

    from hconv.kernels.spectrum import _largest_root

    mpmath.mp.dps = 40
    r = np.concatenate([np.linspace(-1, 1, 801), [-1 + 1e-12, -1 + 1e-6, 1 - 1e-12, 1 - 1e-6]])
    # diag(q + 2p·cos(θ/3 + 2πk/3)) has this r; in units where q = 3 and p = 1 the root is 3 + 2c
    theta = [mpmath.acos(mpmath.mpf(float(x))) for x in r]
    roots = [[3 + 2 * mpmath.cos(t / 3 + 2 * mpmath.pi * k / 3) for k in range(3)] for t in theta]
    diag = np.array([[float(x) for x in row] for row in roots]).T
    zero = np.zeros_like(diag[0])
    hi, err = _largest_root(Sym3(diag[0], diag[1], diag[2], zero, zero, zero))
    want = np.array([float(max(row)) for row in roots])
    # The diagonal is rounded to float64, so r moves by about eps; near r = -1 that moves c by
    # eps/√(1 − r²), which err covers: the bound must hold, and away from the ends one rounding.
    assert np.all(np.abs(hi - want) <= err)
    inner = np.abs(r) < 0.99
    assert np.max(np.abs(hi - want)[inner] / np.spacing(want[inner])) <= 4
