"""The recipes of docs/recipes.md: each is a file in docs/recipes/, quoted word for word in the doc,
and each, run as a user runs it on the real engine, writes what ``hconv convert`` writes for the
same files: the same rows in the same order, every value to the bit, the statuses, and ω's unit;
and prints one line naming what it wrote and the rows there.

Each test skips when its engine is not installed (``pip install -e '.[recipes]'``; Spark also
needs Java); CI installs every engine, so none skips there. The Ray and Spark tests, 5 to 25 s
each, are marked ``engines_slow``: ``pytest -m "not engines_slow"`` leaves them out locally.
Spark runs with its web UI off and the JVM's quick compiler only (:func:`_spark_conf`): what it
computes is the same, in much less CPU time on data this small (docs/measurements.md).
The dataset is twelve files from ``hconv generate``, so that a directory of output
files whose names do not sort (part.10 before part.2) shows, with rows flagged singular (ω NaN)
and ill_conditioned among the ok ones, and with the inertia stored in g·cm² (field metadata
``unit``), so that a recipe whose engine drops that metadata and reads it in SI is caught.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest
from helpers import need

import hconv
from hconv.tables.pipeline import convert_file
from hconv.tools.generate import generate_file

ROOT = Path(__file__).resolve().parents[1]
RECIPES = ROOT / "docs" / "recipes"
DOC = ROOT / "docs" / "recipes.md"
FILES = 12
INERTIA = ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """Twelve Parquet files of 2,000 to 4,750 rows, named so that they sort, the inertia in g·cm²."""
    folder = tmp_path_factory.mktemp("recipes") / "in"
    folder.mkdir()
    for k in range(FILES):
        path = folder / f"part-{k:02d}.parquet"
        generate_file(str(path), 2000 + 250 * k, seed=k, cond_max=1e17)
        table = pq.read_table(path)
        for c in INERTIA:
            i = table.schema.get_field_index(c)
            g_cm2 = pc.multiply(table.column(c), 1e7)
            table = table.set_column(i, pa.field(c, pa.float64(), metadata={"unit": "g*cm**2"}), g_cm2)
        pq.write_table(table, path)
    return folder


@pytest.fixture(scope="module")
def reference(dataset) -> pa.Table:
    """``hconv convert`` of each file (its library call, which is what the command runs), in the
    files' order."""
    out = dataset.parent / "hconv"
    out.mkdir()
    for path in sorted(dataset.iterdir()):
        convert_file(str(path), str(out / path.name))
    table = _read(out)
    # rows of every kind: ok, ill_conditioned, and singular with ω NaN
    assert {"ok", "ill_conditioned", "singular"} <= set(_plain(table.column("status")).to_pylist())
    assert np.isnan(table.column("wx").to_numpy()).any()
    assert hconv.units_of(table.schema)["Ixx"] == "g*cm**2"
    return table


def _read(path: Path) -> pa.Table:
    """A Parquet file, or a folder's Parquet files one after the other in the order of their names."""
    files = sorted(path.glob("*.parquet")) if path.is_dir() else [path]
    assert files, f"{path}: no Parquet files"
    return pa.concat_tables([pq.read_table(f) for f in files])


def _run(recipe: str, dataset: Path, cwd: Path, env: dict[str, str] | None = None) -> tuple[str, str, Path]:
    """Run the command docs/recipes/RECIPE's docstring shows, word for word, as a user does from a
    clone's root with the dataset in data/ (here ``cwd``, with ``docs`` and ``data`` linked in),
    with ``env`` added to the environment;
    its stdout, its output as the command names it (its last argument) and that output's path."""
    command = re.search(rf"^ +python (docs/recipes/{re.escape(recipe)} .*)$", (RECIPES / recipe).read_text(), re.M)
    assert command, f"{recipe}: its docstring shows no 'python docs/recipes/{recipe} ...' command"
    for name, target in (("docs", ROOT / "docs"), ("data", dataset)):
        if not (cwd / name).exists():
            (cwd / name).symlink_to(target, target_is_directory=True)
    proc = subprocess.run(
        [sys.executable, *shlex.split(command.group(1))],
        capture_output=True,
        cwd=cwd,
        timeout=600,
        text=True,
        env={**os.environ, **(env or {})},
    )
    assert proc.returncode == 0, f"{recipe} failed:\n{proc.stdout}\n{proc.stderr}"
    dst = shlex.split(command.group(1))[-1]
    return proc.stdout, dst, cwd / dst


