"""``hconv generate``: synthetic scenes of analytic bodies (:mod:`hconv.tools.scene`) written to a
file or stdout through the same atomic, background writer as ``convert``."""

from __future__ import annotations

import time

import pyarrow as pa

from hconv.errors import UsageError, option
from hconv.tables.output import Output
from hconv.tables.pipeline import BackgroundWriter
from hconv.tables.sniff import format_of
from hconv.tools.scene import check_scene, iter_scene, make_scene


def generate_file(
    dst: str,
    rows: int,
    *,
    scene: str = "mix",
    cond_max: float = 1e3,
    seed: int = 0,
    dst_format: str | None = None,
    force: bool = False,
) -> float:
    """Write a synthetic scene of ``rows`` bodies (see :mod:`hconv.tools.scene`) to ``dst``, atomically,
    chunk by chunk; returns the seconds taken."""
    if rows < 0:
        raise UsageError(f"{option('rows')} must be 0 or more, got {rows}")
    check_scene(scene, cond_max)
    fout = format_of(dst, dst_format, "dst_format")
    t0 = time.perf_counter()
    with Output(dst, fout, force=force) as out, BackgroundWriter(out) as writer:
        for cols in iter_scene(rows, seed=seed, scene=scene, cond_max=cond_max):
            writer.write(pa.table(cols))
        if rows == 0:  # still a valid file, with the scene's columns
            writer.write(pa.table(make_scene(0, scene=scene)))
    return time.perf_counter() - t0
