"""Telling what a path holds before reading it: the format a name (or ``--from``/``--to``) says;
a path that is missing, a directory or a pipe; and, from a file's first bytes, what a file that is
not plain CSV or Parquet is instead (compressed, a spreadsheet, UTF-16 text), each with the
command that makes it readable; and a CSV's dialect (:class:`Dialect`): its delimiter, decimal
mark and comment lines."""

from __future__ import annotations

import csv
import difflib
import os
import re
import shlex
import stat
from dataclasses import dataclass
from pathlib import Path

from hconv.errors import InputError, OutputError, UsageError, option
from hconv.tables.formats import EXTENSIONS, FOREIGN, FORMATS, NAMES, WRITES, choices, listing
from hconv.tables.inputs import unreadable
from hconv.tables.job import DELIMITERS


def format_of(path: str, given: str | None, flag: str) -> str:
    """``given`` if set, else the format named by ``path``'s extension; UsageError otherwise.
    ``flag`` is ``src_format`` (``--from``) for an input, ``dst_format`` (``--to``) for an output."""
    if path == "":  # an unset shell variable: "hconv convert "$in" out.csv"
        which, std = ("input", "stdin") if flag == "src_format" else ("output", "stdout")
        raise UsageError(f"the {which} path is empty (''); give a file path, or - for {std}")
    if given:
        if given not in FORMATS:
            raise UsageError(f"{option(flag)} must be {choices(FORMATS)}, got {given!r}")
        if flag == "dst_format":
            _check_writes(given, flag)
        named = _named_format(path) if path != "-" else None
        if named not in (None, given):  # out.csv with --to parquet: one of the two is a mistake
            base = path[: -len(Path(path).suffix)]
            if flag == "src_format" and _head_format(path) == named:  # the bytes side with the name
                raise UsageError(
                    f"{path}: is {_AN[named]} {NAMES[named]} file, as its name says, not {NAMES[given]}; "
                    f"drop {option(flag, given)}"
                )
            raise UsageError(
                f"{path}: the name says {NAMES[named]} but {option(flag, given)} says "
                f"{NAMES[given]}; name it {base}{EXTENSIONS[given][0]}, or drop {option(flag)}"
            )
        return given
    if path == "-":
        fmts = FORMATS if flag == "src_format" else WRITES
        raise UsageError(
            f"'-' has no extension to tell the format (one of {choices(fmts)}); "
            f"pass {option(flag, 'csv')} or {option(flag, 'parquet')}"
        )
    suffix = Path(path).suffix.lower()
    fmt = _named_format(path)
    if fmt is None:
        if flag == "src_format":
            input_kind(path)  # a path that is missing or a directory: say so, not that its name has no format
        _refuse_compressed_name(path, suffix, flag)
        fmts = FORMATS if flag == "src_format" else WRITES
        verb = "reads" if flag == "src_format" else "writes"
        if suffix in _SPREADSHEETS and flag == "src_format":  # the advice its bytes get under another name
            raise UsageError(f"{path}: is {FOREIGN[suffix]} ({suffix}), which hconv does not read; {_SAVE_AS_CSV}")
        if suffix == ".json" and flag == "src_format":
            raise UsageError(f"{path}: {_JSON_LINES.format(path=path, lines=os.path.splitext(path)[0] + '.jsonl')}")
        if suffix in FOREIGN:
            raise UsageError(
                f"{path}: its name says {FOREIGN[suffix]} ({suffix}), which hconv does not {verb[:-1]}; "
                f"hconv {verb} {listing(fmts, extensions=False)}"
            )
        raise UsageError(
            f"{path}: cannot tell its format from its name; pass {option(flag, 'FORMAT')}, one of {choices(fmts)}"
        )
    if flag == "dst_format":
        _check_writes(fmt, flag, path)
    return fmt


_JSON_LINES = (
    "hconv reads JSON lines, not JSON: for one object per line, pass --from jsonl; for one array "
    "of objects, first: jq -c '.[]' {path} > {lines}"
)


