"""Shared test helpers: an independent 50-digit reference, random bodies, and the real CLI."""
from __future__ import annotations

import os
import subprocess
import sys

import mpmath
import numpy as np
import pytest

from hconv.tools.scene import random_rotations, rotate_tensors

EPS = np.finfo(np.float64).eps


def mp_solve(I: np.ndarray, H: np.ndarray) -> np.ndarray:
    """I⁻¹H for a stack ``(N, 3, 3)``, ``(N, 3)`` solved in 50-digit arithmetic, rounded to float64."""
    out = np.empty_like(H, dtype=np.float64)
    with mpmath.workdps(50):
        for k in range(len(H)):
            x = mpmath.lu_solve(mpmath.matrix(I[k].tolist()), mpmath.matrix(H[k].tolist()))
            out[k] = [float(v) for v in x]
    return out


def rel_err(w: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Norm-wise relative error per row, safe from overflow at any magnitude."""
    m = np.max(np.abs(ref), axis=1, keepdims=True)
    m = np.where(m > 0, m, 1.0)
    return np.linalg.norm((w - ref) / m, axis=1) / np.linalg.norm(ref / m, axis=1)


def spd_bodies(rng: np.random.Generator, n: int, cond: float) -> np.ndarray:
    """``n`` rotated SPD tensors with cond(I) = ``cond`` exactly in their moments; ``(n, 3, 3)``."""
    mid = 10.0 ** (-np.log10(cond) * rng.random(n))
    moments = np.stack([np.ones(n), mid, np.full(n, 1.0 / cond)], axis=1)
    return rotate_tensors(random_rotations(rng, n), moments)


def slender_bodies(rng: np.random.Generator, n: int, cond: float) -> np.ndarray:
    """``n`` physical bodies with cond(I) ≈ ``cond``: rods and thin plates, moments (ε, 1, 1 + t·ε)
    with ε = 1/cond and t in [0, 1] (t = 1 is a plate, on the triangle inequality's boundary)."""
    eps_m = np.full(n, 1.0 / cond)
    moments = np.stack([eps_m, np.ones(n), 1.0 + rng.random(n) * eps_m], axis=1)
    return rotate_tensors(random_rotations(rng, n), moments)


def physical_bodies(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` rotated tensors whose moments obey the triangle inequality, cond ≤ ~20; ``(n, 3, 3)``."""
    # second moments of a random mass distribution along each principal axis
    c = rng.uniform(0.05, 1.0, (n, 3))
    moments = np.stack([c[:, 1] + c[:, 2], c[:, 0] + c[:, 2], c[:, 0] + c[:, 1]], axis=1)
    return rotate_tensors(random_rotations(rng, n), moments)


def six(I: np.ndarray) -> np.ndarray:
    """``(N, 3, 3)`` to the six-number form ``(N, 6)``."""
    return np.stack([I[:, 0, 0], I[:, 1, 1], I[:, 2, 2], I[:, 0, 1], I[:, 0, 2], I[:, 1, 2]], axis=1)


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


def run_hconv(*args: str, input: bytes | None = None, cwd=None) -> subprocess.CompletedProcess:
    """Run the real command (``python -m hconv``) as a user would; bytes in, bytes out."""
    env = dict(os.environ, COLUMNS="200")
    return subprocess.run([sys.executable, "-m", "hconv", *args], input=input, capture_output=True,
                          cwd=cwd, env=env, timeout=120)


def run_inprocess(*args: str, capsys) -> tuple[int, str, str]:
    """``hconv ARGS`` in this process, through the console script's ``cli.main``; returns
    (exit code, stdout, stderr). For tests that run the command hundreds of times."""
    from hconv import cli

    old = sys.argv
    sys.argv = ["hconv", *args]
    try:
        cli.main()
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    finally:
        sys.argv = old
    out, err = capsys.readouterr()
    return code, out, err
