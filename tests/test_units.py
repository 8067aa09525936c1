"""Units in and out: any unit pint understands, SI without pint, and the unit-slip status."""

from __future__ import annotations

import math
import subprocess
import sys
from fractions import Fraction

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import command_imports, hconv_inprocess, mp_solve, need, physical_bodies, rel_err, six, vec, w_of

import hconv
from hconv.errors import UsageError
from hconv.solve import units
from hconv.tables.job import Job

SIX = ["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"]


def test_factor_known_conversions():
    # Independent arithmetic: 1 g·cm² = 1e-3 kg · 1e-4 m²; 1 lb = 0.45359237 kg, 1 ft = 0.3048 m.
    assert units.factor("I", "g*cm**2") == pytest.approx(1e-7, rel=1e-15)
    assert units.factor("I", "lb*ft**2") == pytest.approx(0.45359237 * 0.3048**2, rel=1e-15)
    assert units.factor("H", "g*mm**2/s") == pytest.approx(1e-9, rel=1e-15)
    assert units.factor("I", "kg·m²") == 1.0 and units.factor("H", "N*m*s") == 1.0
    assert units.omega_factor("deg/s") == pytest.approx(180 / math.pi, rel=1e-15)
    assert units.omega_factor("rpm") == pytest.approx(60 / (2 * math.pi), rel=1e-15)


@pytest.mark.parametrize(
    "bad, needle",
    [
        ("g*cm", "not a unit of inertia"),
        ("furlongs_per_blob", "does not understand"),
        ("degC*m**2", "offset|not a unit"),
    ],
)
def test_factor_bad_unit_is_a_usage_error(bad, needle):
    with pytest.raises(UsageError, match=needle):
        units.factor("I", bad, "--unit I")


def test_convert_gram_centimetre_inputs_give_the_same_omega(rng):
    I = physical_bodies(rng, 40)
    H = rng.normal(size=(40, 3))
    want = mp_solve(I, H)
    si = pa.table({**vec("H", H), **dict(zip(SIX, six(I).T))})
    cgs = pa.table({**vec("H", H * 1e7), **dict(zip(SIX, six(I).T * 1e7))})
    job = Job(unit_options=(("I", "g*cm**2"), ("H", "g*cm**2/s")))
    got = hconv.convert_table(cgs, job=job)
    assert rel_err(w_of(got), want).max() < 1e-14
    assert rel_err(w_of(hconv.convert_table(si)), want).max() < 1e-14
    assert got.schema.field("Ixy").metadata[b"unit"] == b"g*cm**2"  # the unit it was read in


def test_convert_parquet_unit_metadata_is_read(tmp_path, rng, capsys):
    I = physical_bodies(rng, 20)
    H = rng.normal(size=(20, 3))
    fields = [pa.field(c, pa.float64(), metadata={"unit": "g*cm**2/s"}) for c in ("Hx", "Hy", "Hz")]
    fields += [pa.field(c, pa.float64(), metadata={"unit": "g*cm**2"}) for c in SIX]
    t = pa.Table.from_arrays([pa.array(x) for x in np.concatenate([H.T, six(I).T]) * 1e7], schema=pa.schema(fields))
    pq.write_table(t, tmp_path / "cgs.parquet")
    proc = hconv_inprocess(
        "convert",
        str(tmp_path / "cgs.parquet"),
        str(tmp_path / "out.parquet"),
        "--omega-unit",
        "deg/s",
        "-q",
        capsys=capsys,
    )
    assert proc.returncode == 0, proc.stderr.decode()
    out = pq.read_table(tmp_path / "out.parquet")
    assert out.schema.field("wx").metadata[b"unit"] == b"deg/s"
    assert rel_err(w_of(out), np.degrees(mp_solve(I, H))).max() < 1e-14