def _check_writes(fmt: str, flag: str, path: str | None = None) -> None:
    """UsageError for an output format hconv reads but does not write (JSON lines)."""
    if fmt in WRITES:
        return
    where = f"{path}: " if path else ""
    raise UsageError(
        f"{where}hconv reads {NAMES[fmt]} but does not write it: "
        f"pass {option(flag, 'arrow')} (or csv, parquet)" + (", and name OUT for it" if path else "")
    )


def _named_format(path: str) -> str | None:
    """The format ``path``'s extension names, or None."""
    suffix = Path(path).suffix.lower()
    return next((f for f, exts in EXTENSIONS.items() if suffix in exts), None)


#: Compressions people often hand hconv: name, leading bytes, file suffixes, the command that
#: writes the plain bytes to stdout, and the one that compresses a file ({plain}, {packed}).
_COMPRESSIONS = (
    ("gzip", b"\x1f\x8b", (".gz", ".gzip"), "gzip -dc", "gzip {plain}"),
    ("bzip2", b"BZh", (".bz2",), "bzip2 -dc", "bzip2 {plain}"),
    ("xz", b"\xfd7zXZ\x00", (".xz",), "xz -dc", "xz {plain}"),
    ("zstd", b"\x28\xb5\x2f\xfd", (".zst", ".zstd"), "zstd -dc", "zstd {plain}"),
    ("zip", b"PK\x03\x04", (".zip",), "unzip -p", "zip {packed} {plain}"),
)
_OLE2 = b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1"  # Excel 97-2003 (.xls)
_SAVE_AS_CSV = "open it in the spreadsheet and save the sheet as 'CSV UTF-8 (comma delimited)'"
_SPREADSHEETS = (".xlsx", ".xls", ".ods")  #: spreadsheets by their names, told to be saved as CSV


def _refuse_compressed_name(path: str, suffix: str, flag: str) -> None:
    """``in.csv.gz`` and ``out.csv.gz``: hconv reads and writes plain files only (the message for
    reading names the command that decompresses it)."""
    packed = next((c for c in _COMPRESSIONS if suffix in c[2]), None)
    plain = path[: -len(suffix)] if suffix else path
    if packed is None or not any(Path(plain).suffix.lower() in exts for exts in EXTENSIONS.values()):
        return
    what, _, _, unpack, pack = packed
    kind = NAMES[_named_format(plain) or "csv"]
    if flag == "src_format":
        raise InputError(
            f"{path}: is {_packed(what)}; hconv reads uncompressed {kind}, so decompress it first: "
            f"{unpack} {shlex.quote(path)} > {shlex.quote(_free_name(plain))}"
        )
    raise OutputError(
        f"{path}: hconv writes uncompressed {kind}; write {plain} and compress it afterwards: "
        + pack.format(plain=shlex.quote(plain), packed=shlex.quote(path))
    )


def _free_name(plain: str) -> str:
    """``plain``, or if that exists ``<base>-plain<ext>`` (then -plain-2, …): a decompress command
    must never overwrite a file, least of all the plain copy the user may already have."""
    base, ext = os.path.splitext(plain)
    name, k = plain, 1
    while os.path.lexists(name):
        name = f"{base}-plain{ext}" if k == 1 else f"{base}-plain-{k}{ext}"
        k += 1
    return name


def _packed(what: str) -> str:
    return "a zip archive" if what == "zip" else f"{what}-compressed"


