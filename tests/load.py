"""Keep cores busy, so that the tests can be run as on a loaded machine (tests/under-load.sh).

    python tests/load.py [--cores N] [--seconds S]

starts N processes (default: one per core) that each spin in a pure-Python loop, and stops them
all after S seconds (default 1800), on Ctrl-C or SIGTERM, or when this process ends in any way:
each worker also stops by itself once its parent is gone (killed outright, say), so that a
load left behind never slows a machine down for long. Prints one line when the load runs.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import signal
import sys
import time


def _spin(parent: int, until: float) -> None:
    """Busy arithmetic until ``until`` (time.monotonic) or until ``parent`` is no longer ours."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops us; a terminal's Ctrl-C stops it
    x = 0
    while os.getppid() == parent and time.monotonic() < until:
        for k in range(200_000):  # some milliseconds of work between the checks
            x = (x + k * k) % 1_000_003


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cores", type=int, default=os.cpu_count() or 1, help="busy processes (default: one per core)")
    parser.add_argument("--seconds", type=float, default=1800.0, help="stop after this long at most (default 1800)")
    a = parser.parse_args(argv)
    if a.cores < 1 or a.seconds <= 0:
        parser.error("--cores must be 1 or more and --seconds more than 0")
    until = time.monotonic() + a.seconds
    ctx = multiprocessing.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    workers = [ctx.Process(target=_spin, args=(os.getpid(), until), daemon=True) for _ in range(a.cores)]
    for w in workers:
        w.start()

    def stop(signum: int, frame: object) -> None:
        raise SystemExit(0)

    signal.signal(signal.SIGTERM, stop)
    print(f"load: {a.cores} busy processes for at most {a.seconds:g} s (pid {os.getpid()})", flush=True)
    try:
        for w in workers:
            w.join()
    except (KeyboardInterrupt, SystemExit):
        pass
    finally:
        for w in workers:
            w.terminate()
        for w in workers:
            w.join()
    return 0


if __name__ == "__main__":
    sys.exit(main())
