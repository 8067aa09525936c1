"""Reference points: the parallel-axis shift to a pivot and a free body's orbital momentum,
against bodies whose inertia about the pivot is known in closed form."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest
from helpers import axis_angle, mp_solve, physical_bodies, quats, rel_err, rodrigues, six, vec, w_of

import hconv
from hconv.errors import InputError
from hconv.solve.options import Conventions
from hconv.tables.job import Job

PIVOT = Job(conventions=Conventions(about="pivot"))
SIX = ["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"]


def box_about_corner(m, a, b, c):
    """A box a×b×c with a corner at the pivot and edges along the axes: about the corner,
    Ixx = m(b²+c²)/3 and the products are -m·a·b/4, -m·a·c/4, -m·b·c/4 (tensor entries)."""
    corner = np.zeros((len(m), 3, 3))
    corner[:, 0, 0], corner[:, 1, 1], corner[:, 2, 2] = (
        m * (b**2 + c**2) / 3,
        m * (a**2 + c**2) / 3,
        m * (a**2 + b**2) / 3,
    )
    corner[:, 0, 1] = corner[:, 1, 0] = -m * a * b / 4
    corner[:, 0, 2] = corner[:, 2, 0] = -m * a * c / 4
    corner[:, 1, 2] = corner[:, 2, 1] = -m * b * c / 4
    return corner


def test_convert_pivot_cylinder_about_its_end_matches_closed_form(rng):
    # A solid cylinder (mass m, radius a, length L) along x, pivoting about the centre of one end
    # face: about that point the moments are m·a²/2 (axis) and m·(a²/4 + L²/3) (across).
    n = 50
    m, a, L = rng.uniform(0.5, 5, n), rng.uniform(0.01, 0.2, n), rng.uniform(0.5, 3, n)
    across_com = m * (3 * a**2 + L**2) / 12
    H = rng.normal(size=(n, 3))
    t = pa.table(
        {
            **vec("H", H),
            "I1": m * a**2 / 2,
            "I2": across_com,
            "I3": across_com,
            "m": m,
            "rx": L / 2,
            "ry": np.zeros(n),
            "rz": np.zeros(n),
        }
    )
    got = w_of(hconv.convert_table(t, job=PIVOT))
    about_end = np.stack([m * a**2 / 2, m * (a**2 / 4 + L**2 / 3), m * (a**2 / 4 + L**2 / 3)], axis=1)
    np.testing.assert_allclose(got, H / about_end, rtol=1e-14)


def test_convert_pivot_box_about_a_corner_matches_closed_form(rng):
    n = 50
    m = rng.uniform(0.5, 5, n)
    a, b, c = rng.uniform(0.1, 2, (3, n))
    H = rng.normal(size=(n, 3))
    com = {"I1": m * (b**2 + c**2) / 12, "I2": m * (a**2 + c**2) / 12, "I3": m * (a**2 + b**2) / 12}
    t = pa.table({**vec("H", H), **com, "m": m, "rx": a / 2, "ry": b / 2, "rz": c / 2})
    assert rel_err(w_of(hconv.convert_table(t, job=PIVOT)), mp_solve(box_about_corner(m, a, b, c), H)).max() < 1e-13


def test_convert_pivot_turned_box_in_world_frame(rng):
    # The same box turned by q; H and r given in the world frame. About the corner, the world
    # tensor is R·I_corner·Rᵀ, so ω = (R·I_corner·Rᵀ)⁻¹·H.
    n = 40
    m = rng.uniform(0.5, 5, n)
    a, b, c = rng.uniform(0.1, 2, (3, n))
    u, th = axis_angle(rng, n)
    R = rodrigues(u, th)
    H = rng.normal(size=(n, 3))
    r_world = np.einsum("nij,nj->ni", R, np.stack([a, b, c], axis=1) / 2)
    t = pa.table(
        {
            **vec("H", H),
            "I1": m * (b**2 + c**2) / 12,
            "I2": m * (a**2 + c**2) / 12,
            "I3": m * (a**2 + b**2) / 12,
            "m": m,
            **vec("r", r_world),
            **vec("q", quats(u, th), "wxyz"),
        }
    )
    want = mp_solve(R @ box_about_corner(m, a, b, c) @ np.swapaxes(R, 1, 2), H)
    assert rel_err(w_of(hconv.convert_table(t, job=PIVOT)), want).max() < 1e-13


def test_convert_free_body_removes_orbital_momentum(rng):
    # ω and the centre's velocity v are chosen; H about the origin = I_C·ω + r × m·v.
    n = 60
    I = physical_bodies(rng, n)
    w = rng.normal(size=(n, 3))
    m, r, v = rng.uniform(0.5, 5, n), rng.normal(size=(n, 3)) * 3, rng.normal(size=(n, 3)) * 2
    H_origin = np.einsum("nij,nj->ni", I, w) + np.cross(r, m[:, None] * v)
    t = pa.table({**vec("H", H_origin), **dict(zip(SIX, six(I).T)), "m": m, **vec("r", r), **vec("v", v)})
    got = w_of(hconv.convert_table(t, job=Job(conventions=Conventions(about="free"))))
    assert rel_err(got, w).max() < 1e-12
    plain = w_of(hconv.convert_table(t))  # treating H as if about the centre of mass is wrong
    assert np.median(rel_err(plain, w)) > 0.1


@pytest.mark.parametrize("about, missing", [("pivot", "m"), ("free", "vx, vy, vz")])
def test_convert_pivot_and_free_name_what_they_need(about, missing):
    t = pa.table(
        {
            "Hx": [1.0],
            "Hy": [0.0],
            "Hz": [0.0],
            "I": [1.0],
            "rx": [1.0],
            "ry": [0.0],
            "rz": [0.0],
            **({"m": [1.0]} if about == "free" else {}),
        }
    )
    with pytest.raises(InputError, match=f"missing columns? {missing}"):
        hconv.convert_table(t, job=Job(conventions=Conventions(about=about)))


@pytest.mark.parametrize("form", ["scalar", "sym6"])
def test_convert_mass_not_positive_with_inertia_is_invalid_input(form):
    """Without --about too: a body of negative or zero mass but non-zero inertia is not a body;
    zero mass with zero inertia (a massless link) is singular, as any zero tensor is."""
    m = [2.0, -5.0, 0.0, np.nan, 0.0]
    I = [1.0, 1.0, 1.0, 1.0, 0.0]
    cols = (
        {"I": I}
        if form == "scalar"
        else {"Ixx": I, "Iyy": I, "Izz": I, "Ixy": [0.0] * 5, "Ixz": [0.0] * 5, "Iyz": [0.0] * 5}
    )
    t = pa.table({"Hx": [1.0] * 5, "Hy": [0.0] * 5, "Hz": [0.0] * 5, **cols, "m": m})
    got = hconv.convert_table(t)
    assert got.column("status").to_pylist() == ["ok", "invalid_input", "invalid_input", "invalid_input", "singular"]
    assert got.column("wx").to_pylist()[0] == 1.0


def test_convert_pivot_bad_mass_row_is_invalid_input():
    t = pa.table(
        {
            "Hx": [1.0] * 3,
            "Hy": [0.0] * 3,
            "Hz": [0.0] * 3,
            "I": [1.0] * 3,
            "m": [1.0, -1.0, np.nan],
            "rx": [0.0] * 3,
            "ry": [1.0] * 3,
            "rz": [0.0] * 3,
        }
    )
    got = hconv.convert_table(t, job=PIVOT)
    assert got.column("status").to_pylist() == ["ok", "invalid_input", "invalid_input"]
    assert got.column("wx").to_pylist()[0] == 0.5  # 1 / (1 + 1·1²)


def test_invalid_inputs_names_a_cause_exactly_when_the_status_is_invalid_input(rng):
    """Random single bodies, with NaN, ±Inf, a zero q, a bad mass or a value beyond float32 planted
    in random sets: invalid_inputs names a set exactly when solve says invalid_input, and names
    the planted one; hconv one prints why from these names."""
    from hconv.solve import bodies

    abouts = {"same": Conventions(), "pivot": Conventions(about="pivot"), "free": Conventions(about="free")}
    for _ in range(300):
        conv = abouts[rng.choice(list(abouts))]
        method = str(rng.choice(["exact", "document", "eigen"]))
        precision = int(rng.choice([64, 32]))
        sets = {
            "H": rng.normal(size=3),
            "I": np.array([2.0, 3.0, 4.0, 0.1, 0.0, 0.0]),
            "q": rng.normal(size=4),
            "r": rng.normal(size=3),
            "m": np.array([1.5]),
            "v": rng.normal(size=3),
        }
        name = str(rng.choice(list(sets)))
        planted = str(rng.choice(["nan", "inf", "zero_q", "mass", "big"]))
        if planted == "zero_q":
            sets["q"][:] = 0.0
        elif planted == "mass":
            sets["m"][:] = rng.choice([0.0, -2.0])
        elif planted == "big":
            sets[name][0] = 1e39
        else:
            sets[name][rng.integers(len(sets[name]))] = float(planted) * rng.choice([-1, 1])
        sets = {k: v[:, None] for k, v in sets.items()}
        state = bodies.solve(sets, "sym6", method, precision, conv).status[0]
        causes = bodies.invalid_inputs(sets, "sym6", method, precision, conv)
        if planted == "big" and name in ("m", "v"):  # finite, within range; the shift overflows float32
            assert not causes  # and hconv one says a value overflowed on the way
            continue
        assert bool(causes) == (state == "invalid_input"), (planted, name, method, precision, conv, causes)
        if planted in ("nan", "inf") and causes:
            assert (name, "not_finite") in causes
        if planted == "zero_q":
            assert ("q", "zero_quaternion") in causes
