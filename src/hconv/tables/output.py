"""Atomic output: batches go to a temporary file next to the output (:mod:`hconv.tables.temporaries`
names it), renamed into place only when the whole run succeeded, so a failed or interrupted run
leaves no partial output. With "-" as output the finished file is then copied to stdout. A write
that fails names the output, its errno kept (a full disk: :data:`NO_ROOM`)."""

from __future__ import annotations

import errno
import os
import shutil
import stat
import sys
from pathlib import Path

import pyarrow as pa

from hconv import interrupts
from hconv.errors import OutputError, UsageError, first_line, option
from hconv.tables.csvio import CsvWriter
from hconv.tables.parquetio import ParquetWriter
from hconv.tables.sniff import delimiter_by_name
from hconv.tables.temporaries import temporary_file


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
        self._writer: CsvWriter | ParquetWriter | None = None
        self._tmp: str | None = None
        self._target = path  #: where the file goes: ``path``, or the file a link at ``path`` names
        if path == "-":
            if fmt == "parquet" and sys.stdout is not None and sys.stdout.isatty():
                raise UsageError(
                    f"Parquet is binary: redirect stdout (> out.parquet) or use {option('dst_format', 'csv')}"
                )
            if input_path not in (None, "-") and _stdout_is(input_path):  # `>> in.parquet` would append to it
                raise OutputError("stdout: is the input file (redirected onto it); write the output to another path")
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
        if not target.parent.is_dir():
            raise OutputError(f"{path}: {str(target.parent)!r} is not a directory; give a path in a directory")
        if input_path not in (None, "-") and target.exists() and os.path.samefile(input_path, target):
            raise OutputError(f"{path}: is the input file; write the output to another path")
        if target.exists() and not force:
            raise OutputError(f"{path}: already exists; pass {option('force', True)} to overwrite it")

    def __enter__(self) -> Output:
        if self.path == "-":
            fd, self._tmp = temporary_file("hconv-stdout-")
        else:
            target = Path(self._target)
            # cut a long name so that the pid and the rest still fit in the 255 bytes a name may have
            name = os.fsdecode(os.fsencode(target.name)[:160])
            try:
                fd, self._tmp = temporary_file(f".{name}.", str(target.parent))
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
                if self.fmt == "csv":  # out.tsv gets tabs
                    self._writer = CsvWriter(self._tmp, table.schema, delimiter_by_name(self.shown) or ",")
                else:
                    self._writer = ParquetWriter(self._tmp, table.schema)
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


def _stdout_is(path: str) -> bool:
    """Whether stdout is the file at ``path`` (a shell's ``>`` or ``>>`` onto it)."""
    try:
        return os.path.samestat(os.fstat(sys.stdout.fileno()), os.stat(path))
    except (OSError, ValueError, AttributeError):  # closed, not a file descriptor (a test's capture), gone
        return False