def test_convert_unit_option_beats_metadata_and_names_bad_keys():
    t = pa.table({"Hx": [1.0], "Hy": [0.0], "Hz": [0.0], "I": [2.0]})
    got = hconv.convert_table(t, job=Job(unit_options=(("Hx", "kg*cm**2/s"),)))
    assert w_of(got)[0, 0] == pytest.approx(0.5e-4, rel=1e-15)
    with pytest.raises(UsageError, match="'Lx' is not a column hconv reads"):
        hconv.convert_table(t, job=Job(unit_options=(("Lx", "kg"),)))


def test_status_unit_suspect_catches_gram_centimetre_slip():
    # A 1 m water cube (1000 kg, moments 1000·2/12): plausible. Its g·cm² numbers read as kg·m²,
    # or its mass given in grams, are not.
    ok_I = 1000 * 2 / 12
    t = pa.table(
        {
            "Hx": [1.0] * 4,
            "Hy": [0.0] * 4,
            "Hz": [0.0] * 4,
            "I": [ok_I, ok_I * 1e7, ok_I, ok_I * 1e-7],
            "m": [1000.0, 1000.0, 1e6, 1000.0],
        }
    )
    got = hconv.convert_table(t).column("status").to_pylist()
    # row 2 (I 1e7 too big) could be inertia about a far pivot, so without --about only the
    # "too dense" rows are certain; about the centre of mass every slip is caught.
    assert got == ["ok", "ok", "unit_suspect", "unit_suspect"]
    t2 = (
        t.append_column("rx", pa.array([0.0] * 4))
        .append_column("ry", pa.array([0.0] * 4))
        .append_column("rz", pa.array([0.0] * 4))
    )
    from hconv.solve.options import Conventions

    got = hconv.convert_table(t2, job=Job(conventions=Conventions(about="pivot"))).column("status").to_pylist()
    assert got == ["ok", "unit_suspect", "unit_suspect", "unit_suspect"]


def test_one_units_and_omega_unit(capsys):
    proc = hconv_inprocess(
        "one",
        "--H",
        "1e7,0,0",
        "--I",
        "2e7",
        "--unit",
        "H=g*cm**2/s",
        "--unit",
        "I=g*cm**2",
        "--omega-unit",
        "deg/s",
        "--json",
        capsys=capsys,
    )
    assert proc.returncode == 0, proc.stderr.decode()
    import json

    out = json.loads(proc.stdout)
    assert out["unit"] == "deg/s" and out["w"][0] == pytest.approx(math.degrees(0.5), rel=1e-15)


def test_convert_omega_unit_refused_for_document_methods(capsys):
    proc = hconv_inprocess(
        "one",
        "--H",
        "1,0,0",
        "--I",
        "2,2,2",
        "--r",
        "1,1,0",
        "--method",
        "document",
        "--omega-unit",
        "deg/s",
        capsys=capsys,
    )
    assert proc.returncode == 2 and b"m^2/s" in proc.stderr


# Numbers that carry a unit or a mask, handed to hconv.convert (issue 24). Before the fix numpy
# made bare numbers of all of them: a pint Quantity kept its magnitude (with only pint's
# UnitStrippedWarning), astropy-, unyt- and xarray-style arrays and masked arrays silently.

G_CM2 = Fraction(1, 10**7)  # 1 g·cm² = 1e-3 kg · (1e-2 m)² in kg·m², exactly


def _ureg():
    import pint

    return pint.UnitRegistry()


def _frac(a) -> np.ndarray:
    return np.array([[Fraction(x) for x in row] for row in np.atleast_2d(a)], dtype=object)


def test_convert_pint_quantities_are_read_in_their_own_units():
    """The issue's example: before, ω = [1, 1, 1] (the magnitudes divided, units dropped)."""
    ureg = _ureg()
    res = hconv.convert([1, 2, 3] * ureg("g*cm**2/s"), [1, 2, 3] * ureg("kg*m**2"))
    assert str(res.w.units) == "radian / second" and res.unit == "rad/s" and res.status == "ok"
    # H_i / I_i = 1e-7·i / i; pint's factor for g·cm² (a file's too) is 1e-3·1e-4, one rounding off
    assert res.w.magnitude.tolist() == pytest.approx([float(G_CM2)] * 3, rel=1e-15)
    assert (res.w + 1 * ureg("rad/s")).magnitude[0] == 1 + 1e-7  # the caller's registry: pint mixes no others


