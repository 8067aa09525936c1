"""A dataset's files converted on a Dask cluster: small files packed into tasks of many files
(:func:`batch_bytes`), a larger file alone, each running :func:`hconv.tables.onefile.convert_one`
on a worker, while the driver (the process that called
:func:`~hconv.tables.dataset.convert_dataset`) collects the records and writes the manifest, as a
run in one process does. Dask (``distributed``, the ``hconv[dask]`` extra) is imported only here,
and only when a run asks for a cluster.

Where the files are
-------------------
A worker reads the input and writes the output itself, so both must be where every worker sees
them at the same path: object storage (the file system, with its endpoint, travels with each
task; credentials come from each worker's environment), or a directory every worker mounts at
the same path. Paths are absolute: a worker's working directory does not matter.

What a task may do twice, and what a killed worker leaves
---------------------------------------------------------
Dask runs a task again when the worker running it dies. A task writes nothing but its own output,
through a temporary file committed whole, so a second run writes the same bytes again: it may
replace an output at its own path (one the first run committed before it died), which the
manifest has claimed as hconv's own before any task started. A killed worker cannot remove its
temporary file, and its host may be another machine, where :func:`hconv.tables.temporaries.remove_stale_temporaries`
cannot tell that it died; so every temporary file of a run carries the run's tag in its name, and
the driver removes that run's leftovers in OUT, and each worker in its temporary directory, once
no task runs (:meth:`Session.close`).

Stopping
--------
On Ctrl-C the driver sets a Dask :class:`~distributed.Event` that every task checks between
batches (at most every :data:`STOP_CHECK_SECONDS`): a task not yet started returns at once, one
running removes its temporary file and stops. The driver waits for them (at most
:data:`STOP_WAIT_SECONDS`), records the files committed meanwhile, writes the manifest, and
removes the run's temporary files.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import re
import shutil
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator
from typing import Any

from hconv import errors
from hconv.errors import HconvError, OutputError, UsageError, first_line, option
from hconv.solve.engines import available_cores
from hconv.tables import temporaries
from hconv.tables.manifest import FileRecord, GroupCommit, make_durable
from hconv.tables.onefile import SMALL_FILE_BYTES, convert_one
from hconv.tables.parts import Part, PartRecord, convert_part, join_parts, remove_parts, split
from hconv.tables.pipeline import default_threads
from hconv.tables.planning import Plan, Task
from hconv.tables.storage import Place, remove_run_objects

EXTRA = "pip install 'dask[distributed]' (hconv's dask extra: pip install '.[dask]' in its clone)"
#: --cluster's values besides "local": the address of a running Dask scheduler.
_ADDRESS = re.compile(r"^(tcp|tls)://[^\s/:]+:\d+/?$")
#: How often a running task asks whether the run was stopped: each asking is a round trip to the
#: scheduler, so not every batch.
STOP_CHECK_SECONDS = 0.5
#: How long a stopped run waits for its running tasks to stop or finish (each stops at its next
#: batch) before it gives up on them.
STOP_WAIT_SECONDS = 30.0


def dask_installed() -> bool:
    return importlib.util.find_spec("distributed") is not None


def check(cluster: object, workers: object, timeout: object) -> None:
    """UsageError unless the cluster options make sense and Dask is installed; imports nothing."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise UsageError(f"{option('workers')} must be a whole number, 1 or more, got {workers!r}")
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not timeout > 0:
        raise UsageError(f"{option('cluster_timeout')} must be a number of seconds above 0, got {timeout!r}")
    if workers is not None and cluster is None:
        raise UsageError(f"{option('workers')} sets how many workers {option('cluster', 'local')} starts; add that")
    if workers is not None and cluster != "local":
        raise UsageError(
            f"{option('workers')} is for {option('cluster', 'local')}; a running scheduler has the workers "
            "started for it (dask worker ADDRESS starts one more)"
        )
    if isinstance(cluster, str):
        if cluster != "local" and not _ADDRESS.match(cluster):
            raise UsageError(
                f"{option('cluster')} must be local or a Dask scheduler's address such as tcp://HOST:8786, "
                f"got {cluster!r}"
            )
    elif cluster is None or not hasattr(cluster, "submit"):
        raise UsageError(f"{option('cluster')} must be 'local', a scheduler's address or a distributed.Client")
    if not dask_installed():
        raise UsageError(f"{option('cluster')} needs Dask: {EXTRA}")


