"""hconv: angular momentum H [kg·m²/s] to angular velocity ω, row by row, with honest diagnostics.

``hconv.convert`` works on numpy arrays, with an :class:`Options` (or its keywords) for the
method, precision, degenerate bodies and engine; ``hconv.convert_body`` on one body as ``hconv
one`` takes it; ``hconv.convert_table`` on pyarrow Tables and RecordBatches (pyarrow is imported
only when that is called), with a :class:`Job` (an Options with the scene's columns, units and
formats); ``hconv.convert_file`` on a file, ``hconv.convert_dataset`` on a directory, glob or
prefix of files, local or on object storage, and ``hconv.convert_path`` on either, by what the
path is, as ``hconv convert`` decides. Every one takes ``job=`` or the keywords, never both.
For engines that own the data (DuckDB, Polars, Dask, Ray, Spark): ``hconv.output_schema`` gives
``convert_table``'s result schema without converting, and ``hconv.parquet_write_options``
hconv's own Parquet writer settings, and ``hconv.units_of`` the units a schema or Parquet files
store, for engines that drop them (docs/recipes.md).
Conventions: :mod:`hconv.kernels.inertia`; the package's layers: docs/architecture.md.
"""

from __future__ import annotations

from hconv import interrupts

interrupts.end_quietly_while_starting()  # first: the imports below take most of the command's start

from hconv.solve.convert import Result, convert  # noqa: E402
from hconv.solve.forms import FORMS  # noqa: E402
from hconv.solve.methods import METHODS  # noqa: E402
from hconv.solve.options import Conventions, Options  # noqa: E402
from hconv.solve.status import STATUSES  # noqa: E402
from hconv.tables.job import Job  # noqa: E402
from hconv.version import __version__  # noqa: E402

__all__ = [
    "convert",
    "convert_body",
    "convert_table",
    "output_schema",
    "parquet_write_options",
    "units_of",
    "convert_file",
    "convert_dataset",
    "convert_path",
    "Job",
    "Options",
    "Conventions",
    "Result",
    "METHODS",
    "FORMS",
    "STATUSES",
    "__version__",
]


def __getattr__(name: str) -> object:  # keeps `import hconv` free of pyarrow
    if name in ("convert_table", "output_schema", "units_of"):
        from hconv.tables import arrow

        return getattr(arrow, name)
    if name == "parquet_write_options":
        from hconv.tables.parquetio import parquet_write_options

        return parquet_write_options
    if name == "convert_dataset":
        from hconv.tables.dataset import convert_dataset

        return convert_dataset
    if name == "convert_file":
        from hconv.tables.pipeline import convert_file

        return convert_file
    if name == "convert_path":
        from hconv.tables.paths import convert_path

        return convert_path
    if name == "convert_body":
        from hconv.tables.body import convert_body

        return convert_body
    raise AttributeError(f"module 'hconv' has no attribute {name!r}")