def assert_says_what_it_wrote(stdout: str, dst: str, got: pa.Table, more: str = "") -> None:
    """The one line a recipe prints on success: its output as the command names it, and the rows
    that ``got``, read back from there, holds."""
    assert stdout.splitlines() == [f"wrote {dst}: {got.num_rows} rows{more}"]


def _plain(column: pa.ChunkedArray) -> pa.ChunkedArray:
    return column.cast(column.type.value_type) if pa.types.is_dictionary(column.type) else column


def assert_same_rows(got: pa.Table, want: pa.Table) -> None:
    """The same columns and rows in the same order; floats to the bit (NaN included), other
    columns by value (a string may come back as large_string, status as text)."""
    assert got.column_names == want.column_names
    assert got.num_rows == want.num_rows
    for name in want.column_names:
        a, b = _plain(got.column(name)), _plain(want.column(name))
        assert a.null_count == b.null_count, name
        if pa.types.is_floating(b.type):
            assert a.type == b.type, name
            bits = np.uint64 if b.type.bit_width == 64 else np.uint32
            np.testing.assert_array_equal(a.to_numpy().view(bits), b.to_numpy().view(bits), err_msg=name)
        else:
            assert a.cast(b.type).equals(b), name


def _engine(module: str) -> None:
    """The engine, or a skip without it (a failure in CI: :func:`helpers.need`); Spark also needs Java."""
    need(module)
    if module == "pyspark.sql" and shutil.which("java") is None:
        assert not os.environ.get("HCONV_ALL_ENGINES"), (
            "Spark needs Java, which .ci/run installs: did its apt-get fail?"
        )
        pytest.skip("Spark needs Java (apt-get install openjdk-17-jre-headless)")


def assert_same_units(out: Path, want: pa.Table) -> None:
    """Every column's unit as ``hconv convert`` stores it, ω's and the inertia's in g·cm² among them,
    read back from OUT as a reader would (hconv.units_of, which also reads Spark's schema)."""
    got = hconv.units_of(out)
    assert got == hconv.units_of(want.schema)
    assert [got[c] for c in ("wx", "wy", "wz", "Ixx")] == ["rad/s"] * 3 + ["g*cm**2"]


def _sorted(table: pa.Table) -> pa.Table:
    return table.take(pc.sort_indices(table, [(c, "ascending") for c in ("Hx", "Hy", "Hz", "Ixx")]))


def test_duckdb_recipe_writes_what_hconv_convert_writes(dataset, reference, tmp_path):
    _engine("duckdb")
    said, dst, omega = _run("duckdb_hconv.py", dataset, tmp_path)
    got = _read(omega)
    assert_says_what_it_wrote(said, dst, got)
    assert_same_rows(got, reference)
    assert got.schema.equals(reference.schema, check_metadata=True)
    assert_same_units(omega, reference)


def test_polars_recipe_writes_what_hconv_convert_writes(dataset, reference, tmp_path):
    _engine("polars")
    said, dst, omega = _run("polars_hconv.py", dataset, tmp_path)
    got = _read(omega)
    assert_says_what_it_wrote(said, dst, got)
    assert_same_rows(got, reference)
    assert_same_units(omega, reference)
    assert got.schema.field("status").type == reference.schema.field("status").type
    assert got.schema.field("body").type == pa.large_string()  # Polars' text


def test_dask_recipe_writes_what_hconv_convert_writes_in_files_that_sort(dataset, reference, tmp_path):
    _engine("dask.dataframe")
    said, dst, omega = _run("dask_hconv.py", dataset, tmp_path)
    names = sorted(p.name for p in omega.glob("*.parquet"))
    assert names == [f"part-{k:05d}.parquet" for k in range(FILES)]
    got = _read(omega)
    assert_says_what_it_wrote(said, dst, got)
    assert_same_rows(got, reference)
    assert_same_units(omega, reference)
    assert got.schema.field("status").type == reference.schema.field("status").type
    assert got.schema.field("Ixx").metadata == reference.schema.field("Ixx").metadata


@pytest.mark.engines_slow
def test_ray_data_recipe_writes_hconv_converts_rows(dataset, reference, tmp_path):
    _engine("ray.data")
    said, dst, omega = _run("ray_data_hconv.py", dataset, tmp_path)
    got = _read(omega)
    assert_says_what_it_wrote(said, dst, got)
    # Ray does not promise the order (the recipe says so): the same rows, in any order
    assert_same_rows(_sorted(got), _sorted(reference))
    assert got.schema.equals(reference.schema, check_metadata=True)
    assert_same_units(omega, reference)


