"""Types for CSV's pass-through columns in Parquet: pyarrow's CSV reader as the reference, except
where it would change a value; a later block that does not fit is refused, never altered."""

from __future__ import annotations

import csv
import io
import math
import re

import pyarrow as pa
import pyarrow.csv as pacsv
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hconv.tables import csvtypes

#: pyarrow's null markers less its NaN spellings: the reference read keeps NaN a float, as hconv does
REFERENCE_NULLS = [v for v in pacsv.ConvertOptions().null_values if "nan" not in v.lower()]


def as_text(columns: dict) -> pa.Table:
    """The columns as hconv reads CSV's pass-through columns: text, empty fields as ""."""
    return pa.table({k: pa.array(v, pa.string()) for k, v in columns.items()})


def reference(columns: dict) -> pa.Table:
    """pyarrow's own CSV reader on the same values written as a CSV file."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows([list(columns), *zip(*columns.values())])
    data = buf.getvalue().encode()
    return pacsv.read_csv(io.BytesIO(data), convert_options=pacsv.ConvertOptions(null_values=REFERENCE_NULLS))


AS_PYARROW = {
    "int": ["1", "-2", "30", "4"],
    "float": ["1.50", "1e3", "-0.5", "7"],
    "inf": ["inf", "-inf", "Infinity", "2.5"],
    "empty_in_ints": ["1", "", "NA", "4"],
    "bool": ["true", "false", "True", "FALSE"],
    "ones_and_zeros": ["1", "0", "1", "1"],
    "date": ["2026-11-22", "2026-11-23", "2026-11-24", "2026-11-25"],
    "timestamp": ["2026-11-22T06:00:00", "2026-11-22 07:00:00", "2026-11-22", "2026-11-22T08:30:00"],
    "timestamp_ns": ["2026-11-22T06:00:00.5", "2026-11-22T06:00:00", "2026-11-22", "2026-11-22T06:00:00.123456789"],
    "utc": ["2026-11-22T06:00:00Z", "2026-11-22T06:00:00+01:00", "2026-11-22T06:00:00Z", "2026-11-22T06:00:00Z"],
    "all_empty": ["", "", "", ""],
    "text": ["a", "NA", "", "1"],
    "comma": ["1,5", "2", "3", "4"],
    "big_int64": ["9223372036854775807", "-9223372036854775808", "0", "1"],
}


def test_infer_types_as_pyarrow_csv_reader():
    types = csvtypes.infer(as_text(AS_PYARROW), AS_PYARROW)
    ref = reference(AS_PYARROW)
    assert types == {f.name: f.type for f in ref.schema}
    typed = csvtypes.apply(as_text(AS_PYARROW), types)
    assert typed.equals(ref)  # the values too, nulls included


@pytest.mark.parametrize(
    "values, why",
    [
        (["02134", "10001", "90210", "1"], "zip codes: pyarrow reads 2134"),
        (["007", "12", "", "3"], "an id with leading zeros"),
        (["00", "1", "2", "3"], "a double zero"),
        (["0x1F", "1", "2", "3"], "hex: pyarrow reads 31"),
        (["007", "1.5", "2", "3"], "an integer's leading zero in a float column"),
        (["99999999999999999999", "1", "2", "3"], "beyond int64: pyarrow rounds it to 1e20"),
        (["9007199254740993", "1.5", "2", "3"], "2**53 + 1 in a float column: pyarrow rounds it"),
        (["12:30:00", "01:02:03", "00:00:00", "23:59:59"], "times of day: no cast from text to time32"),
        (["tRue", "false", "true", "false"], "not one of pyarrow's spellings of a boolean"),
    ],
)
def test_infer_keeps_text_where_typing_changes_a_value(values, why):
    types = csvtypes.infer(as_text({"c": values}), ["c"])
    assert types == {"c": pa.string()}, why
    assert csvtypes.apply(as_text({"c": values}), types).column("c").to_pylist() == values


def test_infer_nan_is_a_float_not_null():
    values = ["NaN", "1", "nan", "-nan", "", "-NaN"]
    types = csvtypes.infer(as_text({"c": values}), ["c"])
    assert types == {"c": pa.float64()}  # pyarrow: int64, with nulls for the NaNs
    got = csvtypes.apply(as_text({"c": values}), types).column("c").to_pylist()
    assert math.isnan(got[0]) and got[1] == 1.0 and math.isnan(got[2]) and math.isnan(got[3])
    assert got[4] is None and math.isnan(got[5])  # only the empty field is missing


def test_infer_integer_exact_in_float64_stays_a_number():
    values = ["9007199254740992", "1.5", "2", "3"]  # 2**53: float64 holds it exactly
    assert csvtypes.infer(as_text({"c": values}), ["c"]) == {"c": pa.float64()}


@pytest.mark.parametrize(
    "first, later, whole",
    [
        (["1", "2"], ["3.5", "4"], pa.float64()),
        (["1", "2"], ["n/a", "4"], pa.int64()),  # a null marker fits any type: no misfit
        (["1", "2"], ["007", "4"], pa.string()),
        (["1", "2"], ["x", "4"], pa.string()),
        (["", ""], ["5", ""], pa.int64()),
        (["", ""], ["hello", ""], pa.string()),
        (["2026-11-22", "2026-11-23"], ["2026-11-22T06:00:00", ""], pa.timestamp("s")),
        (["1", "0"], ["true", "false"], pa.bool_()),
        (["1", "2"], ["99999999999999999999", "4"], pa.string()),
    ],
)
def test_apply_later_block_that_does_not_fit_raises_retype_and_whole_file_fits_both(first, later, whole):
    blocks = [as_text({"c": first}), as_text({"c": later})]
    types = csvtypes.infer(blocks[0], ["c"])
    if types["c"] == whole:
        csvtypes.apply(blocks[1], types)  # fits
    else:
        with pytest.raises(csvtypes.Retype) as err:
            csvtypes.apply(blocks[1], types)
        assert err.value.column == "c" and err.value.value in later
    batches = [b.to_batches()[0] for b in blocks]
    assert csvtypes.whole_file(batches) == {"c": whole}
    both = pa.concat_tables(csvtypes.apply(b, {"c": whole}) for b in blocks)
    if whole == pa.string():
        assert both.column("c").to_pylist() == first + later
    else:  # the type pyarrow infers from the whole file, and its values
        assert both.equals(reference({"c": first + later}))


@pytest.mark.parametrize(
    "values, kept",
    [
        (["NA", "null", ""], pa.string()),
        (["NA", "NA", "NA"], pa.string()),
        (["#N/A", "NULL"], pa.string()),
        (["", ""], pa.null()),  # blanks alone: nothing written is lost
    ],
)
def test_infer_null_markers_alone_stay_text(values, kept):
    """Before: a column of NA, null and blanks only got pyarrow's null type, its text lost in Parquet."""
    types = csvtypes.infer(as_text({"s": values}), ["s"])
    assert types == {"s": kept}
    typed = csvtypes.apply(as_text({"s": values}), types)
    assert typed.column("s").to_pylist() == (values if kept == pa.string() else [None] * len(values))