def test_convert_pint_tensor_and_offset_in_their_own_units(rng):
    ureg = _ureg()
    I = physical_bodies(rng, 8)  # (N, 3, 3) in kg·m²
    I_g_mm2 = I * 1e10  # the numbers a g·mm² export holds
    H = rng.normal(size=(8, 3))
    res = hconv.convert(H * ureg("g*cm**2/s"), six(I_g_mm2) * ureg("g*mm**2"))
    # Independent: each number times its exact factor to SI, in rationals, then a 50-digit solve.
    H_si = (_frac(H) * G_CM2).astype(float)
    I_si = (_frac(I_g_mm2.reshape(-1, 9)) * Fraction(1, 10**9)).astype(float).reshape(-1, 3, 3)
    assert rel_err(res.w.to("rad/s").magnitude, mp_solve(I_si, H_si)).max() < 1e-14
    # The document method reads r too: ω_i = (r_j² + r_k²) / I_i · H_i, in m²/s.
    doc = hconv.convert(
        [1, 1, 1] * ureg("g*cm**2/s"), [2, 3, 4] * ureg("g*cm**2"), [1, 2, 3] * ureg("mm"), method="document"
    )
    r2 = [Fraction(k, 1000) ** 2 for k in (1, 2, 3)]
    want = [(r2[1] + r2[2]) / 2, (r2[0] + r2[2]) / 3, (r2[0] + r2[1]) / 4]  # the 1e-7 of H and I cancel
    assert doc.w.units == ureg("m**2/s").units
    assert doc.w.magnitude.tolist() == pytest.approx([float(x) for x in want], rel=1e-15)


@pytest.mark.parametrize(
    "name, wrong, message",
    [
        ("H", "kg*m**2", r"^H: 'kg \* m \*\* 2' is not a unit of angular momentum \(kg\*m\*\*2/s\)$"),
        ("I", "kg*m**2/s", r"^I: 'kg \* m \*\* 2 / s' is not a unit of inertia \(kg\*m\*\*2\)$"),
        ("r", "s", r"^r: 's' is not a unit of length \(m\)$"),
    ],
    ids=["H", "I", "r"],
)
def test_convert_pint_unit_of_another_quantity_is_refused_naming_the_argument(name, wrong, message):
    ureg = _ureg()
    units_given = {"H": "kg*m**2/s", "I": "kg*m**2", "r": "m", name: wrong}
    H, I, r = ([1, 2, 3] * ureg(units_given[k]) for k in "HIr")
    with pytest.raises(UsageError, match=message):
        hconv.convert(H, I, r, method="document")


def test_convert_masked_entries_are_invalid_input_rows():
    H = np.ma.masked_array([[1.0, 2.0, 3.0], [1e300, 2.0, 3.0], [4.0, 4.0, 4.0]], mask=[[0] * 3, [1, 0, 0], [0] * 3])
    res = hconv.convert(H, np.full((3, 3), 2.0)[:, None] * np.eye(3))  # three rows of moments, as matrices
    assert res.status.tolist() == ["ok", "invalid_input", "ok"]
    assert np.isnan(res.w[1]).all() and res.w[2].tolist() == [2.0, 2.0, 2.0]
    assert H.data[1, 0] == 1e300 and H.mask[1, 0]  # the caller's array untouched
    # in a Quantity too, and a masked I
    I = np.ma.masked_array([[2.0] * 3] * 3, mask=[[0] * 3, [0] * 3, [0, 0, 1]])
    res = hconv.convert(H.data * _ureg()("g*cm**2/s"), I[:, None] * np.eye(3) * _ureg()("g*cm**2"))
    assert res.status.tolist() == ["ok", "ok", "invalid_input"]