def what_it_is(head: bytes, path: str, name: str, fmt: str) -> str | None:
    """What a file that is not plain ``fmt`` is instead, from its first bytes, and how to make it
    readable: a compressed file, a spreadsheet or UTF-16 text. None if it is none of these."""
    piped = path != name  # stdin, or a pipe given by name: the fix goes into the pipe
    kind = NAMES.get(fmt, fmt)
    other = table_format(head)
    if other is not None and other != fmt and (fmt, other) != ("csv", "parquet"):  # csvio names Parquet itself
        how = f"pass {option('src_format', other)}" if piped else rename_or_pass(name, other)
        return f"is {_AN[other]} {NAMES[other]} file, not {kind}; to read it as that, {how}"

    def fix(command: str, suffixes: tuple, tag: str) -> str:
        if piped:
            return f"in the pipe, before hconv: ... | {command} | hconv ..."
        base, ext = os.path.splitext(name)
        if ext.lower() in suffixes:  # ok.csv.gz -> ok.csv; ok.zip -> ok.csv, not ok
            plain = base if _named_format(base) else base + EXTENSIONS[fmt][0]
        else:
            plain = f"{base}{tag}{ext}"
        return f"first: {command} {shlex.quote(name)} > {shlex.quote(_free_name(plain))}"

    for what, magic, suffixes, unpack, _ in _COMPRESSIONS:
        if not head.startswith(magic):
            continue
        if what == "bzip2" and not (head[3:4].isdigit() and head[4:10] in (b"1AY&SY", b"\x17rE8P\x90")):
            continue  # a text file may start with 'BZh'; a bzip2 stream goes on with its block magic
        if what == "zip" and (b"[Content_Types].xml" in head or b"xl/" in head):
            return f"is an Excel workbook (.xlsx), not {kind}; {_SAVE_AS_CSV}"
        if what == "zip" and b"opendocument.spreadsheet" in head[:128]:
            return f"is an OpenDocument spreadsheet (.ods), not {kind}; {_SAVE_AS_CSV}"
        return (
            f"is {_packed(what)}; hconv reads uncompressed {kind}, so decompress it {fix(unpack, suffixes, '-plain')}"
        )
    if head.startswith(_OLE2):
        return f"is an Excel 97-2003 workbook (.xls), not {kind}; {_SAVE_AS_CSV}"
    if fmt != "csv":
        return None
    encoding = None
    if head.startswith((b"\xff\xfe\x00\x00", b"\x00\x00\xfe\xff")):
        encoding = "UTF-32"
    elif head.startswith((b"\xff\xfe", b"\xfe\xff")):
        encoding = "UTF-16"
    elif len(head) >= 4:  # UTF-16 without a byte-order mark: in ASCII text every other byte is NUL
        even, odd = head[0::2], head[1::2]
        if odd.count(0) >= 0.9 * len(odd) and even.count(0) <= 0.1 * len(even):
            encoding = "UTF-16LE"
        elif even.count(0) >= 0.9 * len(even) and odd.count(0) <= 0.1 * len(odd):
            encoding = "UTF-16BE"
    if encoding:
        return (
            f"is {encoding} text; hconv reads UTF-8, so convert it {fix(f'iconv -f {encoding} -t UTF-8', (), '-utf8')}"
        )
    return None


_AN = {"csv": "a", "parquet": "a", "arrow": "an", "jsonl": "a"}


def table_format(head: bytes) -> str | None:
    """The binary table format that ``head``, a file's first bytes, starts with: ``parquet``
    (``PAR1``), ``arrow`` (the IPC file format's ``ARROW1``, or a stream's first message: the
    continuation marker then a little-endian length), or None."""
    if head.startswith(b"PAR1"):
        return "parquet"
    if head.startswith(b"ARROW1") or head.startswith(b"FEA1"):
        return "arrow"
    if len(head) >= 8 and head[:4] == b"\xff\xff\xff\xff" and 0 < int.from_bytes(head[4:8], "little") < 1 << 24:
        return "arrow"
    return None


def _head_format(path: str) -> str | None:
    """:func:`table_format` of the file at ``path``'s first bytes; None if it cannot be read."""
    try:
        with open(path, "rb") as f:
            return table_format(f.read(8))
    except OSError:
        return None


