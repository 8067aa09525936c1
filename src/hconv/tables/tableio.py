"""Tables in and out, batch by batch: CSV and Parquet, files or stdin/stdout ("-").

Reading never holds more than a batch in memory (stdin is first spooled to a temporary file,
since Parquet needs to seek). Writing goes to a temporary file next to the output and is renamed
into place only when the whole run succeeded, so a failed or interrupted run leaves no partial
output. With "-" as output the finished file is then copied to stdout. A run killed outright
leaves its temporary file, but the name says which process made it, and the next run that writes
into that directory removes it once that process has ended (:func:`remove_stale_temporaries`).

From CSV, the columns hconv does not use are read as text (:attr:`Input.text`), so that CSV
output gives them back exactly as they went in; into Parquet, the pipeline gives them types
(:mod:`hconv.tables.csvtypes`), unless the Job says ``keep_text``. ω's unit goes into a column
``w_unit`` in CSV; in Parquet it is the ``unit`` metadata of wx, wy, wz.

Whatever pyarrow raises while reading is the input's (InputError, naming the file, and for
Parquet the row group), and a file that changes while it is read is refused; pyarrow is given
native files only (see ``_open_csv``).
"""

from __future__ import annotations

import contextlib
import csv
import difflib
import errno
import io
import itertools
import os
import re
import shlex
import shutil
import socket
import stat
import sys
import tempfile
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from hconv import interrupts
from hconv.errors import InputError, OutputError, UsageError, option
from hconv.solve import forms
from hconv.tables import csvtypes, layout, sets
from hconv.tables.formats import EXTENSIONS, FORMATS
from hconv.tables.job import Job

CSV_BLOCK_BYTES = 4 << 20
PARQUET_BATCH_ROWS = 65536
UNIT_COLUMN = layout.UNIT_COLUMN


def format_of(path: str, given: str | None, flag: str) -> str:
    """``given`` if set, else the format named by ``path``'s extension; UsageError otherwise.
    ``flag`` is ``src_format`` (``--from``) for an input, ``dst_format`` (``--to``) for an output."""
    if path == "":  # an unset shell variable: "hconv convert "$in" out.csv"
        which, std = ("input", "stdin") if flag == "src_format" else ("output", "stdout")
        raise UsageError(f"the {which} path is empty (''); give a file path, or - for {std}")
    if given:
        if given not in FORMATS:
            raise UsageError(f"{option(flag)} must be {' or '.join(FORMATS)}, got {given!r}")
        named = _named_format(path) if path != "-" else None
        if named not in (None, given):  # out.csv with --to parquet: one of the two is a mistake
            base = path[: -len(Path(path).suffix)]
            raise UsageError(
                f"{path}: the name says {_FORMAT_NAMES[named]} but {option(flag, given)} says "
                f"{_FORMAT_NAMES[given]}; name it {base}{EXTENSIONS[given][0]}, or drop {option(flag)}"
            )
        return given
    if path == "-":
        raise UsageError(
            f"'-' has no extension to tell the format; pass {option(flag, 'csv')} or {option(flag, 'parquet')}"
        )
    suffix = Path(path).suffix.lower()
    fmt = _named_format(path)
    if fmt is None:
        if flag == "src_format":
            _input_kind(path)  # a path that is missing or a directory: say so, not that its name has no format
        _refuse_compressed_name(path, suffix, flag)
        raise UsageError(
            f"cannot tell the format of {path!r} from its extension; "
            f"name it .csv or .parquet, or pass {option(flag, 'csv')} or {option(flag, 'parquet')}"
        )
    return fmt


_FORMAT_NAMES = {"csv": "CSV", "parquet": "Parquet"}


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


def _refuse_compressed_name(path: str, suffix: str, flag: str) -> None:
    """``in.csv.gz`` and ``out.csv.gz``: hconv reads and writes plain files only (the message for
    reading names the command that decompresses it)."""
    packed = next((c for c in _COMPRESSIONS if suffix in c[2]), None)
    plain = path[: -len(suffix)] if suffix else path
    if packed is None or not any(Path(plain).suffix.lower() in exts for exts in EXTENSIONS.values()):
        return
    what, _, _, unpack, pack = packed
    kind = _FORMAT_NAMES[_named_format(plain) or "csv"]
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


def _what_it_is(head: bytes, path: str, name: str, fmt: str) -> str | None:
    """What a file that is not plain ``fmt`` is instead, from its first bytes, and how to make it
    readable: a compressed file, a spreadsheet or UTF-16 text. None if it is none of these."""
    piped = path != name  # stdin, or a pipe given by name: the fix goes into the pipe
    kind = "CSV" if fmt == "csv" else "Parquet"

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


