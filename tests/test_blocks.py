"""The numpy engine's blocks (hconv.solve.blocks): shared among threads with the same bits as on
one, on the main thread only, and stopped at a block that fails."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from helpers import physical_bodies, same_bits

import hconv
from hconv.solve import blocks


def test_convert_blocks_threads_give_the_same_bits(rng, monkeypatch):
    monkeypatch.setattr(blocks, "THREADED_BLOCK_ROWS", 1000)
    n = 3 * blocks.THREADED_BLOCK_ROWS + 17
    I, H = physical_bodies(rng, n), rng.normal(size=(n, 3))
    I[5, 0, 0] = np.nan  # a row for the general converter inside a threaded block
    monkeypatch.setattr(blocks.engines, "available_cores", lambda: 2)
    assert blocks.block_threads(4) == 2
    both = hconv.convert(H, I, method="refined", engine="numpy")
    monkeypatch.setattr(blocks, "MAX_BLOCK_THREADS", 1)
    one = hconv.convert(H, I, method="refined", engine="numpy")
    for a, b in [
        (both.w, one.w),
        (both.cond, one.cond),
        (both.status_code, one.status_code),
        (both.residual, one.residual),
    ]:
        assert same_bits(a, b)
    assert both.status[5] == "invalid_input" and (both.status == "ok").mean() > 0.99


def test_block_threads_one_off_the_main_thread(monkeypatch):
    monkeypatch.setattr(blocks.engines, "available_cores", lambda: 8)
    assert blocks.block_threads(1) == 1
    assert blocks.block_threads(100) == blocks.MAX_BLOCK_THREADS
    seen = []
    t = threading.Thread(target=lambda: seen.append(blocks.block_threads(100)))
    t.start()
    t.join()
    assert seen == [1]


def test_convert_blocks_stop_at_a_block_that_fails(rng, monkeypatch):
    """An exception in one block (Ctrl-C arrives as one) stops the call: the blocks not yet
    started never start."""
    monkeypatch.setattr(blocks, "THREADED_BLOCK_ROWS", 1000)
    n = 200 * blocks.THREADED_BLOCK_ROWS
    I, H = physical_bodies(rng, 2)[np.zeros(n, int)], np.ones((n, 3))
    monkeypatch.setattr(blocks.engines, "available_cores", lambda: 2)
    calls = []
    real = blocks._convert_block

    def failing(*args: object) -> None:
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        real(*args)

    monkeypatch.setattr(blocks, "_convert_block", failing)
    with pytest.raises(KeyboardInterrupt):
        hconv.convert(H, I, engine="numpy")
    # the other thread may finish a few blocks before the main thread sees the failure, not all
    assert 3 <= len(calls) < 100