@contextlib.contextmanager
def connect(cluster: object, workers: int | None, timeout: float, threads: int | None) -> Iterator[Session]:
    """A session on the cluster ``cluster`` (see :func:`check`), its workers' hconv checked;
    closed (and the run's temporary files removed) on the way out. ``threads``: batches each
    task converts at once (default: a worker's cores shared among the tasks it runs at once)."""
    import dask
    import distributed

    own: list[Any] = []  # what this session started, and so closes
    client: Any
    if isinstance(cluster, str) and cluster == "local":
        cores = available_cores()
        n = workers or cores
        # one file at a time per worker; its batches on the cores left to it
        threads = threads or max(1, cores // n)
        # The workers' scratch space in a folder of this run's, removed with it: Dask's default
        # (TMPDIR/dask-scratch-space) stayed behind after every run.
        scratch = _Scratch()
        with scratch.removed_on_error(), warnings.catch_warnings(), dask.config.set(temporary_directory=scratch.path):
            # "Port 8787 is already in use" and the like: hconv asks for no dashboard, and the
            # warning's four lines crowded out hconv's own output
            warnings.simplefilter("ignore", UserWarning)
            local = distributed.LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=40,
                local_directory=scratch.path,
            )
        own += [local, scratch]  # closed in this order: the workers first, then their folder
        client = distributed.Client(local, set_as_default=False)
        own.insert(0, client)
        where = "a local Dask cluster"
    elif isinstance(cluster, str):
        not_there = f"start one there (dask scheduler), give its address, or raise {option('cluster_timeout')}"
        _probe(cluster, timeout, not_there)
        try:
            client = distributed.Client(cluster, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            why = "" if "timed out" in str(exc).lower() else f" ({first_line(exc)})"
            raise UsageError(
                f"{option('cluster', cluster)}: no Dask scheduler answered within {timeout:g} s{why}; {not_there}"
            ) from None
        except Exception as exc:  # noqa: BLE001 - whatever a server that is not Dask's makes its client raise
            raise UsageError(
                f"{option('cluster', cluster)}: what answers there is not a Dask scheduler "
                f"({type(exc).__name__}: {first_line(exc)}); {not_there}"
            ) from None
        own.append(client)
        where = f"the Dask scheduler at {cluster}"
    else:
        client = cluster
        where = f"the Dask scheduler at {client.scheduler.address}"
    session = Session(client, where, threads)
    try:
        session.check_workers(timeout)
        yield session
    finally:
        session.close(own)


def _probe(address: str, timeout: float, fix: str) -> None:
    """UsageError unless a Dask scheduler may be at ``tcp://HOST:PORT``: something accepts a
    connection there within ``timeout`` and speaks first, as a Dask server does (it sends its
    handshake on accepting). Dask's client, connected to a server that waits for a request (an
    HTTP server: the dashboard's port 8787, a proxy), waits for ever whatever its timeout says,
    and Ctrl-C does not reach it. tls:// is left to Dask: there the client speaks first."""
    import socket

    scheme, _, rest = address.partition("://")
    if scheme != "tcp":
        return
    host, _, port = rest.rstrip("/").rpartition(":")
    given = option("cluster", address)
    deadline = time.monotonic() + timeout
    try:
        sock = socket.create_connection((host, int(port)), timeout=timeout)
    except TimeoutError:
        raise UsageError(f"{given}: no Dask scheduler answered within {timeout:g} s; {fix}") from None
    except ConnectionRefusedError:  # waiting longer would not help: the fix is the address
        raise UsageError(
            f"{given}: nothing listens there (connection refused); start a scheduler there (dask scheduler) "
            "or give the address of one"
        ) from None
    except OSError as exc:
        raise UsageError(f"{given}: no Dask scheduler answered ({first_line(exc)}); {fix}") from None
    with sock:
        try:
            sock.settimeout(max(0.1, deadline - time.monotonic()))
            first = sock.recv(8)
        except TimeoutError:
            raise UsageError(
                f"{given}: a server there accepted the connection but said nothing in {timeout:g} s; a "
                "Dask scheduler speaks at once (is this the dashboard's port? a scheduler listens on "
                f"8786 unless told otherwise); {fix}"
            ) from None
        except OSError as exc:
            why = first_line(exc)
            raise UsageError(f"{given}: what answers there is not a Dask scheduler ({why}); {fix}") from None
    if len(first) < 8 or first.startswith(b"HTTP"):
        raise UsageError(f"{given}: what answers there is not a Dask scheduler; {fix}")


class Session:
    """One run's use of a cluster: its tasks, its stop event and its temporary files' tag."""

    def __init__(self, client: Any, where: str, threads: int | None):
        self.client = client
        self.where = where
        self.threads = threads
        self.run_id = temporaries.new_run_tag()
        self.workers = 0
        self.addresses: set[str] = set()
        self.dst: Place | None = None
        self.futures: list[Any] = []
        self.split_files = 0  #: files split into parts (whose files the run removes at its end)
        self.parts = 0  #: the parts those files were split into

    def describe(self) -> str:
        return f"{self.where}, {self.workers} worker" + ("s" if self.workers != 1 else "")

    def describe_end(self) -> str:
        """:meth:`describe`, and how many of the workers the run started with are gone by its end
        (a worker that died: Dask ran its tasks again elsewhere)."""
        try:
            now = set(self.client.scheduler_info().get("workers", {}))
        except Exception:  # noqa: BLE001 - a scheduler lost at the end: nothing more to say
            return self.describe()
        lost = len(self.addresses - now)
        return self.describe() + (f" ({lost} lost during the run; their files were converted again)" if lost else "")

    def check_workers(self, timeout: float) -> None:
        """UsageError unless the cluster has a worker within ``timeout`` and each runs this hconv."""
        from hconv.version import __version__

        try:
            self.client.wait_for_workers(1, timeout=timeout)
        except (OSError, TimeoutError):
            raise UsageError(
                f"{self.where} has no worker after {timeout:g} s; start one (dask worker ADDRESS)"
            ) from None
        found = self.client.run(_prepare_worker, on_error="return")
        wrong = {w: v for w, v in found.items() if v != __version__}
        if wrong:
            worker, v = sorted(wrong.items())[0]
            has = f"runs hconv {v}" if isinstance(v, str) else f"cannot run hconv ({first_line(v)})"
            raise UsageError(
                f"{self.where}: worker {worker} {has} (this is hconv {__version__})"
                f"{f' and {len(wrong) - 1} others too' if len(wrong) > 1 else ''}; "
                f"install hconv {__version__} with its dask extra on every worker"
            )
        self.workers = len(found)
        self.addresses = set(found)

    def run(
        self, plan: Plan, commit: GroupCommit, *, strict: bool, task_rows: int
    ) -> Iterator[tuple[Task, HconvError | None]]:
        """Submit the files to convert as tasks: small files packed together into tasks of about
        :func:`batch_bytes` each, a larger file alone, or for a large Parquet file one task per
        part and one joining them (:func:`hconv.tables.parts.split`, ``task_rows``); (task, its
        error or None) for each file as its task completes, its record handed to ``commit``
        first (durable already: the worker flushed its task's outputs). KeyboardInterrupt stops
        the tasks (see the module)."""
        import distributed

        self.dst = plan.dst
        stop = distributed.Event(f"hconv-stop-{self.run_id}", client=self.client)
        args = (
            plan.src.place,
            plan.dst,
            plan.job,
            strict,
            self.threads,
            self.run_id,
            stop.name,
            errors.on_command_line(),
        )
        by_key: dict[str, list[Task]] = {}
        files = []  # the futures whose results are files' records: a batch's, a join's
        limit = batch_bytes(plan.todo, self.workers)
        for k, group in enumerate(_batches(plan.todo, limit)):
            key = f"hconv-{self.run_id}-{k}"
            by_key[key] = group
            parts = split(group[0], plan.src.place, task_rows, self.run_id) if len(group) == 1 else []
            if not parts:
                files.append(self.client.submit(_convert_on_worker, group, *args, key=key, pure=False))
                continue
            task = group[0]
            self.split_files += 1
            self.parts += len(parts)
            done = [
                self.client.submit(_convert_on_worker, [task], *args, part=p, key=f"{key}-part-{p.k}", pure=False)
                for p in parts
            ]
            self.futures += done
            files.append(
                self.client.submit(
                    _join_on_worker,
                    task,
                    parts,
                    done,
                    plan.dst,
                    self.run_id,
                    errors.on_command_line(),
                    key=key,
                    pure=False,
                )
            )
        self.futures += files
        handled = set()
        try:
            for future in distributed.as_completed(files, loop=self.client.loop):
                group = by_key[future.key]
                outcomes = self._outcomes(future, group, commit)
                handled.add(future.key)
                yield from zip(group, outcomes)
        except KeyboardInterrupt:
            stop.set()
            # every task not handled yet, including those done but still queued in as_completed
            waiting = [f for f in files if f.key not in handled]
            with contextlib.suppress(Exception):  # a worker stops, finishes, or is lost: all fine now
                for future in distributed.as_completed(waiting, timeout=STOP_WAIT_SECONDS, loop=self.client.loop):
                    self._outcomes(future, by_key[future.key], commit)
            raise

    @staticmethod
    def _outcomes(future: Any, group: list[Task], commit: GroupCommit) -> list[HconvError | None]:
        """Each file's outcome of a finished task, its record handed to ``commit``."""
        try:
            got = future.result()
        except HconvError as exc:
            return [exc] * len(group)
        except Exception as exc:  # noqa: BLE001 - Dask's own failures: a worker lost too often (KilledWorker)
            if type(exc).__name__ != "KilledWorker":
                raise
            return [
                OutputError(
                    f"{task.input.rel}: not converted: the workers running it died, {first_line(exc)}; "
                    "it may need more memory than a worker has"
                )
                for task in group
            ]
        results = got if isinstance(got, list) else [got]
        outcomes: list[HconvError | None] = []
        for result in results:
            if isinstance(result, FileRecord):
                commit.add(result, None)
                outcomes.append(None)
            else:
                outcomes.append(result)  # an HconvError, or None: stopped before it was done
        return outcomes

    def close(self, own: list[Any]) -> None:
        """Cancel what still waits, close what this session started, and remove the run's
        temporary files: in OUT (local), and in each worker's temporary directory."""
        if self.futures:
            with contextlib.suppress(Exception):
                self.client.cancel(self.futures)
        with contextlib.suppress(Exception):  # a worker gone, or a scheduler lost: nothing to sweep there
            self.client.run(_remove_run_temporaries, self.run_id, on_error="return")
        for thing in own:
            with contextlib.suppress(Exception):
                thing.close()
        # after the close, so that no task of a local cluster still writes
        _remove_run_temporaries(self.run_id)
        if self.dst is not None and self.dst.local:
            temporaries.remove_run_temporaries(self.dst.root, self.run_id, recursive=True)
        elif self.dst is not None and self.split_files:  # the parts a killed worker or a stopped run left in OUT
            with contextlib.suppress(HconvError):
                remove_run_objects(self.dst, self.run_id)


class _Scratch:
    """A local cluster's scratch folder, removed when closed."""

    def __init__(self) -> None:
        self.path = tempfile.mkdtemp(prefix="hconv-dask-")

    @contextlib.contextmanager
    def removed_on_error(self) -> Iterator[None]:
        try:
            yield
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        shutil.rmtree(self.path, ignore_errors=True)


#: Small files are packed into tasks of at least this many bytes in all (fewer where the dataset
#: is too small to give each worker several tasks), so that a task pays for its scheduling
#: (docs/scaling.md measures a task's cost against a small file's).
TASK_BYTES = 64 << 20
#: Tasks per worker that a dataset of small files is cut into at least, so that the last tasks
#: finish together.
TASKS_PER_WORKER = 4


def batch_bytes(tasks: list[Task], workers: int) -> int:
    """The bytes of input a task of small files carries: :data:`TASK_BYTES`, or less, so that the
    dataset makes :data:`TASKS_PER_WORKER` tasks per worker."""
    total = sum(t.input.size for t in tasks)
    return max(1, min(TASK_BYTES, total // max(1, TASKS_PER_WORKER * workers)))


def _batches(tasks: list[Task], limit: int) -> Iterator[list[Task]]:
    """``tasks`` in their order, packed into groups of about ``limit`` bytes of input; a file of
    ``limit`` bytes or more is a group alone (it may be split into parts)."""
    group: list[Task] = []
    size = 0
    for task in tasks:
        if task.input.size >= limit:
            if group:
                yield group
                group, size = [], 0
            yield [task]
            continue
        group.append(task)
        size += task.input.size
        if size >= limit:
            yield group
            group, size = [], 0
    if group:
        yield group


def _prepare_worker() -> str:
    """On a worker: its allocator tuned as the hconv command's is (without it, block temporaries
    are faulted in anew for every block: hconv.kernels.allocator); its hconv version."""
    from hconv.kernels import allocator
    from hconv.version import __version__

    allocator.tune()
    return __version__


def _remove_run_temporaries(run_id: str) -> list[str]:
    return temporaries.remove_run_temporaries(tempfile.gettempdir(), run_id)


class _StopRequestedError(Exception):
    """The run was stopped: raised between batches, so that the conversion cleans up."""


def _convert_on_worker(
    tasks: list[Task],
    src: Place,
    dst: Place,
    job: Any,
    strict: bool,
    threads: int | None,
    run_id: str,
    stop_name: str,
    cli: bool,
    part: Part | None = None,
) -> list[FileRecord | HconvError | None] | PartRecord | HconvError | None:
    """A task's files, or one ``part`` of its one file, on a worker. For files: each one's record
    or error (returned, not raised, so that Dask keeps no traceback for a file hconv names), or
    None where the run was stopped first; the outputs flushed to the disk together before the
    task returns (:func:`hconv.tables.manifest.make_durable`). For a part: its record, error or None."""
    import distributed

    stop = distributed.Event(stop_name)
    asked = [time.monotonic()]

    def check(done: int = 0, total: int | None = None) -> None:
        if time.monotonic() - asked[0] >= STOP_CHECK_SECONDS:
            asked[0] = time.monotonic()
            if stop.is_set():
                raise _StopRequestedError

    if stop.is_set():
        return None if part is not None else [None] * len(tasks)
    if threads is None:  # the worker's cores, shared among the tasks it runs at once
        threads = max(1, default_threads() // max(1, distributed.get_worker().state.nthreads))
    with errors.command_line() if cli else contextlib.nullcontext():
        if part is not None:
            # the task may be a second run of one whose worker died after committing: see the module
            task = dataclasses.replace(tasks[0], overwrite=True)
            try:
                return convert_part(
                    task, part, src, dst, job, strict=strict, threads=threads, progress=check, run=run_id
                )
            except HconvError as exc:
                return exc
            except _StopRequestedError:
                return None
        with temporaries.sweeping_once():
            return _convert_files(tasks, src, dst, job, strict, threads, run_id, check)


def _convert_files(
    tasks: list[Task],
    src: Place,
    dst: Place,
    job: Any,
    strict: bool,
    threads: int,
    run_id: str,
    check: Callable[..., None],
) -> list[FileRecord | HconvError | None]:
    """:func:`_convert_on_worker`'s files, one after another; ``check`` raises
    :class:`_StopRequestedError` once the run is stopped."""
    results: list[FileRecord | HconvError | None] = []
    flushing: list[tuple[int, str]] = []  # (place in results, output) of the outputs to flush
    for task in tasks:
        task = dataclasses.replace(task, overwrite=True)  # as for a part
        small = task.input.size < SMALL_FILE_BYTES
        try:
            check()
            record = convert_one(
                task, src, dst, job, strict=strict, threads=1 if small else threads, progress=check,
                run=run_id, flush=not small, whole=small,
            )  # fmt: skip
        except HconvError as exc:
            results.append(exc)
            continue
        except _StopRequestedError:
            results += [None] * (len(tasks) - len(results))
            break
        if small and dst.local:
            flushing.append((len(results), dst.path(task.output)))
        results.append(record)
    try:
        make_durable([path for _, path in flushing])
    except HconvError as exc:  # not durable: not listed, converted again by the next run
        for k, _ in flushing:
            results[k] = exc
    return results


def _join_on_worker(
    task: Task, parts: list[Part], done: list[PartRecord | HconvError | None], dst: Place, run_id: str, cli: bool
) -> FileRecord | HconvError | None:
    """A split file's parts joined into its output, on a worker, once every part is done: its
    record; else (a part failed, or the run was stopped) the parts removed, and the first part's
    error or None."""
    task = dataclasses.replace(task, overwrite=True)  # as _convert_on_worker's
    failed = [r for r in done if not isinstance(r, PartRecord)]
    with errors.command_line() if cli else contextlib.nullcontext():
        try:
            if failed:
                remove_parts(parts, dst)
                return next((r for r in failed if r is not None), None)  # an error; else stopped
            return join_parts(task, parts, [r for r in done if isinstance(r, PartRecord)], dst, run=run_id)
        except HconvError as exc:
            return exc