def input_kind(path: str) -> str:
    """``file``, or ``pipe`` for a FIFO or a character device (``<(zcat in.csv.gz)``, /dev/stdin),
    which cannot seek and is spooled like stdin; InputError for a path that cannot be an input."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise InputError(_missing(path)) from None
    except OSError as exc:
        raise unreadable(path, exc) from None
    if stat.S_ISDIR(mode):
        raise InputError(_directory(path))
    if stat.S_ISFIFO(mode) or stat.S_ISCHR(mode):
        return "pipe"
    if not stat.S_ISREG(mode):
        raise InputError(f"{path}: is not a file (a socket?); give a CSV or Parquet file")
    return "file"


def _missing(path: str) -> str:
    if os.path.islink(path):
        return f"{path}: is a link to {os.readlink(path)!r}, which does not exist; check the link"
    parent = os.path.dirname(path)
    if parent and not os.path.isdir(parent):
        return f"{path}: does not exist, nor does the directory {parent!r}; check the path"
    try:
        names = os.listdir(parent or ".")
    except OSError:
        names = []
    near = difflib.get_close_matches(os.path.basename(path), names, n=1, cutoff=0.8)
    guess = f" (did you mean {os.path.join(parent, near[0])}?)" if near else ""
    return f"{path}: does not exist{guess}; check the path"


def _directory(path: str) -> str:
    """A directory given to a command that reads one file (``hconv convert`` takes a directory as a
    dataset, hconv.tables.dataset, and does not get here)."""
    known = {e for exts in EXTENSIONS.values() for e in exts}
    try:
        files = sorted(e.name for e in os.scandir(path) if e.is_file() and Path(e.name).suffix.lower() in known)
    except OSError:
        files = []
    head = f"{path}: is a directory, and this command reads one file"
    pointer = "hconv convert takes a whole directory: see docs/datasets.md"
    if not files:
        return f"{head}; give a CSV or Parquet file ({pointer})"
    if len(files) == 1:
        return f"{head}; give the file in it, {os.path.join(path, files[0])} ({pointer})"
    return (
        f"{head}; give one of the {len(files)} CSV or Parquet files in it, such as "
        f"{os.path.join(path, files[0])} ({pointer})"
    )


def rename_or_pass(name: str, fmt: str) -> str:
    """How to read a file whose bytes are ``fmt`` as ``fmt``: a name with another format's
    extension must change (--from may not contradict it); one without may keep it."""
    if _named_format(name):
        return f"rename it {os.path.splitext(name)[0]}{EXTENSIONS[fmt][0]}"
    return f"name it {EXTENSIONS[fmt][0]} or pass {option('src_format', fmt)}"


# --- a CSV's dialect -------------------------------------------------------------------------
# As DuckDB's CSV reader sniffs one: the delimiter is the candidate (comma, semicolon, tab, bar)
# that splits the header into the most columns while every row of the first block has as many;
# comment lines (``#``) before the header are skipped; a decimal comma and a row of units under the
# header are told from the values of hconv's columns (hconv.tables.csvio, once it knows them).

#: Extensions that name tab-separated text: read with a tab delimiter, and written with one.
TAB_EXTENSIONS = (".tsv", ".tab")


@dataclass(frozen=True)
class Dialect:
    """How a CSV file is written: its delimiter, its decimal mark, the comment lines before its
    header, and the units a row under the header gives hconv's columns ((column, unit) pairs)."""

    delimiter: str = ","
    decimal: str = "."
    comment_lines: int = 0
    units: tuple = ()
    units_row: bool = False  #: a row of units under the header, not a data row
    units_text: tuple = ()  #: that row as written, one text a column (CSV output writes it again)

    def describe(self) -> str:
        """What the summary says of a dialect that is not plain CSV; "" for plain CSV."""
        if self == Dialect():
            return ""
        shown = "tab" if self.delimiter == "\t" else repr(self.delimiter)
        parts = [f"{shown} separated", f"decimal {self.decimal!r}"]
        if self.comment_lines:
            parts.append(f"{self.comment_lines} comment line{'s' if self.comment_lines > 1 else ''} skipped")
        if self.units_row:
            parts.append("units from the row under the header")
        return "read as CSV: " + ", ".join(parts)


def delimiter_by_name(name: str) -> str | None:
    """The delimiter a file's name says: a tab for ``.tsv`` and ``.tab``; None for any other."""
    return "\t" if Path(name).suffix.lower() in TAB_EXTENSIONS else None


def comment_lines(lines: list[str]) -> int:
    """How many of ``lines`` before the header are comments (start with ``#``)."""
    k = 0
    while k < len(lines) and lines[k].lstrip().startswith("#"):
        k += 1
    return k


