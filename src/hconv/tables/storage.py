"""Where a dataset's files live: a local directory, or a prefix on object storage (``s3://``,
``gs://``, ``abfs://``, ``hdfs://``, ``file://``) through pyarrow's file systems, or through
fsspec's for a scheme pyarrow has none for, when fsspec and that scheme's package are installed.

What is atomic where
--------------------
Locally, every file is written to a temporary file beside it and renamed into place
(:class:`hconv.tables.output.Output`); a rename within a directory is atomic.

Object storage has no rename, and needs none: S3, GCS and Azure make an object visible only once
its upload is complete (a PUT, or the CompleteMultipartUpload that ends a multipart upload), and
a reader then sees the previous object or the new one whole, never a part. What must never happen
is completing the upload of a part of a file, and pyarrow's output stream completes its upload
whenever it is closed, even by its destructor after an error or an interrupt. So hconv never
streams a conversion to object storage: it converts into a local temporary file and, once that
file is complete, copies it to its key in one call into pyarrow's C++ (:func:`put`). Python runs
a Ctrl-C or SIGTERM handler only between bytecodes, so an interrupt waits for that call to
return (one file's upload) and never lands between its writes. An upload that fails is never
completed: S3 does not assemble an object from a multipart upload whose part failed, and a small
file is sent whole in one PUT when its stream closes. A process killed mid-upload can leave an
incomplete multipart upload, which no reader sees (a bucket lifecycle rule,
AbortIncompleteMultipartUpload, removes its parts), but never a partial object and never a
temporary key. Inputs on object storage are fetched into a local temporary file first
(:func:`fetch`), since the readers seek and may read a CSV twice.

Credentials come as the file system's own SDK finds them (for S3: ``AWS_ACCESS_KEY_ID``,
``AWS_SECRET_ACCESS_KEY``, ``AWS_SESSION_TOKEN``, ``~/.aws``, an instance role). pyarrow 26 does
not read ``AWS_ENDPOINT_URL``, so hconv does: the endpoint of an S3-compatible server is
``endpoint_url``, else ``AWS_ENDPOINT_URL_S3``, else ``AWS_ENDPOINT_URL``, as the AWS CLI and
boto3 take it.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.fs as pafs

from hconv.errors import InputError, OutputError, UsageError, first_line, option
from hconv.tables import temporaries
from hconv.tables.formats import EXTENSIONS, choices, listing

_URI = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*)://")
GLOB_CHARS = "*?["
#: Reads from object storage go through a buffer this size: each read of pyarrow's S3 file is a
#: request, so 1 MiB reads would be a request per MiB.
FETCH_BUFFER = 8 << 20
_LOCAL = pafs.LocalFileSystem()
DIRECTORY = pafs.FileType.Directory


def is_uri(spec: str) -> bool:
    """Whether ``spec`` is a URI (``scheme://...``) rather than a local path."""
    return bool(_URI.match(spec))


def has_glob(spec: str) -> bool:
    return any(c in spec for c in GLOB_CHARS)


def format_by_name(name: str) -> str | None:
    """The format a file name's extension implies, or None."""
    suffix = Path(name).suffix.lower()
    return next((f for f, exts in EXTENSIONS.items() if suffix in exts), None)


def hidden(rel: str) -> bool:
    """Whether a path inside a dataset is left out of it: any part starting with ``.`` or ``_``,
    as pyarrow, Spark and Hive leave out ``_SUCCESS``, ``_temporary/``, ``.crc`` files, hconv's own
    temporary files and its manifest."""
    return any(part.startswith((".", "_")) for part in rel.split("/"))


@dataclass(frozen=True)
class Listed:
    """A file of a dataset: its path relative to the dataset's root, its size and its
    modification time (nanoseconds; object stores give whole seconds), as listed."""

    rel: str
    size: int
    mtime_ns: int | None


@dataclass(frozen=True)
class Place:
    """A directory or prefix: its file system, its path there, and how the user wrote it."""

    fs: Any  #: a pyarrow.fs.FileSystem
    root: str  #: the directory or prefix in ``fs``, without a trailing '/'
    shown: str  #: as the user wrote it, without a trailing '/': messages, and local paths
    local: bool  #: on this machine's file system (written with temporary files and renames)

    def path(self, rel: str) -> str:
        """``rel``'s path in :attr:`fs`."""
        return f"{self.root}/{rel}" if self.root else rel

    def name(self, rel: str) -> str:
        """``rel`` as messages name it, and as a local path relative to the working directory."""
        return f"{self.shown}/{rel}" if self.shown else rel

    @property
    def identity(self) -> str:
        """The place however it was written: ``file://`` and an absolute path, or the URI."""
        return f"file://{self.root}" if self.local else f"{self.fs.type_name}://{self.root}"

    @property
    def resolved(self) -> str:
        """Where the place is: :attr:`identity` with a local path's links resolved (the part that
        exists), so that ``dslink/sub``, with ``dslink`` a link to ``ds``, is inside ``ds``."""
        return f"file://{os.path.realpath(self.root)}" if self.local else self.identity

    def contains(self, other: Place) -> bool:
        """Whether ``other`` is this place or inside it, however links name them."""
        return inside(other.resolved, self.resolved)

    def list(self, error: type[InputError] | type[OutputError] = InputError) -> list[Listed]:
        """Every file under this place, recursively; none if it does not exist. ``error``: what a
        failure to list it raises (OutputError for OUT)."""
        try:
            infos = self.fs.get_file_info(pafs.FileSelector(self.root, recursive=True, allow_not_found=True))
        except OSError as exc:
            raise error(f"{self.shown}: cannot list it {store_failure(exc)}") from None
        cut = len(self.root) + 1 if self.root else 0
        return sorted(
            (Listed(i.path[cut:], i.size, i.mtime_ns) for i in infos if i.type == pafs.FileType.File),
            key=lambda f: f.rel,
        )


def inside(path: str, folder: str) -> bool:
    """Whether ``path`` is ``folder`` or inside it (both absolute, written alike)."""
    return path == folder or path.startswith(folder.rstrip("/") + "/")


#: What object stores say (pyarrow's S3 error names, and the services' own codes) when a request
#: lacks or has wrong credentials, or names a bucket that is not there; the rest of their text
#: buries the cause.
_DENIED = ("ACCESS_DENIED", "AccessDenied", "InvalidAccessKeyId", "SignatureDoesNotMatch", "No credentials")
_NO_BUCKET = ("NO_SUCH_BUCKET", "NoSuchBucket")


def store_failure(exc: BaseException) -> str:
    """``(the error's first line)``, and what to do where the cause is a common one."""
    text = first_line(exc)
    if any(k in text for k in _NO_BUCKET):
        return f"({text}); the bucket does not exist: create it, or check the URI"
    if any(k in text for k in _DENIED):
        return (
            f"({text}); the store refused the credentials: check AWS_ACCESS_KEY_ID and "
            f"AWS_SECRET_ACCESS_KEY (or AWS_PROFILE), and with {option('cluster')} each worker's too"
        )
    return f"({text})"


def endpoint(endpoint_url: str | None) -> str | None:
    """The S3 endpoint to use: the one given, else AWS_ENDPOINT_URL_S3, else AWS_ENDPOINT_URL."""
    return endpoint_url or os.environ.get("AWS_ENDPOINT_URL_S3") or os.environ.get("AWS_ENDPOINT_URL") or None


def filesystem(uri: str, endpoint_url: str | None = None) -> tuple[Any, str]:
    """(pyarrow file system, path in it) for ``uri``."""
    scheme = _URI.match(uri).group(1).lower()  # type: ignore[union-attr]
    if scheme == "s3":
        url = endpoint(endpoint_url)
        if url:  # pyarrow would send a request to AWS to find the bucket's region first
            rest = uri.split("://", 1)[1].split("?", 1)[0]
            region = os.environ.get("AWS_REGION") or os.environ.get("AWS_DEFAULT_REGION") or "us-east-1"
            return pafs.S3FileSystem(endpoint_override=url, region=region), rest.rstrip("/")
    elif endpoint_url:
        raise UsageError(f"{option('endpoint_url')} is for s3:// URIs, not {scheme}://")
    try:
        fs, path = pafs.FileSystem.from_uri(uri)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as exc:
        if "scheme" not in str(exc).lower() and "not supported" not in str(exc).lower():
            raise UsageError(f"{uri}: not a URI hconv can read {store_failure(exc)}") from None
        return _fsspec(uri, scheme)
    except OSError as exc:
        raise UsageError(f"{uri}: {first_line(exc)}") from None
    return fs, path.rstrip("/")


def _fsspec(uri: str, scheme: str) -> tuple[Any, str]:
    try:
        import fsspec
    except ImportError:
        raise UsageError(
            f"{uri}: pyarrow has no file system for {scheme}://; install fsspec and the package for {scheme}:// "
            "(pip install fsspec ...), or use s3://, gs://, abfs://, hdfs:// or a local path"
        ) from None
    try:
        fs, path = fsspec.core.url_to_fs(uri)
    except (ImportError, ValueError) as exc:
        raise UsageError(f"{uri}: fsspec cannot open {scheme}:// {store_failure(exc)}") from None
    return pafs.PyFileSystem(pafs.FSSpecHandler(fs)), str(path).rstrip("/")


def place(spec: str, endpoint_url: str | None = None) -> Place:
    """The directory or prefix ``spec`` (a local path or a URI)."""
    if is_uri(spec):
        fs, root = filesystem(spec, endpoint_url)
        local = isinstance(fs, pafs.LocalFileSystem)
        return Place(fs, root, spec.rstrip("/"), local)
    shown = spec.rstrip("/") if spec.rstrip("/") else spec
    return Place(_LOCAL, os.path.abspath(spec), shown, True)


@dataclass(frozen=True)
class Source:
    """A dataset's input: a place, and which of its files (a glob relative to it, or every file)."""

    place: Place
    pattern: str | None  #: a glob relative to the place; None: every file under it
    spec: str  #: as the user wrote it

    def files(self, src_format: str | None) -> list[Listed]:
        """The dataset's files, in order of their relative paths: those the pattern matches,
        hidden ones left out (:func:`hidden`), of a format hconv reads unless ``src_format`` says
        what they are. InputError when there are none."""
        match = glob_regex(self.pattern).match if self.pattern is not None else None
        listed = self.place.list()
        if not listed and not self.place.local and self.pattern is None:
            info = self.place.fs.get_file_info(self.place.root)
            if info.type == pafs.FileType.NotFound:
                raise InputError(f"{self.spec}: does not exist; check the URI")
        found = [f for f in listed if not hidden(f.rel) and (match is None or match(f.rel))]
        readable = [f for f in found if src_format or format_by_name(f.rel)]
        if not readable:
            what = f"no file matches {self.spec!r}" if self.pattern is not None else f"{self.spec}: holds no file"
            if found:
                raise InputError(
                    f"{what} with a name of a format hconv reads, {listing()} ({len(found)} others, such as "
                    f"{found[0].rel}); pass {option('src_format', 'FORMAT')} ({choices()}) to read them as one"
                )
            raise InputError(f"{what} (names starting with . or _ are left out); check the path")
        return readable


def source(spec: str, endpoint_url: str | None = None) -> Source:
    """The input ``spec``: a directory, a glob (``data/date=*/*.parquet``, ``**`` for any depth),
    a URI of a prefix or of a glob, or one file."""
    parts = spec.split("/")
    k = next((i for i, p in enumerate(parts) if has_glob(p)), None)
    uri = is_uri(spec)
    if k is not None and (uri or not os.path.exists(spec)):
        base = "/".join(parts[:k])
        if uri and base.endswith(":/"):  # s3://*...: a glob over buckets
            raise UsageError(f"{spec}: give a bucket before the glob, e.g. s3://bucket/data/*.parquet")
        return Source(place(base or ".", endpoint_url), "/".join(parts[k:]), spec)
    where = place(spec, endpoint_url)
    if where.local:
        if os.path.isfile(where.root):
            return Source(_parent(where), glob_escape(os.path.basename(where.root)), spec)
        if not os.path.isdir(where.root):
            raise InputError(f"{spec}: does not exist; check the path")
    else:
        try:
            info = where.fs.get_file_info(where.root)
        except OSError as exc:
            raise InputError(f"{spec}: cannot read it {store_failure(exc)}") from None
        if info.type == pafs.FileType.File:
            return Source(_parent(where), glob_escape(where.root.rsplit("/", 1)[-1]), spec)
    return Source(where, None, spec)


def _parent(p: Place) -> Place:
    root, shown = p.root.rsplit("/", 1)[0], p.shown.rsplit("/", 1)
    return Place(p.fs, root, shown[0] if len(shown) > 1 else ".", p.local)


def glob_escape(name: str) -> str:
    return re.sub(r"([*?\[])", r"[\1]", name)


def glob_regex(pattern: str) -> re.Pattern:
    """A glob as a regular expression over relative paths: ``*`` and ``?`` stay inside a folder
    name, ``**`` crosses folders (``**/`` also matches no folder), ``[...]`` a character class."""
    out, i = [], 0
    while i < len(pattern):
        c = pattern[i]
        if pattern.startswith("**/", i):
            out.append("(?:[^/]*/)*")
            i += 3
        elif pattern.startswith("**", i):
            out.append(".*")
            i += 2
        elif c == "*":
            out.append("[^/]*")
            i += 1
        elif c == "?":
            out.append("[^/]")
            i += 1
        elif c == "[":
            j = i + 1
            if j < len(pattern) and pattern[j] == "!":
                j += 1
            j = pattern.find("]", j + 1)  # a ']' first in the class is part of it
            if j < 0:
                out.append(re.escape(c))
                i += 1
                continue
            body = pattern[i + 1 : j]
            body = "^" + body[1:] if body.startswith("!") else body
            out.append("[" + body.replace("\\", "\\\\") + "]")
            i = j + 1
        else:
            out.append(re.escape(c))
            i += 1
    return re.compile("".join(out) + r"\Z")


def fetch(where: Place, rel: str, path: str) -> str | None:
    """Copy ``rel`` from object storage into the local file ``path`` (made by :func:`stage`);
    returns the object's ETag, if the store gives one."""
    name = where.name(rel)
    try:
        stream = where.fs.open_input_stream(where.path(rel), buffer_size=FETCH_BUFFER)
    except OSError as exc:
        raise InputError(f"{name}: cannot read it {store_failure(exc)}") from None
    with stream, open(path, "wb") as f:
        try:
            meta = stream.metadata() or {}
        except (OSError, NotImplementedError, pa.ArrowNotImplementedError):
            meta = {}
        while True:
            try:
                chunk = stream.read(FETCH_BUFFER)
            except OSError as exc:
                raise InputError(f"{name}: cannot read it {store_failure(exc)}") from None
            if not chunk:
                break
            try:
                f.write(chunk)
            except OSError as exc:
                raise OutputError(
                    f"{name}: could not be copied to a temporary file in {os.path.dirname(path)!r} "
                    f"({exc.strerror or exc}); set TMPDIR to a directory with room"
                ) from None
    etag = meta.get(b"ETag") or meta.get("ETag")
    return etag.decode() if isinstance(etag, bytes) else etag


def stage(beside: str | None = None, kind: str = "stage", run: str | None = None) -> str:
    """An empty temporary file: to convert into before the output is committed, beside the local
    output ``beside`` (renamed over it) or in the temporary directory (for :func:`put`); or, with
    ``kind="fetch"``, to :func:`fetch` an input into. ``run``: the tag of a run on a cluster, in
    the name, so that the run can remove what its killed workers left
    (:func:`hconv.tables.temporaries.remove_run_temporaries`). The caller removes it."""
    if beside is None:
        fd, path = temporaries.temporary_file(temporaries.run_prefix(f"hconv-{kind}-", run))
    else:
        # the name cut, as the one-file writer cuts it: with the run's tag, the maker and the
        # suffix, a long output name (or a part's, itself a long name) passed 255 bytes
        name = os.fsdecode(os.fsencode(os.path.basename(beside))[:120])
        prefix = temporaries.run_prefix(f".{name}.", run)
        fd, path = temporaries.temporary_file(prefix, os.path.dirname(beside) or ".")
    os.close(fd)
    return path


def put(local_path: str, where: Place, rel: str) -> int:
    """Copy the complete local file ``local_path`` to ``rel`` under the object-storage place
    ``where``, atomically for readers (see the module's docstring); returns its size."""
    name, target = where.name(rel), where.path(rel)
    size = os.path.getsize(local_path)
    try:
        pafs.copy_files(
            os.path.abspath(local_path),
            target,
            source_filesystem=_LOCAL,
            destination_filesystem=where.fs,
            chunk_size=FETCH_BUFFER,
            # on this thread: an fsspec store is Python, which a pyarrow thread still running
            # as the interpreter exits after an error would call into, and abort the process
            use_threads=False,
        )
        stored = where.fs.get_file_info(target).size
    except OSError as exc:
        raise OutputError(f"{name}: could not be written {store_failure(exc)}; it was left as it was") from None
    if stored != size:
        raise OutputError(f"{name}: holds {stored} bytes after the upload of {size}; run again to write it anew")
    return size


def exists(where: Place, rel: str) -> bool:
    """Whether the file ``rel`` is under ``where``."""
    if where.local:
        return os.path.isfile(where.path(rel))
    return file_info(where, rel).type == pafs.FileType.File


def file_info(where: Place, rel: str) -> Any:
    """The pyarrow FileInfo of ``rel`` under the output place ``where``; OutputError naming it
    when the store cannot say (refused, unreachable)."""
    try:
        return where.fs.get_file_info(where.path(rel) if rel else where.root)
    except OSError as exc:
        raise OutputError(f"{where.name(rel) if rel else where.shown}: cannot reach it {store_failure(exc)}") from None


def remove(where: Place, rel: str) -> None:
    """Remove the file ``rel`` under ``where`` if it is there."""
    try:
        if where.local:
            os.unlink(where.path(rel))
        else:
            where.fs.delete_file(where.path(rel))
    except FileNotFoundError:
        pass
    except OSError as exc:
        if exists(where, rel):
            raise OutputError(f"{where.name(rel)}: could not be removed {store_failure(exc)}") from None


def remove_run_objects(where: Place, run: str) -> list[str]:
    """Remove the temporary objects (parts) of the run ``run`` under the object-storage place
    ``where``: :func:`hconv.tables.temporaries.remove_run_temporaries` for a prefix; their names."""
    gone = []
    for f in where.list():
        if temporaries.is_run_temporary(f.rel.rsplit("/", 1)[-1], run):
            remove(where, f.rel)
            gone.append(f.rel)
    return gone


def write_bytes(where: Place, rel: str, data: bytes) -> None:
    """Write a small file (the manifest) whole: locally through a temporary file, flushed to the
    disk and renamed; on object storage in one upload."""
    if where.local:
        target = where.path(rel)
        tmp = ""
        try:
            os.makedirs(os.path.dirname(target), exist_ok=True)
            fd, tmp = temporaries.temporary_file(f".{os.path.basename(target)}.", os.path.dirname(target))
            with os.fdopen(fd, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            os.chmod(tmp, 0o666 & ~temporaries.umask())
            os.replace(tmp, target)
        except OSError as exc:
            raise OutputError(f"{where.name(rel)}: could not be written ({exc.strerror or exc})") from None
        finally:
            if tmp and os.path.exists(tmp):
                os.unlink(tmp)
        return
    staged = ""
    try:
        staged = stage()
        with open(staged, "wb") as f:
            f.write(data)
        put(staged, where, rel)
    finally:
        if staged:
            os.unlink(staged)


def read_bytes(where: Place, rel: str) -> bytes | None:
    """A small file's bytes, or None if it does not exist."""
    try:
        if where.local:
            with open(where.path(rel), "rb") as f:
                return f.read()
        with where.fs.open_input_stream(where.path(rel)) as f:
            return bytes(f.read())
    except FileNotFoundError:
        return None
    except OSError as exc:
        if not where.local and file_info(where, rel).type == pafs.FileType.NotFound:
            return None
        raise OutputError(f"{where.name(rel)}: cannot read it {store_failure(exc)}") from None
