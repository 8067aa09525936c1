"""Shared test helpers: an independent 50-digit reference, random bodies and rotations built
apart from hconv's own code, table shorthands, the real CLI, and consoles to print tables on."""

from __future__ import annotations

import importlib
import io
import os
import signal
import socket
import subprocess
import sys

import mpmath
import numpy as np
import pyarrow as pa
import pytest
from rich.console import Console

from hconv.kernels.metrics import relative_error
from hconv.tools.scene import cylinder_moments, rotate_tensors

EPS = np.finfo(np.float64).eps

#: Credentials for the local S3-compatible server of the tests (conftest.py's ``s3`` fixture).
S3_ENV = {
    "AWS_ACCESS_KEY_ID": "testing",
    "AWS_SECRET_ACCESS_KEY": "testing",
    "AWS_DEFAULT_REGION": "us-east-1",
    "AWS_EC2_METADATA_DISABLED": "true",  # never ask an instance-metadata address for credentials
}


def need(module: str) -> object:
    """The optional module ``module`` (an extra's), imported; the test skips without it, except
    where every extra must be there: .ci/run installs them all and sets HCONV_ALL_ENGINES, so that
    a missing one fails there rather than skip unseen."""
    if os.environ.get("HCONV_ALL_ENGINES"):
        return importlib.import_module(module)
    return pytest.importorskip(module)


def free_port() -> int:
    """A TCP port on 127.0.0.1 free now, for a server a test starts."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def mp_solve(I: np.ndarray, H: np.ndarray) -> np.ndarray:
    """I⁻¹H for a stack ``(N, 3, 3)``, ``(N, 3)`` solved in 50-digit arithmetic, rounded to float64."""
    out = np.empty_like(H, dtype=np.float64)
    with mpmath.workdps(50):
        for k in range(len(H)):
            x = mpmath.lu_solve(mpmath.matrix(I[k].tolist()), mpmath.matrix(H[k].tolist()))
            out[k] = [float(v) for v in x]
    return out


def rel_err(w: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Norm-wise relative error per row of ``(N, 3)`` stacks: hconv's own measure
    (:func:`hconv.kernels.metrics.relative_error`, itself tested against mpmath)."""
    return relative_error(np.asarray(w, dtype=np.float64).T, np.asarray(ref, dtype=np.float64).T)