def sniff_delimiter(lines: list[str], name: str, known: frozenset = frozenset()) -> str:
    """The delimiter of the CSV whose header and first rows are ``lines``: the candidate that splits
    the header into the most columns with most rows as long (a row of the wrong length is named
    later, by its number); of two alike, the one with more rows as long. A tie is settled by the
    header naming hconv's columns (``known``) under one of them only; else UsageError naming
    ``--delimiter``. Comma when none splits the header."""
    score: dict[str, tuple[int, int]] = {}  # delimiter -> (columns, rows as long as the header)
    headers: dict[str, list[str]] = {}
    for d in DELIMITERS:
        try:
            rows = [r for r in csv.reader(lines, delimiter=d) if r]
        except csv.Error:  # a value longer than the csv module's limit: not this delimiter's table
            continue
        if not rows or len(rows[0]) < 2:
            continue
        agree = sum(len(r) == len(rows[0]) for r in rows[1:])
        if 2 * agree >= len(rows) - 1:
            score[d], headers[d] = (len(rows[0]), agree), rows[0]
    if not score:
        return ","
    top = max(score.values())
    best = [d for d in DELIMITERS if score.get(d) == top]
    if len(best) > 1:
        naming = [d for d in best if known & {c.strip() for c in headers[d]}]
        if len(naming) == 1:
            return naming[0]
        shown = [repr("tab" if d == "\t" else d) for d in best]
        raise UsageError(
            f"{name}: cannot tell the delimiter: {' and '.join(shown)} both split every line into {top[0]} columns; "
            f"pass {' or '.join(option('delimiter', s) for s in shown)}"
        )
    return best[0]


#: A number written with a decimal comma: 1,5  -0,25  ,5  1,5e-3
_DECIMAL_COMMA = re.compile(r"\s*[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?\s*")
#: A number written with a decimal point, not a whole number: 1.5  -.25  1.5e-3
_DECIMAL_POINT = re.compile(r"\s*[+-]?(\d+\.\d*|\.\d+)([eE][+-]?\d+)?\s*")


def delimiter_hint(names: list, lines: list[str], delimiter: str, name: str, given: bool, known: frozenset) -> str:
    """Where a header split by ``delimiter`` names none of the ``known`` columns, and its first
    ``lines`` split better by another delimiter: which one, and the fix (``given``: the delimiter
    was given by ``--delimiter``, which may be dropped; else by the name, .tsv); else ""."""
    if not any(n.strip() in known for n in names):
        try:
            sniffed = sniff_delimiter(lines, name, known)
        except UsageError:
            sniffed = delimiter
        if sniffed != delimiter:
            words = DELIMITERS[sniffed], DELIMITERS[delimiter]
            other = f" or drop {option('delimiter')}" if given else ", or name the file .csv"
            fix = f"pass {option('delimiter', words[0])}{other}"
            return f" (the header is separated by {words[0]}s, not {words[1]}s: {fix})"
    return ""


def decimal_comma(text: str) -> bool:
    """Whether ``text`` is a number written with a decimal comma (``0,5``)."""
    return _DECIMAL_COMMA.fullmatch(text) is not None


def sniff_decimal(values: dict[str, list[str]], name: str) -> str:
    """The decimal mark of hconv's columns, from their first values (column -> texts) in a file
    whose delimiter is not a comma: a comma if some are written with one and none with a point;
    UsageError naming ``--decimal`` if both are."""
    comma = next(((c, v) for c, vs in values.items() for v in vs if _DECIMAL_COMMA.fullmatch(v)), None)
    if comma is None:
        return "."
    point = next(((c, v) for c, vs in values.items() for v in vs if _DECIMAL_POINT.fullmatch(v)), None)
    if point is not None:
        raise UsageError(
            f"{name}: cannot tell the decimal mark: column {comma[0]!r} holds {comma[1]!r} and column {point[0]!r} "
            f"holds {point[1]!r}; pass {option('decimal', repr(','))} or {option('decimal', repr('.'))}"
        )
    return ","
