"""The file formats hconv reads and writes, and the extensions that name them.

Kept apart from the readers and writers (:mod:`hconv.tables.csvio`, :mod:`hconv.tables.parquetio`,
which need pyarrow) so that the CLI can offer the choices without importing pyarrow.
"""

from __future__ import annotations

#: Format name -> the extensions that imply it (lower case).
#: ``.tsv`` and ``.tab`` are CSV with a tab delimiter (hconv.tables.sniff.TAB_EXTENSIONS).
EXTENSIONS = {"csv": (".csv", ".tsv", ".tab"), "parquet": (".parquet", ".pq")}
FORMATS = tuple(EXTENSIONS)
