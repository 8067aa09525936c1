"""hconv: angular momentum H [kg·m²/s] to angular velocity ω, row by row, with honest diagnostics.

``hconv.convert`` works on numpy arrays; ``hconv.convert_table`` on pyarrow Tables and
RecordBatches (pyarrow is imported only when that is called). Conventions: :mod:`hconv.kernels.inertia`.
"""
from __future__ import annotations

__version__ = "0.1.0"

from hconv.solve.convert import Result, convert  # noqa: E402
from hconv.solve.methods import METHODS  # noqa: E402
from hconv.solve.status import STATUSES  # noqa: E402

__all__ = ["convert", "convert_table", "Result", "METHODS", "STATUSES", "__version__"]


def __getattr__(name):  # keeps `import hconv` free of pyarrow
    if name == "convert_table":
        from hconv.tables.arrow import convert_table

        return convert_table
    raise AttributeError(f"module 'hconv' has no attribute {name!r}")
