"""Atomic output: batches go to a temporary file next to the output (:mod:`hconv.tables.temporaries`
names it), renamed into place only when the whole run succeeded, so a failed or interrupted run
leaves no partial output. With "-" as output the finished file is then copied to stdout. A write
that fails names the output, its errno kept (a full disk: :data:`NO_ROOM`).

One exception, as Unix filters behave: with "-" as output, a stdout that is a pipe, and a run
that may stream (``stream``: CSV, or Arrow's stream format from a single pass), batches go
straight into the pipe, so that its reader gets rows at once, and a reader that goes away
(``| head``) stops the run at its next write (BrokenPipeError, which the command takes quietly).
A run that fails then has written the rows before the failure; its exit code says so.

An existing directory as OUT for one input file is the file of the input's name in it, as ``cp``
does (:func:`into_directory`)."""

from __future__ import annotations

import errno
import os
import shlex
import shutil
import stat
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from hconv import interrupts
from hconv.errors import HconvError, InputError, OutputError, UsageError, first_line, option
from hconv.tables import csvio, layout
from hconv.tables.csvwrite import CsvWriter
from hconv.tables.formats import EXTENSIONS, NAMES
from hconv.tables.ipcio import IpcWriter
from hconv.tables.job import Job
from hconv.tables.parquetio import ParquetWriter
from hconv.tables.sniff import delimiter_by_name, format_of, input_kind
from hconv.tables.temporaries import temporary_file, umask