def random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` uniformly random rotations ``(n, 3, 3)``, from normalised Gaussian quaternions.

    Written here on purpose, not taken from hconv (whose scenes use its own quaternion code):
    the bodies a test checks hconv on are not built by the code under test.
    """
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    rows = (
        (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=1)


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


def hard_bodies(rng: np.random.Generator, shape: str = "(N,3,3)") -> tuple[np.ndarray, np.ndarray]:
    """A stack that holds every status and every hard case, with H; ``(n, 3, 3)`` (or, with
    ``shape="(N,6)"``, the six numbers) and ``(n, 3)``."""
    n = 40
    parts = [
        physical_bodies(rng, n),
        *(spd_bodies(rng, n, c) for c in (1e2, 1e6, 1e9, 1e12, 1e14, 1e16)),  # ill_conditioned, singular
        slender_bodies(rng, n, 1e6),
        slender_bodies(rng, n, 1e12),  # physical, so ill_conditioned shows (not_physical would win)
        rotate_tensors(
            random_rotations(rng, n), cylinder_moments(1.0, rng.uniform(0.01, 1, n), rng.uniform(0.01, 2, n))
        ),
        rotate_tensors(random_rotations(rng, n), np.tile([1.0, 1.0, 1.0], (n, 1))),  # spheres
        rotate_tensors(random_rotations(rng, n), np.tile([1.0, 1.0, 2.0], (n, 1))),  # plates: the triangle's edge
        rotate_tensors(random_rotations(rng, n), np.tile([1.0, 1.0, 3.0], (n, 1))),  # not_physical
        rotate_tensors(random_rotations(rng, n), np.tile([-1.0, 2.0, 3.0], (n, 1))),  # not_positive_definite
        physical_bodies(rng, n) * 1e150,
        physical_bodies(rng, n) * 1e-150,
        physical_bodies(rng, n) * 2.0**130,  # just beyond the closed form's unscaled range
        np.zeros((n, 3, 3)),
    ]
    I = np.concatenate(parts)
    H = rng.normal(size=(I.shape[0], 3))
    H[-3 * n : -2 * n] *= 1e150
    H[-2 * n : -n] *= 1e-150
    I[0, 0, 1] = np.nan  # invalid_input
    I[1, 2, 2] = np.inf
    H[2, 1] = np.nan
    I[3, 0, 1] += 0.5  # not_symmetric
    H[4] = 0.0  # ω = 0 exactly
    I[5], H[5] = np.diag([1e-300, 1e-300, 1e-300]), 1e10  # ω beyond the range: overflow
    H[6] = 1e-320  # ω on the subnormal grid: inaccurate
    if shape == "(N,6)":
        I = I.reshape(-1, 9)[:, [0, 4, 8, 1, 2, 5]]
        I[3, 3] += 0.5  # the planted asymmetry has no six-number spelling: another finite body
    return I, H


def same_bits(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    return a is None and b is None or np.array_equal(a, b, equal_nan=True)


def assert_same_answers(got, ref, method: str) -> None:
    """Two conversions of the same rows agree as docs/engines.md promises: statuses, cond and
    ``exact``'s ω bit for bit; ``refined``'s ω and the residual within 2 eps (each is within a
    rounding of I⁻¹H, whoever decided when refinement stops)."""
    assert np.array_equal(got.status_code, ref.status_code)
    assert same_bits(got.cond, ref.cond)
    if method == "exact":
        assert same_bits(got.w, ref.w)
    else:
        ok = np.isfinite(ref.w).all(axis=1)
        assert np.array_equal(ok, np.isfinite(got.w).all(axis=1))
        assert rel_err(got.w[ok], ref.w[ok]).max() <= 2 * np.finfo(float).eps
    if ref.residual is not None:
        measured = np.isfinite(ref.residual)
        assert np.array_equal(measured, np.isfinite(got.residual))
        assert np.all(np.abs(got.residual - ref.residual)[measured] <= 2 * np.finfo(float).eps)


def six(I: np.ndarray) -> np.ndarray:
    """``(N, 3, 3)`` to the six-number form ``(N, 6)``."""
    return np.stack([I[:, 0, 0], I[:, 1, 1], I[:, 2, 2], I[:, 0, 1], I[:, 0, 2], I[:, 1, 2]], axis=1)


def axis_angle(rng, n):
    """Random unit axes ``(n, 3)`` and angles ``(n,)`` in (-π, π]."""
    u = rng.normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True), rng.uniform(-np.pi, np.pi, n)


def rodrigues(u, theta):
    """Rotation matrices ``(n, 3, 3)`` from axis and angle: cosθ·E + sinθ·[u]× + (1-cosθ)·u·uᵀ."""
    n = len(theta)
    K = np.zeros((n, 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -u[:, 2], u[:, 1], -u[:, 0]
    K -= np.swapaxes(K, 1, 2)
    c, s = np.cos(theta)[:, None, None], np.sin(theta)[:, None, None]
    return c * np.eye(3) + s * K + (1 - c) * np.einsum("ni,nj->nij", u, u)


def quats(u, theta):
    """(w, x, y, z) for the same rotations: the half-angle form."""
    return np.column_stack([np.cos(theta / 2), np.sin(theta / 2)[:, None] * u])


def table(**cols) -> pa.Table:
    return pa.table({k: np.asarray(v) for k, v in cols.items()})


def w_of(t: pa.Table) -> np.ndarray:
    return np.column_stack([t.column(c).to_numpy() for c in ("wx", "wy", "wz")])


def vec(prefix, a, names="xyz"):
    return {f"{prefix}{c}": a[:, k] for k, c in enumerate(names)}


def run_hconv(*args: str, input: bytes | None = None, cwd=None, env: dict | None = None) -> subprocess.CompletedProcess:
    """Run the real command (``python -m hconv``) as a user would; bytes in, bytes out; ``env``
    replaces the environment (COLUMNS=200 unless it says otherwise)."""
    env = dict(os.environ, COLUMNS="200") if env is None else {"COLUMNS": "200", **env}
    return subprocess.run(
        [sys.executable, "-m", "hconv", *args], input=input, capture_output=True, cwd=cwd, env=env, timeout=120
    )


def terminal_signals() -> None:
    """``preexec_fn`` for a child that must see Ctrl-C as from a terminal: SIGINT and SIGQUIT at
    their defaults. A child inherits an ignored signal, and a test process may have both ignored
    (a C system() call running in another thread), so the child would never see the SIGINT."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGQUIT, signal.SIG_DFL)


# A sitecustomize for a child started with StopAt's environment. The interpreter imports it at the
# end of its own start, before hconv. When the point HCONV_TEST_STOP_AT is reached (MODULE: its
# import starts; MODULE:NAME or MODULE:CLASS.NAME: the function's first call, once the module is
# imported; MODULE:NAME#K: its K-th call), the child writes a byte on fd HCONV_TEST_TOLD and reads
# fd HCONV_TEST_WAIT, which gives nothing until the test closes it: a signal the test sends
# meanwhile lands at that point.
_STOP_AT = """
import os, sys


def _stop():
    os.write(int(os.environ["HCONV_TEST_TOLD"]), b"1")
    os.read(int(os.environ["HCONV_TEST_WAIT"]), 1)  # a signal's handler runs here


class _StopAt:
    module, _, name = os.environ["HCONV_TEST_STOP_AT"].partition(":")
    name, _, call = name.partition("#")

    def find_spec(self, fullname, path=None, target=None):
        if fullname != self.module:
            return None
        sys.meta_path.remove(self)
        if not self.name:
            _stop()
            return None
        import importlib.util

        spec = importlib.util.find_spec(fullname)
        run, (*where, attr) = spec.loader.exec_module, self.name.split(".")

        def exec_module(module):
            run(module)
            owner = module
            for part in where:
                owner = getattr(owner, part)
            fn = getattr(owner, attr)
            calls = [int(self.call or 1)]

            def stopped(*args, **kwargs):
                calls[0] -= 1
                if calls[0] == 0:
                    setattr(owner, attr, fn)  # that call only
                    _stop()
                return fn(*args, **kwargs)

            setattr(owner, attr, stopped)

        spec.loader.exec_module = exec_module
        return spec


sys.meta_path.insert(0, _StopAt())
"""


class StopAt:
    """A handshake with a child process, so that a test acts (sends a signal, kills it) at a point
    of the child's run however slow the machine, instead of after a sleep: ``point`` as in
    ``_STOP_AT`` above. Start the child with ``env=stop.env(...)`` and ``pass_fds=stop.fds``,
    then call :meth:`started`; :meth:`reached` waits until the child is at the point (False if it
    ended first); act; then :meth:`release` lets it go on (a child that ignored the signal goes
    on, and the test sees it finish)."""

    def __init__(self, folder, point: str):
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "sitecustomize.py").write_text(_STOP_AT)
        self.folder, self.point = folder, point
        self._told_r, self._told_w = os.pipe()
        self._wait_r, self._wait_w = os.pipe()
        self.fds = (self._told_w, self._wait_r)

    def env(self, base: dict | None = None) -> dict:
        base = dict(os.environ) if base is None else dict(base)
        path = os.pathsep.join([str(self.folder), base.get("PYTHONPATH", "")])
        told, wait = map(str, self.fds)
        return dict(base, PYTHONPATH=path, HCONV_TEST_STOP_AT=self.point, HCONV_TEST_TOLD=told, HCONV_TEST_WAIT=wait)

    def started(self) -> None:
        """The child has started with its copies of the pipes' ends: close this process's."""
        for fd in self.fds:
            os.close(fd)

    def reached(self) -> bool:
        got = os.read(self._told_r, 1)  # b"" once every copy of the other end is closed: it ended
        os.close(self._told_r)
        return got == b"1"

    def release(self) -> None:
        os.close(self._wait_w)


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


def hconv_inprocess(*args: str, capsys, columns: str = "200") -> subprocess.CompletedProcess:
    """``hconv ARGS`` in this process (:func:`run_inprocess`), its result shaped as
    :func:`run_hconv`'s (returncode, bytes out and err; COLUMNS=200 unless told), for a test of
    what the command says and writes rather than of the process itself: no interpreter to start,
    so no start-up for a loaded machine to slow down."""
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = columns
    try:
        code, out, err = run_inprocess(*args, capsys=capsys)
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return subprocess.CompletedProcess(["hconv", *args], code, out.encode(), err.encode())


def run_on_terminal(*args: str, columns: int = 80, cwd=None) -> tuple[int, str]:
    """Run the real command with stdout and stderr on a terminal ``columns`` wide, as a user at a
    terminal sees it; returns (exit code, what the terminal showed, colours and cursor moves removed)."""
    import fcntl
    import pty
    import re
    import struct
    import termios

    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 50, columns, 0, 0))
    env = dict(os.environ, COLUMNS=str(columns), TERM="xterm-256color")
    proc = subprocess.Popen(
        [sys.executable, "-m", "hconv", *args],
        stdout=follower,
        stderr=follower,
        stdin=subprocess.DEVNULL,
        cwd=cwd,
        env=env,
    )
    os.close(follower)
    chunks = []
    while True:
        try:
            data = os.read(leader, 65536)
        except OSError:  # the terminal closes (EIO) once the command has exited
            break
        if not data:
            break
        chunks.append(data)
    os.close(leader)
    code = proc.wait(timeout=120)
    text = b"".join(chunks).decode().replace("\r\n", "\n")
    return code, re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", text)


#: The characters of a rich table's box: none may show in text for tools.
BOX = set("┏┓┗┛┃━┡┩╇┳┻│─└┘├┤┼┌┐")


def terminal(width: int) -> Console:
    return Console(file=io.StringIO(), width=width, force_terminal=True, color_system=None)


def shown(console: Console) -> list[str]:
    return console.file.getvalue().splitlines()  # type: ignore[attr-defined]


def assert_fits(lines: list[str], width: int, names) -> None:
    text = "\n".join(lines)
    assert max(len(ln) for ln in lines) <= width, max(lines, key=len)
    assert "…" not in text
    for name in names:  # whole, on one line: neither cut nor wrapped inside
        assert any(name in ln for ln in lines), name


def command_imports(args: list[str], module: str) -> tuple[object, bool, str]:
    """Run the hconv command with ``args`` in a new process (what it imports is under test, so it
    cannot run in this one): (its exit code, whether ``module`` was imported, its stderr)."""
    code = (
        f"import sys; sys.argv = ['hconv', *{[str(a) for a in args]!r}]\n"
        "from hconv.cli import main\ntry: main()\nexcept SystemExit as exc: print(exc.code)\n"
        f"print({module!r} in sys.modules)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=60)
    words = proc.stdout.decode().split()
    code_word = words[-2] if len(words) >= 2 else None
    return (
        (int(code_word) if code_word and code_word.lstrip("-").isdigit() else code_word),
        words[-1:] == ["True"],
        proc.stderr.decode(),
    )