def test_convert_list_of_quantities_or_masked_arrays_is_refused():
    ureg = _ureg()
    with pytest.raises(UsageError, match=r"^H holds pint Quantities, whose units numpy would drop; "):
        hconv.convert([[1, 2, 3] * ureg("g*cm**2/s"), [4, 5, 6] * ureg("g*cm**2/s")], np.ones((2, 3)))
    masked = np.ma.masked_array([1.0, 2.0, 3.0], mask=[0, 1, 0])
    with pytest.raises(UsageError, match=r"^I holds masked arrays, whose masks numpy would drop; "):
        hconv.convert(np.ones((2, 3)), ([1.0, 1.0, 1.0], masked))


def _stand_in(module: str, name: str, attribute: str) -> type:
    """An ndarray subclass standing in for a unit library's array type: of that library's module
    and class name, carrying its unit in the same attribute (astropy.units.Quantity: ``unit``;
    unyt's unyt_array: ``units``). Neither library is installed here (astropy alone is ~10 MB,
    with pyerfa), and hconv knows them only by those names and attributes."""

    class StandIn(np.ndarray):
        def __new__(cls, values, unit):
            obj = np.asarray(values, dtype=float).view(cls)
            setattr(obj, attribute, unit)
            return obj

        def __array_finalize__(self, obj):
            setattr(self, attribute, getattr(obj, attribute, None))

    StandIn.__module__, StandIn.__name__, StandIn.__qualname__ = module, name, name
    return StandIn


@pytest.mark.parametrize(
    "module, name, attribute, text",
    [
        ("astropy.units.quantity", "Quantity", "unit", "astropy's Quantity in g cm2 / s"),
        ("unyt.array", "unyt_array", "units", "unyt's unyt_array in g cm2 / s"),
    ],
    ids=["astropy", "unyt"],
)
def test_convert_array_of_another_unit_library_is_refused(module, name, attribute, text):
    cls = _stand_in(module, name, attribute)
    H = cls([[1.0, 2.0, 3.0]], "g cm2 / s")
    assert np.asarray(H).tolist() == [[1.0, 2.0, 3.0]]  # what numpy would have read
    with pytest.raises(
        UsageError,
        match=rf"^H is {text}, which hconv does not read; pass a pint Quantity or plain numbers in "
        r"kg\*m\*\*2/s \(e\.g\. H\.to_value\('kg\*m\*\*2/s'\)\)$",
    ):
        hconv.convert(H, np.ones((1, 3)))


def test_convert_xarray_units_attribute_is_read():
    xr = need("xarray")
    res = hconv.convert(
        np.array([[1.0, 2.0, 3.0]]), xr.DataArray(np.array([[1.0, 2.0, 4.0]]), attrs={"units": "g*cm**2"})
    )
    want = [float(Fraction(h) / (Fraction(i) * G_CM2)) for h, i in ((1, 1), (2, 2), (3, 4))]
    assert res.w[0].tolist() == pytest.approx(want, rel=1e-15) and type(res.w) is np.ndarray
    # pint-xarray keeps the unit in the data: that Quantity is read
    res = hconv.convert(xr.DataArray([1.0, 2.0, 3.0] * _ureg()("g*cm**2/s")), [1.0, 2.0, 3.0])
    assert res.w.magnitude.tolist() == pytest.approx([float(G_CM2)] * 3, rel=1e-15)
    with pytest.raises(UsageError, match=r"^I.attrs\['units'\]: 'kg\*m\*\*2/s' is not a unit of inertia"):
        hconv.convert(np.ones((1, 3)), xr.DataArray(np.ones((1, 3)), attrs={"units": "kg*m**2/s"}))