def _input_kind(path: str) -> str:
    """``file``, or ``pipe`` for a FIFO or a character device (``<(zcat in.csv.gz)``, /dev/stdin),
    which cannot seek and is spooled like stdin; InputError for a path that cannot be an input."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise InputError(_missing(path)) from None
    except OSError as exc:
        raise _oserror(path, exc) from None
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
    readme = "hconv convert takes a whole directory: see 'Datasets' in the README"
    if not files:
        return f"{head}; give a CSV or Parquet file ({readme})"
    if len(files) == 1:
        return f"{head}; give the file in it, {os.path.join(path, files[0])} ({readme})"
    return (
        f"{head}; give one of the {len(files)} CSV or Parquet files in it, such as "
        f"{os.path.join(path, files[0])} ({readme})"
    )


@dataclass
class Input:
    """An open input: its schema, its batches, and how far reading has got (for progress)."""

    name: str
    schema: pa.Schema
    batches: Iterator[pa.RecordBatch]
    total: int | None  #: rows (Parquet) or bytes (CSV); None if unknown
    position: Callable[[], int]  #: rows or bytes read so far
    plan: layout.Layout  #: the input's column sets, planned for the Job
    _closers: list = field(default_factory=list)
    #: CSV: the columns hconv does not use, read as text (Parquet: none); see hconv.tables.csvtypes
    text: tuple = ()
    path: str = ""  #: the file read (for stdin, its spooled copy, which lives as long as this Input)
    first_row: int = 0  #: the file's row that :attr:`batches` starts at (a part of the file: ``rows``)

    def close(self) -> None:
        for c in reversed(self._closers):
            c()
        self._closers.clear()

    def __enter__(self) -> Input:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_input(path: str, fmt: str, job: Job, name: str | None = None, rows: tuple[int, int] | None = None) -> Input:
    """Open ``path`` ("-" for stdin) as ``fmt``, planned for ``job`` (:func:`hconv.tables.layout.plan`);
    InputError with a fix if it can't be. Stdin, or a pipe given by name, is spooled first.
    ``name``: what messages call the input (default: ``path``), such as the URI of an object
    that was fetched into ``path``. ``rows``: (start, stop), only those rows of a Parquet file
    (:func:`_open_parquet`)."""
    closers = []
    name = name or path
    if path == "-":
        name = "stdin"
        if sys.stdin is None or sys.stdin.isatty():
            raise UsageError(
                "input is '-' but stdin is a terminal; pipe a file in, "
                "e.g. `cat in.csv | hconv convert - out.csv --from csv`"
            )
        spooled = spool(sys.stdin.buffer, name)
        closers.append(lambda: os.unlink(spooled))
        path = spooled
    elif _input_kind(path) == "pipe":
        try:
            stream = open(path, "rb")  # noqa: SIM115 - closed by the with below, once spooled
        except OSError as exc:
            raise _oserror(name, exc) from None
        with stream:
            if stream.isatty():
                raise UsageError(f"input {name} is a terminal; give a file, or pipe one in")
            spooled = spool(stream, name)
        closers.append(lambda: os.unlink(spooled))
        path = spooled
    try:
        if rows is not None and fmt != "parquet":
            raise ValueError("rows is for Parquet input")
        inp = _open_csv(path, name, job) if fmt == "csv" else _open_parquet(path, name, job, rows)
    except BaseException:
        for c in closers:
            c()
        raise
    inp._closers[:0] = closers
    return inp


#: Every temporary file hconv makes ends so; its name also carries the process that made it.
TEMP_SUFFIX = ".hconv-tmp"
# .OUT.<token>-XXXXXXXX.hconv-tmp beside the output; hconv-stdin-/hconv-stdout-<token>-XXXXXXXX.hconv-tmp
# in the temporary directory, and hconv-fetch-/hconv-stage- for a dataset's files on object storage
# (hconv.tables.storage). <token> is pid-start-tag (_maker). A run on a cluster puts its run's tag,
# run-<hex>., before the token (:func:`run_prefix`), so that it can remove what a killed worker left.
_TEMP_NAME = re.compile(
    r"^(?:\..+\.|hconv-(?:stdin|stdout|fetch|stage)-(?:run-[0-9a-f]+\.)?)(\d+)-(\d+)-([0-9a-f]{8})-[a-z0-9_]+\.hconv-tmp$"
)


def _proc_start(pid: int) -> int | None:
    """When process ``pid`` started, in clock ticks since boot (Linux's /proc), or None."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            stat = f.read()
        return int(stat[stat.rindex(b")") + 2 :].split()[19])  # field 22; the name before ')' may hold spaces
    except (OSError, ValueError, IndexError):
        return None


def _machine_tag() -> str:
    """This host and pid namespace, in 8 hex digits: a pid names a process only within both, so a
    file made on another machine sharing the directory, or in another container, is never judged."""
    try:
        namespace = os.readlink("/proc/self/ns/pid")
    except OSError:
        namespace = ""
    return f"{zlib.crc32((socket.gethostname() + '/' + namespace).encode()):08x}"


def _maker() -> str:
    """``pid-start-tag`` for this process's temporary files. The start time tells this process
    from a later one that reuses its pid; it is 0 where there is no /proc, and then only the
    pid is checked."""
    pid = os.getpid()
    return f"{pid}-{_proc_start(pid) or 0}-{_machine_tag()}"


def _maker_gone(pid: int, start: int, tag: str) -> bool:
    """Whether the process that made a temporary file has surely ended; False when unsure."""
    if tag != _machine_tag():
        return False
    now = _proc_start(pid)
    if now is not None:
        return start != 0 and now != start  # another process holds the pid now
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except (OSError, OverflowError):  # PermissionError: it runs, as another user
        return False
    return False  # it runs, but /proc hides it (mounted with hidepid)


def maker() -> str:
    """This process as :func:`maker_gone` can later tell whether it still runs: ``pid-start-tag``."""
    return _maker()


def maker_gone(made_by: str) -> bool:
    """Whether the process :func:`maker` described as ``made_by`` has surely ended; False when
    unsure (another host, or not such a description)."""
    try:
        pid, start, tag = made_by.split("-")
        return _maker_gone(int(pid), int(start), tag)
    except ValueError:
        return False


def remove_stale_temporaries(directory: str) -> list[str]:
    """Remove the temporary files in ``directory`` that hconv runs killed before they could clean
    up (SIGKILL, the OOM killer, a power cut), saying so on stderr; returns their paths.

    Those of any output, not only the one being written: a killed run's file is litter whichever
    output it was for, and no later run may ever write that output again. A file whose maker
    still runs, or may run (another host, no way to tell), is left alone.
    """
    removed: list[str] = []
    try:
        entries = [e for e in os.scandir(directory) if e.name.endswith(TEMP_SUFFIX)]
    except OSError:
        return removed  # making the new temporary file will say what is wrong with the directory
    for entry in entries:
        m = _TEMP_NAME.match(entry.name)
        if not m or not _maker_gone(int(m.group(1)), int(m.group(2)), m.group(3)):
            continue
        path = str(Path(directory) / entry.name)
        try:
            if not entry.is_file(follow_symlinks=False):
                continue
            os.unlink(entry.path)
        except OSError:
            continue  # another run removed it first, or it is not ours to remove
        pid = m.group(1)
        print(f"hconv: removed stale temporary file {path} left by a run that was killed (pid {pid})", file=sys.stderr)
        removed.append(path)
    return removed


#: A part of one output converted by one task of a cluster run (hconv.tables.dataset.split):
#: ``.OUT.run-<hex>.part-<k>.hconv-tmp``, named without the process that wrote it, so that a task
#: run again after its worker died writes the same part (the run removes its parts at its end).
_PART_NAME = re.compile(r"^\..+\.run-[0-9a-f]+\.part-\d+\.hconv-tmp$")


def part_name(name: str, run: str, k: int) -> str:
    """The name of part ``k`` of the output named ``name``, in the run ``run``."""
    return f".{os.fsdecode(os.fsencode(name)[:120])}.run-{run}.part-{k:05d}{TEMP_SUFFIX}"


def is_run_temporary(name: str, run: str) -> bool:
    """Whether the file name ``name`` is a temporary file or a part of the run ``run``."""
    return (
        name.endswith(TEMP_SUFFIX) and f"run-{run}." in name and bool(_TEMP_NAME.match(name) or _PART_NAME.match(name))
    )


def run_prefix(prefix: str, run: str | None) -> str:
    """``prefix`` for a temporary file of the run ``run`` (a tag of hex digits), if any."""
    return f"{prefix}run-{run}." if run else prefix


def remove_run_temporaries(directory: str, run: str, recursive: bool = False) -> list[str]:
    """Remove the temporary files of the run ``run`` in ``directory`` (and below it, if
    ``recursive``), whoever made them: those of a worker killed mid-file, which no other process
    removes while the worker's host cannot tell that it has gone; returns their paths. Call it
    only when no process of that run is still writing."""
    removed = []
    for folder, _dirs, names in os.walk(directory) if recursive else [(directory, [], _names(directory))]:
        for name in names:
            if is_run_temporary(name, run):
                path = os.path.join(folder, name)
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(path)
                    removed.append(path)
    return removed


def _names(directory: str) -> list[str]:
    try:
        return os.listdir(directory)
    except OSError:
        return []


def _mkstemp(prefix: str, directory: str | None = None) -> tuple[int, str]:
    """A new temporary file named for this process, after removing those killed runs left."""
    directory = directory or tempfile.gettempdir()
    remove_stale_temporaries(directory)
    return tempfile.mkstemp(prefix=f"{prefix}{_maker()}-", suffix=TEMP_SUFFIX, dir=directory)


def temporary_file(prefix: str, directory: str | None = None) -> tuple[int, str]:
    """A new temporary file (descriptor, path) named ``PREFIX<pid-start-host>-XXXXXXXX.hconv-tmp``
    in ``directory`` (default: the temporary directory), so that if this process is killed the
    next hconv run there removes it (:func:`remove_stale_temporaries`). ``prefix`` is one of
    ``.NAME.`` (beside a file NAME being written), ``hconv-fetch-`` or ``hconv-stage-``."""
    return _mkstemp(prefix, directory)


def spool(stream: BinaryIO, name: str) -> str:
    """Copy ``stream`` (stdin, or a pipe) into a temporary file and return its path; the caller
    removes it.

    Reading stdin can take as long as whatever feeds it, so this is where Ctrl-C and SIGTERM
    (raised as KeyboardInterrupt) usually land: any way out but success removes the file.
    """
    fd, spooled = _mkstemp("hconv-stdin-")
    try:
        try:
            with os.fdopen(fd, "wb") as f:
                while chunk := _read_chunk(stream, name):
                    f.write(chunk)
        except OSError as exc:  # reading fails as InputError, so this is the temporary directory
            raise OutputError(
                f"{name}: could not be copied to a temporary file in {os.path.dirname(spooled)!r} "
                f"({exc.strerror or exc}); set TMPDIR to a directory with room, or give a file instead of '-'"
            ) from None
    except BaseException:
        os.unlink(spooled)
        raise
    return spooled


def _read_chunk(stream: BinaryIO, name: str) -> bytes:
    try:
        return stream.read(1 << 20)
    except OSError as exc:
        raise InputError(f"{name}: cannot read it ({exc.strerror or exc})") from None


def _oserror(name: str, exc: OSError) -> InputError:
    return InputError(f"{name}: cannot read it ({exc.strerror or exc}); check the path and its permissions")


def _first_line(exc: Exception) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def _sniff_csv(path: str, name: str) -> None:
    """Refuse, with the reason, a file that is not comma-separated UTF-8 text (first 64 KiB)."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
    except OSError as exc:
        raise _oserror(name, exc) from None
    if not head:
        return  # the empty file has its own message
    what = _what_it_is(head, path, name, "csv")
    if what:
        raise InputError(f"{name}: {what}")
    if b"\x00" in head or head.startswith(b"\x89PNG") or head.startswith(b"PAR1"):
        parquet = f" (it looks like Parquet: {_rename_or_pass(name, 'parquet')})"
        raise InputError(f"{name}: is not a text file, so not CSV" + (parquet if head.startswith(b"PAR1") else ""))
    head = head[3:] if head.startswith(b"\xef\xbb\xbf") else head
    cut = head.rfind(b"\n") + 1 if len(head) == 1 << 16 else len(head)
    try:
        head[: cut or len(head)].decode("utf-8")
    except UnicodeDecodeError as exc:
        line = head[: exc.start].count(b"\n") + 1
        raise InputError(
            f"{name}: line {line} is not UTF-8 text; convert the file to UTF-8 first "
            "(for example: iconv -f latin1 -t utf-8)"
        ) from None
    first = head.split(b"\n", 1)[0].decode("utf-8").strip("\r")
    if not first.strip():
        raise InputError(f"{name}: the first line is blank; a CSV needs a header line naming the columns")
    if "," not in first:
        for sep, word in ((";", "semicolons"), ("\t", "tabs"), ("|", "bars")):
            if sep in first:
                raise InputError(
                    f"{name}: the header is separated by {word}, but hconv reads comma-separated CSV; "
                    f"convert the delimiter to commas first"
                )


def _header_hint(names: list) -> str:
    """Why a header may not have matched: spaces around names, or a first line that is no header."""
    known = sets.all_names()
    spaced = [n for n in names if n != n.strip() and n.strip() in known]
    if spaced:
        return f" (the header has spaces around {', '.join(repr(n) for n in spaced[:3])}; remove them)"
    if not any(n.strip() in known for n in names):
        return f" (the first line, {','.join(names)[:50]!r}, names none of hconv's columns: is it a CSV header?)"
    return ""


def _one_line(path: str, name: str) -> bytes | None:
    """The bytes of a CSV file that is one line with no line end (a header and no rows, written
    without its newline), which pyarrow takes for an empty file; None for a file with a line end
    in its first block. InputError for a file with none in its first block: no CSV reader reads
    a line longer than a block, and such a file is rarely a CSV (a 100 MB file without a newline
    was called empty)."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
            if not head or b"\n" in head or b"\r" in head:
                return None
            head += f.read(CSV_BLOCK_BYTES + 1 - len(head))
    except OSError as exc:
        raise _oserror(name, exc) from None
    if b"\n" in head or b"\r" in head:
        return None
    if len(head) <= CSV_BLOCK_BYTES:
        return head
    raise InputError(
        f"{name}: has no line end in its first {CSV_BLOCK_BYTES >> 20} MiB; a CSV is a header line and one "
        f"line per row, each shorter than that: is it a CSV?"
    )


@dataclass(frozen=True)
class _Stat:
    """What tells that a file changed while it was read: its size and modification time, as its
    open descriptor sees them (a file replaced by a rename keeps the one being read unchanged)."""

    size: int
    mtime_ns: int

    @staticmethod
    def of(fd: int) -> _Stat:
        st = os.fstat(fd)
        return _Stat(st.st_size, st.st_mtime_ns)


def _changed(name: str, fd: int | None, at_open: _Stat | None, why: str = "") -> InputError | None:
    """InputError if the file open as ``fd`` is no longer as it was when opened (``at_open``):
    rewritten, cut or appended to while hconv read it, so that what was read mixes two versions."""
    if fd is None or at_open is None:
        return None
    try:
        now = _Stat.of(fd)
    except OSError:
        return None
    if now == at_open:
        return None
    return InputError(
        f"{name}: changed while hconv read it (from {at_open.size} to {now.size} bytes{why}); nothing was "
        "written: run again once whatever writes it has finished"
    )


def _open_csv(path: str, name: str, job: Job) -> Input:
    _sniff_csv(path, name)
    one_line = _one_line(path, name)
    ropts = pacsv.ReadOptions(block_size=CSV_BLOCK_BYTES)

    def source() -> pa.NativeFile:
        """The file as pyarrow reads it: a native file, never a Python file object. pyarrow reads
        ahead on its own threads, which may still be reading when an error is raised here; one
        that holds a Python object needs the interpreter, and if the interpreter is exiting by
        then the process aborts (SIGABRT, 'terminate called without an active exception', about
        one run in ten on a file with bad UTF-8 in its first block). A native file needs no
        interpreter, and pyarrow keeps it open for as long as its threads use it."""
        if one_line is not None:  # a header without its newline: read it with one
            return pa.BufferReader(one_line + b"\n")
        return pa.OSFile(path)

    try:
        with pacsv.open_csv(source(), read_options=ropts) as probe:
            names = probe.schema.names
    except pa.ArrowInvalid as exc:
        if "Empty CSV file" in str(exc):
            raise InputError(
                f"{name}: the file is empty; a CSV needs a header line naming the columns "
                f"{', '.join(sets.VECTOR_SETS['H'])} and the inertia "
                f"({'; or '.join(', '.join(f.columns) for f in forms.FORMS.values() if not f.extends)})"
            ) from None
        raise _csv_parse_error(path, name, exc) from None
    except OSError as exc:
        raise _oserror(name, exc) from None
    try:
        plan = layout.plan(pa.schema([(n, pa.float64()) for n in names]), job, name)
    except InputError as exc:
        raise InputError(f"{exc}{_header_hint(names)}") from None
    nums = set(plan.numeric)
    types = {n: (pa.float64() if n in nums else pa.string()) for n in names}
    # NaN is a float value, not a missing one: pyarrow's default null markers include its
    # spellings, which turned a file's NaN into a null (an empty field in CSV output).
    copts = pacsv.ConvertOptions(column_types=types, strings_can_be_null=False, null_values=csvtypes.NULLS.to_pylist())
    try:
        f = source()
        fd = None if one_line is not None else f.fileno()
        at_open = None if fd is None else _Stat.of(fd)
    except OSError as exc:
        raise _oserror(name, exc) from None
    try:  # the reader parses its first block here already, so bad values can show up now
        reader = pacsv.open_csv(f, read_options=ropts, convert_options=copts)
    except pa.ArrowInvalid as exc:  # f is left to pyarrow, whose read-ahead may still be using it
        raise _changed(name, fd, at_open) or _csv_value_error(path, name, names, ropts, exc) from None
    total = f.size()

    def batches() -> Iterator[pa.RecordBatch]:
        while True:
            try:
                batch = reader.read_next_batch()
            except StopIteration:
                break
            except pa.ArrowInvalid as exc:
                raise _changed(name, fd, at_open) or _csv_value_error(path, name, names, ropts, exc) from None
            except (OSError, pa.ArrowException, MemoryError) as exc:  # all the reader raises is the input's
                raise _changed(name, fd, at_open) or InputError(
                    f"{name}: cannot be read ({_first_line(exc)}); check the file"
                ) from None
            yield batch
        changed = _changed(name, fd, at_open)
        if changed:
            raise changed

    text = tuple(n for n in names if n not in nums)
    return Input(name, reader.schema, batches(), total, f.tell, plan, [], text, path)


def reopen(inp: Input, job: Job) -> Input:
    """A CSV input read again from its first row, as a new Input; ``inp`` must stay open
    meanwhile (for stdin it holds the spooled copy)."""
    return _open_csv(inp.path, inp.name, job)


def text_batches(inp: Input) -> Iterator[pa.RecordBatch]:
    """A CSV input's text columns (:attr:`Input.text`) from its first row, block by block, as
    text; stops early where the file stops being readable (reading ``inp`` says why)."""
    ropts = pacsv.ReadOptions(block_size=CSV_BLOCK_BYTES)
    copts = pacsv.ConvertOptions(
        column_types=dict.fromkeys(inp.text, pa.string()), include_columns=list(inp.text), strings_can_be_null=False
    )
    try:
        with pacsv.open_csv(inp.path, read_options=ropts, convert_options=copts) as reader:
            yield from reader
    except (OSError, pa.ArrowException):  # not the output's: reading inp again says what it is
        return


_CSV_COLUMN = re.compile(r"In CSV column #(\d+): CSV conversion error to \w+: invalid value '(.*)'")


_CSV_RAGGED = re.compile(r"Expected (\d+) columns, got (\d+)")
_CSV_UTF8 = re.compile(r"In CSV column #(\d+): CSV conversion error to string: invalid UTF8")


def _csv_parse_error(path: str, name: str, exc: Exception) -> InputError:
    """A row with the wrong number of values, or too long for a block, named by its data row;
    else pyarrow's first line."""
    m = _CSV_RAGGED.search(str(exc))
    straddles = "straddl" in str(exc)  # a row longer than a block ("straddles two block boundaries")
    if not m and not straddles:
        return InputError(f"{name}: not a readable CSV file ({_first_line(exc)})")
    expected = int(m.group(1)) if m else 0
    row, k = "", 0
    try:  # the error path only: find the row with Python's csv module
        with open(path, newline="", encoding="utf-8-sig") as f:
            for k, fields in enumerate(csv.reader(f)):  # noqa: B007 - k is the last row read, below
                if k == 0:
                    expected = expected or len(fields)
                elif fields and len(fields) != expected:
                    row = f"data row {k}"
                    if any("\n" in v for v in fields):  # a quote that ran on, often to the end of the file
                        return InputError(
                            f"{name}: data row {k} has {len(fields)} values where the header names {expected}, "
                            "one of them running over several lines: a quote opened and never closed? close it"
                        )
                    break
    except csv.Error:  # a value longer than the csv module's limit: pyarrow cut its row at a block's end
        return InputError(
            f"{name}: data row {k + 1} runs on for more than {csv.field_size_limit() >> 10} KiB in one value: "
            "a quote opened and never closed, or a line that is not CSV; fix that row"
        )
    except (OSError, UnicodeDecodeError):
        pass
    if not m:
        return InputError(
            f"{name}: {row or 'a row'} is longer than {CSV_BLOCK_BYTES >> 20} MiB, the longest row hconv reads; "
            "is it a CSV?"
        )
    return InputError(
        f"{name}: {row or 'a row'} has {m.group(2)} values, but the header names {expected} columns; "
        "every row needs one value per column (quote a value that holds a comma)"
    )


def _csv_value_error(path: str, name: str, names: list, ropts: pacsv.ReadOptions, exc: Exception) -> InputError:
    """Turn pyarrow's conversion error into one naming the column, the value and its row."""
    u = _CSV_UTF8.search(str(exc))
    if u:
        return InputError(
            f"{name}: column {names[int(u.group(1))]!r} holds text that is not UTF-8; convert the "
            "file to UTF-8 first (for example: iconv -f latin1 -t utf-8)"
        )
    m = _CSV_COLUMN.search(str(exc))
    if not m:
        return _csv_parse_error(path, name, exc)
    col, value = names[int(m.group(1))], m.group(2)
    where = ""
    try:  # a second pass, on the error path only, to find the row
        copts = pacsv.ConvertOptions(column_types={col: pa.string()}, include_columns=[col], strings_can_be_null=False)
        nulls = set(copts.null_values)
        seen = 0
        for batch in pacsv.open_csv(path, read_options=ropts, convert_options=copts):
            for k, v in enumerate(batch.column(0).to_pylist()):
                if v not in nulls:
                    try:
                        float(v)
                    except ValueError:
                        where = f" in data row {seen + k + 1}"
                        raise StopIteration from None
            seen += batch.num_rows
    except (StopIteration, OSError, pa.ArrowException):
        pass
    return InputError(
        f"{name}: column {col!r} must be numeric but holds {value!r}{where}; "
        "fix or blank that value (a blank becomes a row with status invalid_input)"
    )


def _rename_or_pass(name: str, fmt: str) -> str:
    """How to read a file whose bytes are ``fmt`` as ``fmt``: a name with another format's
    extension must change (--from may not contradict it); one without may keep it."""
    if _named_format(name):
        return f"rename it {os.path.splitext(name)[0]}{EXTENSIONS[fmt][0]}"
    return f"name it {EXTENSIONS[fmt][0]} or pass {option('src_format', fmt)}"


def _not_parquet(path: str, name: str, exc: Exception) -> InputError:
    """Why a file pyarrow cannot open as Parquet is not Parquet, when its first bytes tell."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 12)
    except OSError:
        head = b""
    what = _what_it_is(head, path, name, "parquet")
    if what:
        return InputError(f"{name}: {what}")
    first = head.split(b"\n", 1)[0]
    looks_csv = b"," in first and b"\x00" not in head and not head.startswith(b"PAR1")
    hint = f" (it looks like CSV text: {_rename_or_pass(name, 'csv')})" if looks_csv else ""
    return InputError(
        f"{name}: not a readable Parquet file ({_first_line(exc)}){hint}; "
        "check that it is Parquet and was completely written"
    )


def _open_parquet(path: str, name: str, job: Job, rows: tuple[int, int] | None = None) -> Input:
    """The Parquet file ``path``, in batches of :data:`PARQUET_BATCH_ROWS` rows counted from its
    first row; with ``rows`` (start, stop), only those rows, reading only the row groups that hold
    them, in the batches the whole file's reading gives them when ``start`` is a multiple of
    :data:`PARQUET_BATCH_ROWS` (so that a part's output row groups are the whole file's:
    :func:`hconv.tables.dataset.split`)."""
    try:
        if os.path.getsize(path) == 0:
            raise InputError(f"{name}: the file is empty (0 bytes); it is not a Parquet file")
        source = pa.OSFile(path)
        at_open = _Stat.of(source.fileno())
        # Stream pages rather than pre-buffering whole row groups, so that peak memory does not
        # grow with the writer's row-group size (docs/measurements.md).
        # Pages that carry a checksum (pyarrow writes them with write_page_checksum=True) are
        # checked: a damaged page of plain floats otherwise reads as other numbers, silently.
        pf = pq.ParquetFile(source, pre_buffer=False, buffer_size=1 << 20, page_checksum_verification=True)
        schema = pf.schema_arrow  # a footer whose column metadata is damaged fails here
        meta = pf.metadata
    except pa.ArrowException as exc:
        raise _not_parquet(path, name, exc) from None
    except OSError as exc:
        if exc.errno is None and os.path.isfile(path):  # pyarrow's own errors about the bytes
            raise _not_parquet(path, name, exc) from None
        raise _oserror(name, exc) from None
    plan = layout.plan(schema, job, name)
    done = [0]
    start, stop = rows if rows is not None else (0, meta.num_rows)
    groups, skip = _row_groups(meta, start, stop)

    def read(row_groups: list[int]) -> Iterator[pa.RecordBatch]:
        """``pf``'s batches of ``row_groups``. pyarrow reads and decodes the pages lazily, here, on
        the reading thread: whatever it raises is the input's fault (before, a damaged page's
        OSError reached the CLI as the output's, exit 4), named by its row group."""
        got = pf.iter_batches(batch_size=PARQUET_BATCH_ROWS, row_groups=row_groups)
        n = 0  #: rows read, from the first of row_groups
        while True:
            try:
                batch = next(got)
            except StopIteration:
                return
            except Exception as exc:  # noqa: BLE001 - only pyarrow's reading runs in this try
                raise _changed(name, source.fileno(), at_open, f"; {_first_line(exc)}") or _damaged(
                    pf, name, row_groups, n, exc
                ) from None
            n += batch.num_rows
            yield batch

    def read_all() -> Iterator[pa.RecordBatch]:
        got = read(groups)
        for batch in got if rows is None else _rebatched(got, skip, stop - start):
            done[0] += batch.num_rows
            yield batch
        changed = _changed(name, source.fileno(), at_open)
        if changed:  # rewritten in place while read: what was read may mix two versions of it
            raise changed

    batches = read_all()
    if any(g.is_list and g.size is None for g in plan.groups.values()):
        # A variable-length list column's length shows only in the data: the file's first batch
        # fixes it, here on the reading thread, so every batch (of every part) is held to the same plan.
        first = next(batches, None) if start == 0 else next(read([0]), None)
        if first is not None:
            plan = plan.resolve(pa.Table.from_batches([first]))
            if start == 0:
                batches = itertools.chain([first], batches)
    closers = [pf.close, source.close]
    return Input(name, schema, batches, stop - start, lambda: done[0], plan, closers, first_row=start)


def _damaged(pf: pq.ParquetFile, name: str, groups: list[int], read: int, exc: Exception) -> InputError:
    """The error for a Parquet file whose pages pyarrow could not read after ``read`` rows of the
    row groups ``groups``, naming the row group that fails: the next batch may span several, so
    each that it touches is read again, alone (on this error path only)."""
    meta = pf.metadata
    firsts = list(itertools.accumulate((meta.row_group(k).num_rows for k in range(meta.num_row_groups)), initial=0))
    bad, n = None, 0
    for k in groups:
        rows = meta.row_group(k).num_rows
        if n + rows > read and n < read + PARQUET_BATCH_ROWS:  # the failing batch touches it
            bad = bad if bad is not None else k  # at worst the first it touches
            try:
                for _ in pf.iter_batches(batch_size=PARQUET_BATCH_ROWS, row_groups=[k]):
                    pass
            except Exception:  # noqa: BLE001 - any failure names this row group
                bad = k
                break
        n += rows
    if bad is None:
        return InputError(f"{name}: cannot be read ({_first_line(exc)}); the file is damaged: write it again")
    return InputError(
        f"{name}: row group {bad + 1} of {meta.num_row_groups} (data rows {firsts[bad] + 1}-{firsts[bad + 1]}) "
        f"cannot be read ({_first_line(exc)}); the file is damaged or was not completely written: "
        "write it again from its source"
    )


def _row_groups(meta: pq.FileMetaData, start: int, stop: int) -> tuple[list[int], int]:
    """The row groups holding rows [start, stop), and how many rows of the first precede ``start``."""
    groups: list[int] = []
    skip = first = 0
    for k in range(meta.num_row_groups):
        n = meta.row_group(k).num_rows
        if first < stop and first + n > start:
            if not groups:
                skip = start - first
            groups.append(k)
        first += n
    return groups, skip


def _rebatched(batches: Iterator[pa.RecordBatch], skip: int, count: int) -> Iterator[pa.RecordBatch]:
    """``count`` rows after the first ``skip`` of ``batches``, in batches of
    :data:`PARQUET_BATCH_ROWS` (the last shorter): the reader's batches start at a row group's
    first row, the whole file's at the file's."""
    held: list[pa.RecordBatch] = []
    n = 0
    for batch in batches:
        if skip >= batch.num_rows:
            skip -= batch.num_rows
            continue
        batch = batch.slice(skip, min(batch.num_rows - skip, count))
        skip = 0
        count -= batch.num_rows
        held.append(batch)
        n += batch.num_rows
        while n >= PARQUET_BATCH_ROWS:
            whole = pa.concat_batches(held) if len(held) > 1 else held[0]
            yield whole.slice(0, PARQUET_BATCH_ROWS)
            rest = whole.slice(PARQUET_BATCH_ROWS)
            held, n = ([rest] if rest.num_rows else []), rest.num_rows
        if count <= 0:
            break
    if n:
        yield pa.concat_batches(held) if len(held) > 1 else held[0]


def parquet_shape(source: str | Any) -> tuple[int, int]:
    """(rows, row groups) of a Parquet file, a path or an open file, from its footer alone."""
    with pq.ParquetFile(source) as pf:
        return pf.metadata.num_rows, pf.metadata.num_row_groups


def join_parquet(parts: list[str], path: str) -> None:
    """Write the Parquet files ``parts`` (the parts of one output, in order, each written by
    hconv's writer) into ``path`` as one file, row group by row group: the same schema, metadata
    and writer options, so that the file is the one the whole conversion writes
    (:func:`hconv.tables.dataset.join_parts`)."""
    writer: _ParquetWriter | None = None
    try:
        for part in parts:
            with pq.ParquetFile(part) as pf:
                if writer is None:
                    writer = _ParquetWriter(path, pf.schema_arrow)
                for k in range(pf.metadata.num_row_groups):
                    writer.write(pf.read_row_group(k))
    finally:
        if writer is not None:
            writer.close()


class Output:
    """Atomic output: batches go to a temporary file, renamed over ``path`` on success only.

    Use as a context manager; on any exception (KeyboardInterrupt included) the temporary file
    is removed and ``path`` is left as it was.
    """

    def __init__(
        self, path: str, fmt: str, *, force: bool = False, input_path: str | None = None, shown: str | None = None
    ):
        self.path, self.fmt = path, fmt
        #: the output as messages name it: ``path``, or the file that a dataset's staged ``path`` becomes
        self.shown = shown or ("stdout" if path == "-" else path)
        self._writer: _CsvWriter | _ParquetWriter | None = None
        self._tmp: str | None = None
        self._target = path  #: where the file goes: ``path``, or the file a link at ``path`` names
        if path == "-":
            if fmt == "parquet" and sys.stdout is not None and sys.stdout.isatty():
                raise UsageError(
                    f"Parquet is binary: redirect stdout (> out.parquet) or use {option('dst_format', 'csv')}"
                )
            return
        try:
            mode: int | None = os.stat(path).st_mode  # follows a link: what would be overwritten
        except OSError:
            mode = None
        if mode is not None and stat.S_ISDIR(mode):
            raise OutputError(f"{path}: is a directory; give a file name for the output")
        if mode is not None and not stat.S_ISREG(mode):
            raise OutputError(
                f"{path}: is not a regular file ({_file_kind(mode)}); hconv writes OUT by renaming a finished "
                "file into place; give a file path, or - to write to stdout"
            )
        if os.path.islink(path):  # write the link's target and keep the link, as `>` would
            self._target = os.path.realpath(path)
        target = Path(self._target)
        if not target.parent.exists():
            raise OutputError(f"{path}: the directory {str(target.parent)!r} does not exist; create it first")
        if input_path not in (None, "-") and target.exists() and os.path.samefile(input_path, target):
            raise OutputError(f"{path}: is the input file; write the output to another path")
        if target.exists() and not force:
            raise OutputError(f"{path}: already exists; pass {option('force', True)} to overwrite it")

    def __enter__(self) -> Output:
        if self.path == "-":
            fd, self._tmp = _mkstemp("hconv-stdout-")
        else:
            target = Path(self._target)
            # cut a long name so that the pid and the rest still fit in the 255 bytes a name may have
            name = os.fsdecode(os.fsencode(target.name)[:160])
            try:
                fd, self._tmp = _mkstemp(f".{name}.", str(target.parent))
            except OSError as exc:
                raise OutputError(
                    f"{self.path}: cannot write in {str(target.parent)!r} ({exc.strerror}); check its permissions"
                ) from None
        try:  # __exit__ does not run when __enter__ fails: remove the file here
            os.close(fd)
            if self.path != "-":  # mkstemp makes the file 0600; the output should get the usual permissions
                umask = os.umask(0)
                os.umask(umask)
                os.chmod(self._tmp, 0o666 & ~umask)
        except BaseException:
            os.unlink(self._tmp)
            raise
        return self

    def write(self, table: pa.Table) -> None:
        """Append a converted table; the first call fixes the output schema."""
        if self._tmp is None:
            raise ValueError("write to an Output inside its with block")
        try:
            if self._writer is None:
                self._writer = (_CsvWriter if self.fmt == "csv" else _ParquetWriter)(self._tmp, table.schema)
            self._writer.write(table)
        except OSError as exc:  # a full disk, a quota: the output named, not the temporary file
            raise write_failure(self.shown, exc) from None

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: object) -> None:
        try:
            if self._writer is not None:
                self._writer.close()
            if exc_type is None:
                self._commit()
        except OSError as err:
            if exc_type is None:
                raise write_failure(self.shown, err) from None
        finally:
            if self._tmp and os.path.exists(self._tmp):
                os.unlink(self._tmp)

    def _commit(self) -> None:
        if self._tmp is None:
            return
        if self.path == "-":
            with open(self._tmp, "rb") as f:
                try:
                    shutil.copyfileobj(f, sys.stdout.buffer, 1 << 20)
                    sys.stdout.buffer.flush()
                except BrokenPipeError:  # the reader stopped early (e.g. `| head`): not our failure
                    devnull = os.open(os.devnull, os.O_WRONLY)
                    os.dup2(devnull, sys.stdout.fileno())
            interrupts.committed()
        else:
            # held: an interrupt during the rename acts after it, when the command may be settled
            # (hconv.interrupts), rather than leaving OUT in place and the run exiting 130
            interrupts.point("commit")
            with interrupts.held():
                os.replace(self._tmp, self._target)
                self._tmp = None
                interrupts.committed()
                interrupts.point("committed")


