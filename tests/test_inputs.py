"""hconv.tables.inputs: the loop every reader takes its batches by (read_batches). The readers'
own messages, through it, are tested with their files in test_tableio.py, test_csvio.py,
test_ipcio.py and test_jsonio.py."""

from __future__ import annotations

import os

import pyarrow as pa
import pytest

from hconv.errors import InputError
from hconv.tables.inputs import FileStat, read_batches

BATCH = pa.record_batch({"x": pa.nulls(2, pa.float64())})


def _failed(exc: Exception) -> InputError:
    return InputError(f"in.bin: batch 2 cannot be read ({type(exc).__name__})")


def _reader(*steps):
    """Batches, and an exception raised, or a callable called, between them."""
    for step in steps:
        if isinstance(step, BaseException):
            raise step
        if callable(step):
            step()
        else:
            yield step


@pytest.fixture
def opened(tmp_path):
    path = tmp_path / "in.bin"
    path.write_bytes(b"abc")
    fd = os.open(path, os.O_RDONLY)
    yield path, fd, FileStat.of(fd)
    os.close(fd)


def test_read_batches_a_readers_error_is_named_by_failed(opened):
    _, fd, at_open = opened
    got = read_batches(_reader(BATCH, pa.ArrowInvalid("bad page")), "in.bin", fd, at_open, _failed)
    assert next(got) is BATCH
    with pytest.raises(InputError, match=r"^in\.bin: batch 2 cannot be read \(ArrowInvalid\)$") as caught:
        next(got)
    assert caught.value.__suppress_context__  # one line: pyarrow's traceback is not chained


def test_read_batches_an_error_not_the_readers_passes_as_it_is(opened):
    _, fd, at_open = opened
    got = read_batches(_reader(KeyError("k")), "in.bin", fd, at_open, _failed, (OSError, pa.ArrowException))
    with pytest.raises(KeyError):
        next(got)


@pytest.mark.parametrize("why, said", [(True, "from 3 to 6 bytes; bad page\\)"), (False, "from 3 to 6 bytes\\)")])
def test_read_batches_a_file_changed_before_an_error_is_named_changed(opened, why, said):
    path, fd, at_open = opened

    def append() -> None:
        with open(path, "ab") as f:
            f.write(b"def")

    got = read_batches(_reader(append, pa.ArrowInvalid("bad page\nmore")), "in.bin", fd, at_open, _failed, why=why)
    with pytest.raises(InputError, match=r"^in\.bin: changed while hconv read it \(" + said):
        next(got)


def test_read_batches_a_file_changed_by_the_readers_end_is_refused(opened):
    path, fd, at_open = opened
    got = read_batches(_reader(BATCH, lambda: path.write_bytes(b"ab"), BATCH), "in.bin", fd, at_open, _failed)
    assert [next(got), next(got)] == [BATCH, BATCH]
    with pytest.raises(InputError, match=r"changed while hconv read it \(from 3 to 2 bytes\)"):
        next(got)


def test_read_batches_an_unchanged_file_gives_every_batch(opened):
    _, fd, at_open = opened
    assert list(read_batches(_reader(BATCH, BATCH, BATCH), "in.bin", fd, at_open, _failed)) == [BATCH] * 3
