"""hconv.convert_body: one body with a Job, as hconv one converts it (hconv.tables.body)."""

from __future__ import annotations

import math

import numpy as np
import pyarrow as pa
import pytest

import hconv
from hconv.errors import UsageError
from hconv.tables import body


def test_convert_body_gives_what_convert_table_gives_for_its_row():
    job = hconv.Job(
        conventions=hconv.Conventions(about="pivot"),
        unit_options={"I": "g*cm**2"},
        omega_unit="deg/s",
    )
    H, I, r, m = [0.01, 0.02, 0.03], [2.5e4, 2.5e4, 4e4, 0.0, 0.0, 0.0], [0.1, 0.0, 0.0], 1.0
    res = hconv.convert_body(H, I, r, m=m, job=job)
    names = ["Hx", "Hy", "Hz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz", "rx", "ry", "rz", "m"]
    table = pa.table({n: [v] for n, v in zip(names, [*H, *I, *r, m])})
    out = hconv.convert_table(table, job=job)
    assert [float(x) for x in res.w] == [out.column(c)[0].as_py() for c in ("wx", "wy", "wz")]
    assert (res.status, res.unit, float(res.residual)) == ("ok", "deg/s", out.column("residual")[0].as_py())


def test_convert_body_names_every_missing_value_as_python_spells_it():
    with pytest.raises(UsageError) as info:
        hconv.convert_body([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], about="free")
    assert str(info.value) == (
        "about='free' needs r, the centre of mass relative to the origin of H; the mass m; and v, the "
        "velocity of the centre of mass; pass r=..., m=..., v=..."
    )


def test_convert_body_refuses_a_unit_for_a_column():
    job = hconv.Job(unit_options={"Hx": "g*m**2/s"})
    with pytest.raises(UsageError, match=r"^unit_options=\{'Hx': 'g\*m\*\*2/s'\}: convert_body takes a unit per set: "):
        hconv.convert_body([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], job=job)


def test_convert_body_refuses_an_inertia_of_no_form():
    with pytest.raises(UsageError, match=r"^I takes 1 \(isotropic\), 3 .* values, got 4$"):
        hconv.convert_body([1.0, 2.0, 3.0], [1.0, 2.0, 3.0, 4.0])


def test_convert_body_takes_a_tensor_as_its_nine_numbers():
    res = hconv.convert_body([1.0, 2.0, 3.0], np.diag([1.0, 2.0, 4.0]))
    assert [float(x) for x in res.w] == [1.0, 1.0, 0.75]


def test_convert_body_gives_omega_in_the_unit_asked():
    res = hconv.convert_body([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], omega_unit="deg/s")
    assert res.unit == "deg/s" and [float(x) for x in res.w] == [math.degrees(1.0)] * 3


def test_invalid_inputs_names_the_value_to_blame():
    job = hconv.Job()
    res = hconv.convert_body([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], q=[0, 0, 0, 0], job=job)
    assert res.status == "invalid_input"
    assert body.invalid_inputs([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], q=[0, 0, 0, 0], job=job) == [("q", "zero_quaternion")]


def test_unread_names_the_values_a_run_does_not_read():
    assert body.unread(hconv.Job(), ["H", "I", "r", "v"]) == ["r", "v"]
    free = hconv.Job(conventions=hconv.Conventions(about="free"))
    assert body.unread(free, ["H", "I", "r", "m", "v"]) == []


def test_convert_body_reads_pint_quantities_in_their_own_units():
    """H, I, r, m and v as pint Quantities in units other than SI give what their SI numbers give
    (the factors exact: 1 g·cm² = 1e-7 kg·m², 1 mm = 1e-3 m, 1 g = 1e-3 kg, 1 km/h = 1/3.6 m/s),
    and ω comes back as a Quantity; before, numpy dropped the units (ω 1e7 too large)."""
    import pint

    u = pint.UnitRegistry()
    kw = {"about": "free", "method": "exact"}
    got = hconv.convert_body(
        [1.0, 2.0, 3.0] * u("g*cm**2/s"),
        [1.0, 2.0, 4.0, 0.5, 0.0, 0.0] * u("g*cm**2"),
        [10.0, 0.0, 20.0] * u("mm"),
        m=300.0 * u("g"),
        v=[0.0, 3.6, 0.0] * u("km/h"),
        **kw,
    )
    want = hconv.convert_body(
        [1e-7, 2e-7, 3e-7], [1e-7, 2e-7, 4e-7, 0.5e-7, 0.0, 0.0], [0.01, 0.0, 0.02], m=0.3, v=[0.0, 1.0, 0.0], **kw
    )
    assert str(got.w.units) == "radian / second"
    assert got.w.magnitude.tolist() == pytest.approx(want.w.tolist(), rel=1e-12)
    assert got.status == want.status


def test_convert_body_quantity_of_another_dimension_or_with_a_unit_option_is_refused():
    import pint

    u = pint.UnitRegistry()
    with pytest.raises(UsageError, match=r"^m: 'm' is not a unit of mass \(kg\)$"):
        hconv.convert_body([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [0.0, 0.0, 0.1], m=2 * u.m, v=[0, 0, 0], about="free")
    with pytest.raises(UsageError, match=r"^H is a pint Quantity, which carries its unit: drop unit_options="):
        hconv.convert_body(
            [1.0, 2.0, 3.0] * u("g*cm**2/s"), [1.0, 2.0, 3.0], job=hconv.Job(unit_options={"H": "g*cm**2/s"})
        )
