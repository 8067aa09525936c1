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