@pytest.mark.parametrize(
    "blocks, whole",
    [
        ([["NA", ""], ["null", "NA"]], pa.string()),
        ([["", ""], ["NA", ""]], pa.string()),
        ([["", ""], ["", ""]], pa.null()),
        ([["NA", ""], ["1", "NA"]], pa.int64()),  # a value types the column; its markers are null
    ],
)
def test_whole_file_null_markers_alone_stay_text(blocks, whole):
    batches = [as_text({"s": b}).to_batches()[0] for b in blocks]
    assert csvtypes.whole_file(batches) == {"s": whole}


def test_apply_names_the_first_value_that_does_not_fit():
    values = [str(k) for k in range(1000)]
    values[613], values[800] = "6.5", "x"
    with pytest.raises(csvtypes.Retype) as err:
        csvtypes.apply(as_text({"c": values}), {"c": pa.int64()})
    assert (err.value.column, err.value.value) == ("c", "6.5")


CELLS = st.one_of(
    st.integers(-(10**20), 10**20).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", "NA", "n/a", "NaN", "-nan", "inf", "007", "0x10", "1e3", "1.50", "+4", " 5", "true", "0"]),
    st.text(max_size=4),
)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.lists(st.lists(CELLS, min_size=1, max_size=6), min_size=1, max_size=4))
def test_apply_whole_file_types_keep_every_value(blocks):
    """Whatever the text, each typed value is what Python's own parsers read, the text keeps its
    column text, and a null is only ever a null marker."""
    batches = [as_text({"c": b}).to_batches()[0] for b in blocks]
    types = csvtypes.whole_file(batches)
    nulls = set(REFERENCE_NULLS)
    for block, batch in zip(blocks, batches):
        got = csvtypes.apply(pa.Table.from_batches([batch]), types).column("c").to_pylist()
        for text, value in zip(block, got):
            if value is None:
                assert text in nulls
            elif types["c"] == pa.int64():
                assert value == int(text) and not re.match("[+-]?0[0-9xX]", text)
            elif types["c"] == pa.float64():
                want = float(text)
                assert value == want or (math.isnan(value) and math.isnan(want))
                if "." not in text and "e" not in text.lower() and text.lstrip("+-").isdigit():
                    assert int(value) == int(text)  # an integer stays exact
            elif types["c"] == pa.string():
                assert value == text