class Output:
    """Atomic output: batches go to a temporary file, renamed over ``path`` on success only.

    Use as a context manager; on any exception (KeyboardInterrupt included) the temporary file
    is removed and ``path`` is left as it was.
    """

    def __init__(
        self,
        path: str,
        fmt: str,
        *,
        force: bool = False,
        input_path: str | None = None,
        shown: str | None = None,
        stream: bool = False,
        staged: bool = False,
        reads: Job | None = None,
        source: str | None = None,
    ):
        self.path, self.fmt = path, fmt
        #: ``path`` is the caller's own temporary file (a dataset's output, staged beside it:
        #: :func:`hconv.tables.onefile.stage_output`): written in place, since a second temporary
        #: file would only be renamed onto the first; the caller commits it, or removes it
        self.staged = staged
        #: the output as messages name it: ``path``, or the file that a dataset's staged ``path`` becomes
        self.shown = shown or ("stdout" if path == "-" else path)
        #: the input as messages name it, for a value of it that OUT's format cannot hold
        self.source = source
        self._writer: CsvWriter | ParquetWriter | IpcWriter | None = None
        #: into CSV, the input's row of units by column, written under the header; None: no such row
        self.units: dict[str, str] | None = None
        self._tmp: str | None = None
        self._open = False  #: inside the with block
        self._target = path  #: where the file goes: ``path``, or the file a link at ``path`` names
        #: batches go straight to stdout, a pipe (the module's docstring); else through a temporary file
        self.direct = path == "-" and stream and fmt != "parquet" and _stdout_is_pipe()
        if staged:
            return
        if path == "-":
            if fmt != "csv" and sys.stdout is not None and sys.stdout.isatty():
                raise UsageError(
                    f"{NAMES[fmt].split(' (')[0]} is binary: redirect stdout (> out{EXTENSIONS[fmt][0]}) "
                    f"or use {option('dst_format', 'csv')}"
                )
            if input_path not in (None, "-") and _stdout_is(input_path):  # `>> in.parquet` would append to it
                raise OutputError("stdout: is the input file (redirected onto it); write the output to another path")
            return
        if input_path not in (None, "-"):  # a missing input is the input's error, whatever OUT is
            input_kind(input_path)
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
            raise _no_directory(path, str(target.parent))
        if not target.parent.is_dir():
            raise OutputError(f"{path}: {str(target.parent)!r} is not a directory; give a path in a directory")
        if input_path not in (None, "-") and target.exists() and os.path.samefile(input_path, target):
            raise OutputError(f"{path}: is the input file; write the output to another path")
        if target.exists() and not force:
            raise OutputError(f"{path}: already exists; pass {option('force', True)} to overwrite it")
        if target.exists() and reads is not None and looks_like_input(self._target, fmt, reads):
            raise OutputError(
                f"{path}: looks like an input (it has H and I columns, not hconv's output columns), so "
                f"{option('force', True)} does not overwrite it (an unquoted glob?); quote the glob, or remove "
                "or rename the file"
            )

    def __enter__(self) -> Output:
        self._open = True
        if self.direct:
            return self
        if self.staged:
            self._tmp = self.path
            return self
        if self.path == "-":
            fd, self._tmp = temporary_file("hconv-stdout-")
        else:
            target = Path(self._target)
            # cut a long name so that the pid and the rest still fit in the 255 bytes a name may have
            name = os.fsdecode(os.fsencode(target.name)[:160])
            try:
                fd, self._tmp = temporary_file(f".{name}.", str(target.parent))
            except OSError as exc:
                where = str(target.parent)
                if exc.errno == errno.ENOENT:  # the folder is there, yet takes no file: /proc, a pseudo file system
                    raise OutputError(
                        f"{self.path}: cannot create a file in {where!r}: it takes no new files (a pseudo file "
                        "system, as /proc and /sys are); write OUT in another directory"
                    ) from None
                raise OutputError(
                    f"{self.path}: cannot write in {where!r} ({exc.strerror}); check its permissions"
                ) from None
        try:  # __exit__ does not run when __enter__ fails: remove the file here
            os.close(fd)
            if self.path != "-":  # mkstemp makes the file 0600; the output should get the usual permissions
                os.chmod(self._tmp, 0o666 & ~umask())
        except BaseException:
            os.unlink(self._tmp)
            raise
        return self

    def write(self, table: pa.Table) -> None:
        """Append a converted table; the first call fixes the output schema."""
        if not self._open or (self._tmp is None and not self.direct):
            raise ValueError("write to an Output inside its with block")
        try:
            if self._writer is None:
                self._writer = self._new_writer(table.schema)
            self._writer.write(table)
            if self.direct and table.num_rows:
                interrupts.streamed()
        except BrokenPipeError:  # stdout's reader went away (`| head`): its choice, not a failure
            raise
        except OSError as exc:  # a full disk, a quota: the output named, not the temporary file
            raise write_failure(self.shown, exc) from None
        except InputError as exc:  # a column the format cannot hold: the writer knows no file name
            if self.source is None or str(exc).startswith(f"{self.source}: "):
                raise
            raise InputError(f"{self.source}: {exc}") from None

    def _new_writer(self, schema: pa.Schema) -> CsvWriter | ParquetWriter | IpcWriter:
        # Straight to stdout through its path, so that each writer opens a native file as ever
        # (a pipe opened again by /dev/fd is the same pipe).
        path = f"/dev/fd/{sys.stdout.fileno()}" if self.direct else self._tmp
        assert path is not None
        if self.fmt == "csv":  # out.tsv gets tabs
            return CsvWriter(path, schema, delimiter_by_name(self.shown) or ",", self.units)
        if self.fmt == "arrow":
            return IpcWriter(path, schema, stream=self.path == "-")
        return ParquetWriter(path, schema)

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: object) -> None:
        self._open = False
        try:
            if self._writer is not None:
                self._writer.close()
            if exc_type is None:
                self._commit()
        except BrokenPipeError:
            if exc_type is None:
                raise
        except OSError as err:
            if exc_type is None:
                raise write_failure(self.shown, err) from None
        finally:  # a staged file is the caller's to remove
            if self._tmp and not self.staged and os.path.exists(self._tmp):
                os.unlink(self._tmp)

    def _commit(self) -> None:
        if self.staged:  # in place: the caller commits it
            self._tmp = None
            return
        if self.direct:
            interrupts.committed()
            return
        if self._tmp is None:
            return
        if self.path == "-":
            with open(self._tmp, "rb") as f:
                try:
                    shutil.copyfileobj(f, sys.stdout.buffer, 1 << 20)
                    sys.stdout.buffer.flush()
                except BrokenPipeError:  # the reader stopped early (e.g. `| head`): not our failure,
                    # but no summary either (the rows never reached it): the command stops quietly,
                    # as it does when the reader of a CSV goes away
                    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                    raise
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