@pytest.mark.parametrize("key", ["units", "unit", "Units", "UNIT"])
def test_convert_unit_in_attrs_is_read_under_any_spelling(key):
    """xarray's ``attrs`` under ``unit`` or in capitals was dropped (ω 1e7 too large), as was a
    pandas Series' ``attrs``: every spelling of the key is read."""
    xr, pd = need("xarray"), need("pandas")
    for H in (xr.DataArray([1.0, 2.0, 3.0]), pd.Series([1.0, 2.0, 3.0])):
        H.attrs[key] = "g*cm**2/s"
        res = hconv.convert(H, [1.0, 1.0, 1.0])  # kg·m²
        assert res.w.tolist() == pytest.approx([float(k * G_CM2) for k in (1, 2, 3)], rel=1e-15)
    with pytest.raises(UsageError, match=rf"^H\.attrs\[{key!r}\]: 'kg\*m\*\*2' is not a unit of angular momentum"):
        hconv.convert(
            pd.Series([1.0, 1.0, 1.0], name="H").pipe(lambda s: s.attrs.update({key: "kg*m**2"}) or s), [1, 1, 1]
        )


def test_convert_array_like_with_a_unit_attribute_is_refused_whatever_its_class():
    """Not an ndarray, but numpy reads it through ``__array__`` and would drop its ``unit``."""

    class Measured:
        unit = "g*cm**2/s"

        def __array__(self, dtype=None, copy=None):
            return np.array([1.0, 2.0, 3.0], dtype=dtype)

    with pytest.raises(UsageError, match=r"^H is test_units's Measured in g\*cm\*\*2/s, which hconv does not read"):
        hconv.convert(Measured(), [1.0, 1.0, 1.0])


def test_convert_dimensionless_quantity_names_its_unit():
    with pytest.raises(UsageError, match=r"^H: 'dimensionless' is not a unit of angular momentum"):
        hconv.convert([1.0, 2.0, 3.0] * _ureg()("dimensionless"), [1.0, 1.0, 1.0])


def test_convert_plain_numbers_load_no_pint():
    """pint is found by its classes' modules, never imported to look: hconv.convert on numbers,
    masked arrays and lists (and hconv one, tests/test_cli.py) starts without it."""
    code = (
        "import sys, numpy as np, hconv\n"
        "hconv.convert([[1, 2, 3]], np.ma.masked_array(np.ones((1, 3)), mask=[[0, 1, 0]]))\n"
        "print('pint' in sys.modules)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=60)
    assert proc.stdout.decode().split() == ["False"], proc.stderr.decode()


def test_convert_extra_k_that_is_not_a_bare_number_names_it():
    """A Quantity given as extra_k raised pint's own DimensionalityError, naming nothing."""
    for bad in (1 * _ureg()("kg*m**2"), "2", -1.0, float("nan")):
        with pytest.raises(UsageError, match=r"^extra_k must be a number >= 0 \(an error constant, no unit\), got "):
            hconv.convert([1.0, 2.0, 3.0], [1.0, 1.0, 1.0], extra_k=bad)


@pytest.mark.parametrize("where", ["command", "library"])
def test_factor_imports_pint_without_dask_only_in_the_command(where):
    """The hconv command imports pint as where dask is absent (dask's import cost a run with
    units a third of a second); a library caller's pint keeps its dask support, and dask itself
    still imports afterwards in both."""
    need("dask")
    need("pint")
    setup = "from hconv.solve import units; units.PINT_WITHOUT_DASK = True" if where == "command" else ""
    code = (
        f"import sys; {setup}\n"
        "from hconv.solve import units\n"
        "assert abs(units.factor('I', 'g*cm**2') - 1e-7) < 1e-21\n"
        "import pint.compat; print('dask' in sys.modules, pint.compat.dask_array is not None)\n"
        "import dask; print(dask.__name__)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=60)
    assert proc.returncode == 0, proc.stderr.decode()
    imported, supported = proc.stdout.decode().split()[:2]
    assert (imported, supported) == (("False", "False") if where == "command" else ("True", "True"))


def test_command_with_units_does_not_import_dask():
    need("dask")
    args = ["one", "--H", "1,2,3", "--I", "25000,25000,40000", "--unit", "I=g*cm**2"]
    exit_code, imported, err = command_imports(args, "dask")
    assert (exit_code, imported) == (0, False), err
