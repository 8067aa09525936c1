"""What a bench run, or a script in benchmarks/, could leave behind when killed outright (kill -9,
the OOM killer), and how it does not: its temporary folders are named by the process that made
them (``hconv-bench.<maker>.<kind>…``), so that a later run removes them once that process is
gone, and its children die with it (Linux's parent-death signal).
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import tempfile
from collections.abc import Callable
from typing import Any

#: A bench run's temporary folder, ``hconv-bench.<maker>.<kind>…``: it names the process that made
#: it, so that a later run can remove it once that process is gone (killed outright, it could not).
_FOLDER = re.compile(r"^hconv-bench\.([^.]+)\.")


def temporary_folder(kind: str = "") -> tempfile.TemporaryDirectory[str]:
    """A temporary folder for this bench run, named as :func:`remove_stale_folders` recognises."""
    return tempfile.TemporaryDirectory(prefix=folder_prefix(kind))


def folder_prefix(kind: str = "") -> str:
    """The start of a bench folder's name, ``hconv-bench.<maker>.<kind>``, for this process (the
    scripts in benchmarks/ name theirs so too)."""
    from hconv.tables import temporaries

    return f"hconv-bench.{temporaries.maker()}.{kind}"


def remove_stale_folders(log: Callable[[str], None] = lambda s: None, where: str | None = None) -> list[str]:
    """Remove the folders of bench runs killed outright (kill -9, the OOM killer), which stayed in
    ``where`` (default: the temporary directory), saying so through ``log``; returns their paths.
    A folder whose run still goes, or may (made on another host sharing the directory), is left
    alone."""
    from hconv.tables import temporaries

    removed: list[str] = []
    try:
        entries = list(os.scandir(where or tempfile.gettempdir()))
    except OSError:
        return removed  # making this run's folder will say what is wrong with the directory
    for entry in entries:
        m = _FOLDER.match(entry.name)
        if not m or not temporaries.maker_gone(m.group(1)):
            continue
        try:
            if not entry.is_dir(follow_symlinks=False):
                continue
        except OSError:
            continue
        shutil.rmtree(entry.path, ignore_errors=True)  # another run may be removing it too
        if not os.path.lexists(entry.path):
            log(f"removed {entry.path}, left by a bench run that was killed")
            removed.append(entry.path)
    return removed


def child(args: list, **kwargs: Any) -> subprocess.CompletedProcess:
    """``subprocess.run`` for a child that must not outlive this process: a bench killed outright
    left its cold-start child compiling for seconds, writing into a folder the next run had
    removed. Not for the commands the bench times by the clock (a fork with this hook copies the
    bench's page tables first, where a plain spawn does not)."""
    return subprocess.run(args, preexec_fn=die_with_parent, **kwargs)


def die_with_parent() -> None:
    """In the child, before it runs: the kernel kills it when its parent ends (Linux; elsewhere
    nothing), and it ends at once if the parent has already gone."""
    parent = os.getppid()
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:
        os._exit(1)