@pytest.mark.engines_slow
def test_ray_tasks_recipe_writes_what_hconv_convert_writes_file_by_file(dataset, reference, tmp_path):
    _engine("ray")
    said, dst, omega = _run("ray_tasks_hconv.py", dataset, tmp_path)
    assert sorted(p.name for p in omega.iterdir()) == sorted(p.name for p in dataset.iterdir())
    got = _read(omega)
    assert_says_what_it_wrote(said, dst, got, f" in {FILES} files")
    assert_same_rows(got, reference)
    assert got.schema.equals(reference.schema, check_metadata=True)
    assert_same_units(omega, reference)


def _spark_conf(folder: Path) -> dict[str, str]:
    """The environment for a Spark configuration of the test machine's, in ``folder``: no web UI,
    and the driver's JVM compiling with C1 only. C2, the JVM's optimising compiler, kept cores busy
    beside the recipe's partitions, on CI's two, for a job that ends before its code pays off
    (docs/measurements.md). Neither changes what Spark computes; the recipe runs as written."""
    folder.mkdir()
    (folder / "spark-defaults.conf").write_text(
        "spark.ui.enabled false\nspark.driver.extraJavaOptions -XX:TieredStopAtLevel=1\n"
    )
    return {"SPARK_CONF_DIR": str(folder)}


@pytest.mark.engines_slow
def test_spark_recipe_writes_hconv_converts_rows_in_order_with_the_units_in_sparks_schema(dataset, reference, tmp_path):
    _engine("pyspark.sql")
    said, dst, omega = _run("spark_hconv.py", dataset, tmp_path, env=_spark_conf(tmp_path / "spark-conf"))
    got = _read(omega)
    assert_says_what_it_wrote(said, dst, got)
    assert_same_rows(got, reference)
    assert got.schema.field("status").type == pa.string()
    assert not got.schema.field("wx").metadata  # pyarrow reads Spark's files bare ...
    assert_same_units(omega, reference)  # ... the units are in Spark's schema


# ---- the doc quotes the files it shows ----

FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def test_recipes_doc_quotes_every_recipe_file_word_for_word():
    text = DOC.read_text(encoding="utf-8")
    quoted = {}
    for body in FENCE.findall(text):
        m = re.search(r"python (docs/recipes/\w+\.py)", body)
        if m:
            quoted[m.group(1)] = body
    files = {f"docs/recipes/{p.name}": p.read_text(encoding="utf-8") for p in sorted(RECIPES.glob("*.py"))}
    assert sorted(quoted) == sorted(files), "every recipe file is quoted once in docs/recipes.md, and no other"
    for name, body in files.items():
        assert quoted[name] == body, f"docs/recipes.md quotes {name} otherwise than the file says"


def test_readme_links_the_recipes():
    assert "(docs/recipes.md)" in (ROOT / "README.md").read_text(encoding="utf-8")


def test_recipes_doc_try_block_runs_word_for_word_from_a_clones_root(tmp_path):
    _engine("duckdb")
    block = re.search(r"^```sh\n(.*?)^```", DOC.read_text(encoding="utf-8"), re.S | re.M)
    assert block, "docs/recipes.md shows no sh block to try the recipes with"
    lines = block.group(1).splitlines()
    assert lines[0] == "pip install -e '.[recipes]'"  # done: the tests run in that environment
    (tmp_path / "docs").symlink_to(ROOT / "docs", target_is_directory=True)
    # the environment's python and hconv first on PATH, as in an activated virtual environment
    path = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"
    for line in lines[1:]:
        proc = subprocess.run(
            ["bash", "-ec", line],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=300,
            env={**os.environ, "PATH": path},
        )
        assert proc.returncode == 0, f"{line}\n{proc.stdout}\n{proc.stderr}"
    dst = shlex.split(lines[-1])[-1]
    got = pq.read_table(tmp_path / dst)
    assert got.num_rows == 6000 and hconv.units_of(tmp_path / dst)["wx"] == "rad/s"
    assert_says_what_it_wrote(proc.stdout, dst, got)


def test_recipes_docstring_commands_write_distinct_outputs():
    """Run one after another as shown, recipes that shared omega/ mixed their files there, and
    Spark's refused to write into it."""
    outs = [
        shlex.split(m.group(1))[-1]
        for p in sorted(RECIPES.glob("*.py"))
        if (m := re.search(r"^ +python (docs/recipes/\S+ .*)$", p.read_text(), re.M))
    ]
    assert len(outs) == len(list(RECIPES.glob("*.py"))) and len(set(outs)) == len(outs), outs
