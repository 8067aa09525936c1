"""The file formats hconv reads and writes, and the extensions that name them.

Kept apart from the readers and writers (:mod:`hconv.tables.csvio`, :mod:`hconv.tables.parquetio`,
:mod:`hconv.tables.ipcio`, :mod:`hconv.tables.jsonio`, which need pyarrow) so that the CLI can
offer the choices without importing pyarrow.

``arrow`` is Arrow IPC: its file format (Feather version 2, ``ARROW1`` at both ends) and its
stream format; hconv reads both, telling them by their first bytes, and writes the file format
to a file and the stream format to stdout. ``jsonl`` (JSON lines, one object per line) is read
only.
"""

from __future__ import annotations

#: Format name -> the extensions that imply it (lower case).
#: ``.tsv`` and ``.tab`` are CSV with a tab delimiter (hconv.tables.sniff.TAB_EXTENSIONS).
EXTENSIONS = {
    "csv": (".csv", ".tsv", ".tab"),
    "parquet": (".parquet", ".pq"),
    "arrow": (".arrow", ".feather", ".ipc"),
    "jsonl": (".jsonl", ".ndjson"),
}
FORMATS = tuple(EXTENSIONS)  #: what hconv reads
WRITES = ("csv", "parquet", "arrow")  #: what hconv writes
#: Each format as messages name it.
NAMES = {"csv": "CSV", "parquet": "Parquet", "arrow": "Arrow IPC (Feather)", "jsonl": "JSON lines"}


def listing(fmts: tuple = FORMATS, extensions: bool = True) -> str:
    """``fmts`` with their extensions, for a message: ``CSV (.csv, .tsv, .tab), Parquet (.parquet, .pq) ...``;
    without (``extensions=False``): ``CSV, Parquet ...``."""
    named = [f"{NAMES.get(f, f)} ({', '.join(EXTENSIONS.get(f, ()))})" if extensions else NAMES.get(f, f) for f in fmts]
    return ", ".join(named[:-1]) + " or " + named[-1] if len(named) > 1 else named[0]


def choices(fmts: tuple = FORMATS) -> str:
    """``csv, parquet, arrow or jsonl``: what ``--from``/``--to`` take."""
    return ", ".join(fmts[:-1]) + " or " + fmts[-1] if len(fmts) > 1 else fmts[0]


#: Extensions of formats people hand hconv that it does not read, and what each is.
FOREIGN = {
    ".json": "JSON",
    ".orc": "ORC",
    ".avro": "Avro",
    ".h5": "HDF5",
    ".hdf5": "HDF5",
    ".hdf": "HDF5",
    ".npy": "a NumPy array",
    ".npz": "NumPy arrays",
    ".mat": "a MATLAB file",
    ".pkl": "a Python pickle",
    ".pickle": "a Python pickle",
    ".sqlite": "an SQLite database",
    ".db": "a database",
    ".duckdb": "a DuckDB database",
    ".xlsx": "an Excel workbook",
    ".xls": "an Excel workbook",
    ".ods": "an OpenDocument spreadsheet",
    ".dta": "a Stata file",
    ".sav": "an SPSS file",
    ".rds": "an R data file",
}
