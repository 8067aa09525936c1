"""The run configuration: checked once when made, from Python or the CLI alike."""

from __future__ import annotations

import dataclasses

import pytest

from hconv.errors import UsageError
from hconv.solve.options import Conventions
from hconv.tables.job import Job


def test_job_mapping_and_units_as_dict_or_pairs():
    assert Job(mapping={"Hx": "Lx", "Hy": "Ly"}) == Job(mapping=(("Hx", "Lx"), ("Hy", "Ly")))
    assert Job(unit_options={"I": "g*cm**2"}).unit_options == (("I", "g*cm**2"),)
    with pytest.raises(UsageError, match="mapping takes a dict such as"):
        Job(mapping="Hx=Lx")


def test_job_is_immutable():
    with pytest.raises(dataclasses.FrozenInstanceError):
        Job().method = "lapack"


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"method": "exakt"}, "unknown method 'exakt'; choose one of: exact"),
        ({"quat_order": "zyxw"}, "quat_order must be one of wxyz, xyzw, got 'zyxw'"),
        ({"omega_unit": "parsecs"}, "omega_unit: 'parsecs'"),
        ({"method": "document", "omega_unit": "deg/s"}, r"gives m\^2/s, which is not an angular velocity"),
        ({"conventions": "world"}, "conventions must be a Conventions, got str"),
        ({"keep_text": "no"}, "keep_text must be True or False, got 'no'"),
        ({"diagnostics": "no"}, "diagnostics must be True or False, got 'no'"),  # 'no' read as True
        ({"observed": 1}, "observed must be True or False, got 1"),
    ],
)
def test_job_bad_option_is_refused_when_made(kwargs, needle):
    with pytest.raises(UsageError, match=needle):
        Job(**kwargs)


def test_job_needs_and_output_unit():
    job = Job("document", conventions=Conventions(about="pivot"), observed=True)
    assert list(job.needs()) == ["r", "m", "w_obs"]
    assert job.unit == "m^2/s" and job.omega_scale == 1.0
    deg = Job(omega_unit="deg/s")
    assert deg.unit == "deg/s" and deg.omega_scale == pytest.approx(57.29577951308232, rel=1e-15)


def test_job_set_factor_reads_whole_set_units():
    job = Job(unit_options=(("I", "g*cm**2"), ("Hx", "kg*cm**2/s")))
    assert job.set_factor("I") == pytest.approx(1e-7, rel=1e-15)
    assert job.set_factor("H") == 1.0  # a single column's unit is the planner's business, not a set's


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"mapping": {"Hw": "Lx"}}, "mapping={'Hw': 'Lx'}: hconv has no column 'Hw'; map one of"),
        ({"mapping": (("Hx", "a"), ("Hx", "b"))}, r"mapping gives Hx twice \(a and b\)"),
        ({"mapping": {"Hx": "a", "Hy": "a"}}, "mapping points both Hx and Hy at column 'a'"),
        ({"unit_options": {"I": "furlongs"}}, r"unit_options=\{'I': 'furlongs'\}: .furlongs. is not a unit of inertia"),
        ({"unit_options": {"Hx": "kg"}}, r"unit_options=\{'Hx': 'kg'\}: 'kg' is not a unit of angular momentum"),
    ],
)
def test_job_map_and_units_checked_when_made_without_the_data(kwargs, needle):
    with pytest.raises(UsageError, match=needle):
        Job(**kwargs)


def test_job_unit_given_twice_with_different_units_is_refused(tmp_path, capsys):
    """Before: the last --unit I=... won silently, while a doubled --map was refused."""
    from helpers import run_inprocess

    with pytest.raises(UsageError, match=r"^unit_options gives I twice \(g\*cm\*\*2 and kg\*m\*\*2\); give it once$"):
        Job(unit_options=(("I", "g*cm**2"), ("I", "kg*m**2")))
    assert Job(unit_options=(("I", "g*cm**2"), ("I", "g*cm**2"))).set_factor("I") == pytest.approx(1e-7)
    code, _, err = run_inprocess(
        "convert", "in.csv", str(tmp_path / "o.csv"), "--unit", "I=g*cm**2", "--unit", "I=kg*m**2", capsys=capsys
    )
    assert (code, err) == (2, "hconv: error: --unit gives I twice (g*cm**2 and kg*m**2); give it once\n")


def test_job_unit_for_another_column_waits_for_the_data():
    assert Job(unit_options={"Lx": "g*cm**2/s"}).unit_options == (("Lx", "g*cm**2/s"),)


@pytest.mark.parametrize("function", ["convert_table", "convert_file", "diagnose_file", "compare_file"])
def test_check_job_not_a_job_is_refused_naming_the_fix(function, tmp_path):
    """Before: job='exact' gave AttributeError: 'str' object has no attribute 'engine'."""
    import pyarrow as pa

    import hconv
    from hconv.tables.pipeline import convert_file
    from hconv.tools.compare import compare_file
    from hconv.tools.diagnose import diagnose_file

    src = str(tmp_path / "in.csv")
    call = {
        "convert_table": lambda job: hconv.convert_table(pa.table({"Hx": [1.0]}), job=job),
        "convert_file": lambda job: convert_file(src, src + ".csv", job=job),
        "diagnose_file": lambda job: diagnose_file(src, job=job),
        "compare_file": lambda job: compare_file(src, job=job),
    }[function]
    with pytest.raises(
        UsageError, match=r"^job takes a hconv.Job, got 'exact' \(str\); for the method alone pass method='exact'$"
    ):
        call("exact")
    with pytest.raises(
        UsageError, match=r"^job takes a hconv.Job, got \{'method': 'exact'\} \(dict\); make one with hconv.Job"
    ):
        call({"method": "exact"})


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"omega_unit": 5}, "omega_unit takes a unit as text, e.g. 'deg/s', got 5"),
        ({"omega_unit": None}, "omega_unit takes a unit as text"),
        ({"conventions": Conventions(degenerate="pinv", degenerate_rtol=1e-9)}, None),
    ],
)
def test_job_wrong_type_is_a_usage_error_naming_the_keyword(kwargs, needle):
    if needle is None:
        assert Job(**kwargs).conventions.degenerate_rtol == 1e-9
        with pytest.raises(UsageError, match="degenerate_rtol must be at least 0 and below 1, got '1e-9'"):
            Conventions(degenerate="pinv", degenerate_rtol="1e-9")
        return
    with pytest.raises(UsageError, match=needle):
        Job(**kwargs)