def looks_like_input(path: str, fmt: str, job: Job) -> bool:
    """Whether the existing file ``path`` (as ``fmt``) is one that ``job`` could read as an input
    (it has H and I columns) and is not an earlier output of hconv, so that even ``--force`` keeps
    it (``hconv convert two/*.csv --force``, a glob the shell made into IN and OUT). An output of
    hconv holds every column hconv writes (:data:`hconv.tables.layout.OUTPUT_COLUMNS`) under one
    prefix, any prefix; a column or two of those names is the input's own (a ``status`` of the
    user's, which ``--prefix`` is for), and hconv's schema metadata is no sign either (a table
    whose ω columns were dropped keeps it). Reads the header or the schema only; a file that
    cannot be read so is not an input."""
    try:
        if fmt == "csv":
            header = csvio.header_names(path, job)
            schema = None if header is None else pa.schema([(n, pa.float64()) for n in header])
        elif fmt == "parquet":
            schema = pq.read_schema(path)
        else:
            schema = _ipc_schema(path)
    except (OSError, ValueError, HconvError, pa.ArrowException):
        return False
    if schema is None:
        return False
    names = set(schema.names)
    last = layout.OUTPUT_COLUMNS[-1]
    for name in names:
        prefix = name[: -len(last)] if name.endswith(last) else None
        if prefix is not None and all(prefix + c in names for c in layout.OUTPUT_COLUMNS):
            return False
    try:
        layout.plan(schema, job, path)
    except (HconvError, ValueError):
        return False
    return True


def _ipc_schema(path: str) -> pa.Schema:
    """The schema of an Arrow IPC file, in the file or the stream format."""
    with pa.memory_map(path) as source:
        try:
            return pa.ipc.open_file(source).schema
        except pa.ArrowInvalid:
            source.seek(0)
            return pa.ipc.open_stream(source).schema


#: The errors that say the disk (or the user's quota on it) has no room: no file written there can succeed.
NO_ROOM = (errno.ENOSPC, errno.EDQUOT)


def write_failure(shown: str, exc: OSError) -> OutputError:
    """OutputError for the output ``shown`` that could not be written, its errno kept (so that a
    dataset can tell a full disk, :data:`NO_ROOM`, from one file's failure)."""
    reason = os.strerror(exc.errno) if exc.errno else exc.strerror or first_line(exc)
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


def _stdout_is_pipe() -> bool:
    try:
        return stat.S_ISFIFO(os.fstat(sys.stdout.fileno()).st_mode)
    except (OSError, ValueError, AttributeError):  # closed, not a file descriptor (a test's capture)
        return False


def into_directory(src: str, dst: str, src_format: str | None, dst_format: str | None) -> str:
    """OUT for one input file: ``dst`` itself, or where ``dst`` is an existing directory, the file
    in it named as the input, as ``cp`` names it; with ``dst_format`` another format than the
    input's, the name takes that format's extension (``s.csv --to parquet``: ``dst/s.parquet``)."""
    if dst == "-" or "://" in dst:
        return dst
    if not os.path.isdir(dst):
        # a name ending in / means a directory, and one in a missing directory cannot be written:
        # refused before the name's format is asked for (a directory has none)
        folder = dst.rstrip("/" + os.sep) if dst.endswith(("/", os.sep)) else os.path.dirname(dst)
        if folder and os.path.exists(folder) and not os.path.isdir(folder):
            raise OutputError(f"{dst}: {folder!r} is not a directory; give a path in a directory")
        if folder and not os.path.exists(folder):
            raise _no_directory(dst, folder)
        return dst
    if src == "-":
        raise UsageError(f"{dst}: is a directory, and stdin has no name to give the output; give OUT a file name")
    name = os.path.basename(src.rstrip(os.sep))
    if dst_format is not None and dst_format != format_of(src, src_format, "src_format"):
        stem, ext = os.path.splitext(name)
        named = any(ext.lower() in exts for exts in EXTENSIONS.values())
        name = (stem if named else name) + EXTENSIONS[dst_format][0]
    return os.path.join(dst, name)


def _no_directory(path: str, folder: str) -> OutputError:
    """OUT at ``path`` is in ``folder``, which does not exist: the command that makes it."""
    return OutputError(
        f"{path}: the directory {folder!r} does not exist; create it first (mkdir -p {shlex.quote(folder)})"
    )


def _stdout_is(path: str) -> bool:
    """Whether stdout is the file at ``path`` (a shell's ``>`` or ``>>`` onto it)."""
    try:
        return os.path.samestat(os.fstat(sys.stdout.fileno()), os.stat(path))
    except (OSError, ValueError, AttributeError):  # closed, not a file descriptor (a test's capture), gone
        return False