#: The errors that say the disk (or the user's quota on it) has no room: no file written there can succeed.
NO_ROOM = (errno.ENOSPC, errno.EDQUOT)


def write_failure(shown: str, exc: OSError) -> OutputError:
    """OutputError for the output ``shown`` that could not be written, its errno kept (so that a
    dataset can tell a full disk, :data:`NO_ROOM`, from one file's failure)."""
    reason = os.strerror(exc.errno) if exc.errno else exc.strerror or _first_line(exc)
    err = OutputError(f"{shown}: could not be written ({reason}); nothing was written")
    err.errno = exc.errno
    return err


def _file_kind(mode: int) -> str:
    """What a path that is not a regular file is, for a message."""
    for test, what in (
        (stat.S_ISFIFO, "a named pipe (FIFO)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return what
    return "not a file"


def parquet_write_options(schema: pa.Schema) -> dict:
    """hconv's Parquet settings for a table of ``schema``, as keyword arguments of
    ``pyarrow.parquet.ParquetWriter`` and ``pyarrow.parquet.write_table`` (and of what passes
    them on: Dask's ``to_parquet``, Ray's ``arrow_parquet_args``); hconv's own writer uses them.

    Float columns plain: no dictionary, no compression. Every other column (ids, labels,
    ``status``) dictionary-encoded and snappy-compressed. The settings name top-level columns, so
    the values of a list column get pyarrow's writer defaults: no dictionary, no compression.
    """
    # Dictionary encoding and compression pay for labels and statuses. On floats that rarely
    # repeat, dictionaries only cost time and snappy saves little space for much writing
    # time (docs/measurements.md), so float columns are written plain.
    floats = {f.name for f in schema if pa.types.is_floating(f.type)}
    others = [f.name for f in schema if f.name not in floats]
    return {
        "use_dictionary": others or False,
        "compression": {f.name: "none" if f.name in floats else "snappy" for f in schema},
    }


class _ParquetWriter:
    def __init__(self, path: str, schema: pa.Schema):
        self._w = pq.ParquetWriter(path, schema, **parquet_write_options(schema))

    def write(self, table: pa.Table) -> None:
        self._w.write_table(table)

    def close(self) -> None:
        self._w.close()


def check_csv_columns(schema: pa.Schema, name: str) -> None:
    """InputError, before anything is converted, for a column CSV cannot hold: a struct, map or
    union (lists are written as text, :func:`_list_as_text`)."""
    for f in schema:
        t = f.type.value_type if pa.types.is_dictionary(f.type) else f.type
        if pa.types.is_struct(t) or pa.types.is_map(t) or pa.types.is_union(t):
            raise InputError(_csv_cannot_hold(name, f))


def _csv_cannot_hold(name: str, f: pa.Field, why: str = "") -> str:
    return (
        f"{name + ': ' if name else ''}column {f.name!r} is {f.type}{why}, which CSV cannot hold; "
        "write Parquet instead (OUT named .parquet), or drop the column first"
    )


def _binary_as_text(col: pa.ChunkedArray, f: pa.Field) -> pa.ChunkedArray:
    """A binary column as text, which it must be to go into CSV: InputError if it holds bytes that
    are not UTF-8 (a Parquet byte array without the string annotation usually is text)."""
    try:
        return col.cast(pa.string())
    except pa.ArrowInvalid:
        raise InputError(_csv_cannot_hold("", f, " and holds bytes that are not UTF-8 text")) from None


def _list_as_text(col: pa.ChunkedArray) -> pa.ChunkedArray | pa.Array:
    """A list column as text, ``[1.5, 2.0, 3.0]``, since CSV has no lists; other columns as they are."""
    t = col.type
    if not (pa.types.is_list(t) or pa.types.is_large_list(t) or pa.types.is_fixed_size_list(t)):
        return col
    return pa.array(
        [None if v is None else "[" + ", ".join(repr(x) for x in v) + "]" for v in col.to_pylist()], type=pa.string()
    )


_NEEDS_QUOTES = r'[,"\r\n]'


def _empty_beside_null(col: pa.ChunkedArray) -> bool:
    """A text column holding both nulls and empty strings, which unquoted CSV would merge."""
    return (
        (pa.types.is_string(col.type) or pa.types.is_large_string(col.type))
        and col.null_count > 0
        and bool(pc.any(pc.equal(col, "")).as_py())
    )


def _csv_rows(t: pa.Table) -> bytes:
    """``t`` as CSV rows, each value quoted only if it must be: one holding a comma, quote or line
    break, and, in a column that also holds nulls, the empty string (``""``; a null is empty).
    pyarrow's own quoting (``needed``) quotes every text value, so that ``1`` became ``"1"``; the
    values are formatted by the same cast pyarrow's writer uses, so the bytes match its unquoted
    output otherwise."""
    cols = []
    for col in t.columns:
        text = pc.cast(col, pa.string())
        quoted = pc.binary_join_element_wise('"', pc.replace_substring(text, '"', '""'), '"', "")
        text = pc.if_else(pc.match_substring_regex(text, _NEEDS_QUOTES), quoted, text)
        if col.null_count:
            text = pc.if_else(pc.equal(text, ""), '""', text)
        cols.append(pc.fill_null(text, ""))
    lines = pc.binary_join_element_wise(*cols, ",") if cols else pa.array([""] * t.num_rows)
    return "".join(line + "\n" for line in lines.to_pylist()).encode()


class _CsvWriter:
    """CSV with a minimal-quoting header, ``status`` as text and ω's unit in a ``w_unit`` column."""

    def __init__(self, path: str, schema: pa.Schema):
        self._f = open(path, "wb")  # noqa: SIM115 - written batch by batch; close() closes it
        meta = schema.field("wx").metadata or {} if "wx" in schema.names else {}
        self._unit = meta[b"unit"].decode() if b"unit" in meta else None  # only tables with ω have one
        names = schema.names + ([UNIT_COLUMN] if self._unit else [])
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerow(names)
        self._f.write(buf.getvalue().encode())
        self._plain = pacsv.WriteOptions(include_header=False, quoting_style="none")

    def write(self, table: pa.Table) -> None:
        check_csv_columns(table.schema, "")  # the callers check the input first, naming it
        cols = [
            c.cast(pa.string())
            if pa.types.is_dictionary(c.type)
            else _binary_as_text(c, f)
            if pa.types.is_binary(f.type) or pa.types.is_large_binary(f.type) or pa.types.is_fixed_size_binary(f.type)
            else _list_as_text(c)
            for c, f in zip(table.columns, table.schema, strict=True)
        ]
        names = table.schema.names
        if self._unit:
            cols.append(pa.repeat(self._unit, table.num_rows))
            names = names + [UNIT_COLUMN]
        t = pa.Table.from_arrays(cols, names=names)
        if any(_empty_beside_null(c) for c in t.columns):
            self._f.write(_csv_rows(t))
            return
        buf = pa.BufferOutputStream()
        try:
            pacsv.write_csv(t, buf, self._plain)
        except pa.ArrowInvalid:  # a value holds a comma, quote or newline: quote those values only
            self._f.write(_csv_rows(t))
            return
        self._f.write(buf.getvalue())

    def close(self) -> None:
        self._f.close()
