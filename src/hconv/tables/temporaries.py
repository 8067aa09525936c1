"""hconv's temporary files: their names, which carry the process that made each (and, on a
cluster, the run's tag), the check that this process has ended, and the sweep that removes the
files of runs killed outright (SIGKILL, the OOM killer, a power cut), which could not clean up.
A file whose maker still runs, or may run (another host, no way to tell), is left alone."""

from __future__ import annotations

import contextlib
import os
import re
import socket
import sys
import tempfile
import uuid
import zlib
from collections.abc import Iterator
from pathlib import Path

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
    pid is checked. Worked out once per process (a forked child is another: its pid tells), not
    per file: reading /proc for it cost a small file's output 0.4 ms."""
    pid = os.getpid()
    if _MAKER.get("pid") != pid:
        _MAKER.update(pid=pid, token=f"{pid}-{_proc_start(pid) or 0}-{_machine_tag()}")
    return str(_MAKER["token"])


_MAKER: dict[str, object] = {}


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


#: A part of one output converted by one task of a cluster run (hconv.tables.parts.split):
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


def new_run_tag() -> str:
    """A new run's tag, for :func:`run_prefix`: 12 random hex digits."""
    return uuid.uuid4().hex[:12]


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


#: The directories swept during a :func:`sweeping_once` block (None outside one: every call sweeps).
_swept: set[str] | None = None
#: The umask, as read when the outermost :func:`sweeping_once` block began (None outside one).
_umask: int | None = None


@contextlib.contextmanager
def sweeping_once() -> Iterator[None]:
    """Inside the block, :func:`temporary_file` sweeps each directory once, not at every file: a
    dataset run makes a temporary file per output, and listing a folder of thousands of outputs
    for each cost more than converting a small file. A process killed after the sweep leaves its
    files to the next run, as before. :func:`umask` is read once, here, before the run's threads
    start."""
    global _swept, _umask
    outer, _swept = _swept, set() if _swept is None else _swept
    outer_mask, _umask = _umask, umask()
    try:
        yield
    finally:
        _swept, _umask = outer, outer_mask


def umask() -> int:
    """The process's umask, which a file mkstemp made (0600) is given an output's permissions by.
    Reading it means setting it for a moment: a file or folder another thread made in that moment
    would get no umask at all (0666, 0777). So inside a :func:`sweeping_once` block (a dataset
    run, whose threads make files side by side) it is the value read when the block began."""
    if _umask is not None:
        return _umask
    mask = os.umask(0)
    os.umask(mask)
    return mask


def temporary_file(prefix: str, directory: str | None = None) -> tuple[int, str]:
    """A new temporary file (descriptor, path) named ``PREFIX<pid-start-host>-XXXXXXXX.hconv-tmp``
    in ``directory`` (default: the temporary directory), after removing those killed runs left
    there, so that if this process is killed the next hconv run there removes it
    (:func:`remove_stale_temporaries`). ``prefix`` is one of ``.NAME.`` (beside a file NAME being
    written), ``hconv-stdin-``, ``hconv-stdout-``, ``hconv-fetch-`` or ``hconv-stage-``."""
    directory = directory or tempfile.gettempdir()
    if _swept is None or directory not in _swept:
        remove_stale_temporaries(directory)
        if _swept is not None:
            _swept.add(directory)
    return tempfile.mkstemp(prefix=f"{prefix}{_maker()}-", suffix=TEMP_SUFFIX, dir=directory)
