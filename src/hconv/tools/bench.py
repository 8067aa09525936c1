"""`hconv bench`: speed against accuracy for every method and precision, and the speed targets.

Every time is the fastest of repeats, and every target is a ratio between two times measured in the
same run, because the machine is shared and noisy: the repeats run in interleaved rounds (every
job once per round), so that a slow drift of the machine falls on both sides of a ratio, and the
fastest round of each job is its own cost, the least disturbed by other work (a median kept some
of the disturbance, most on the side of the longer job). Accuracy
is scored like `hconv stability`: against I⁻¹H solved in exact rational arithmetic. Nothing here is
needed at run time; the chart needs matplotlib (hconv's ``bench`` extra).
"""

from __future__ import annotations

import functools
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from hconv.kernels.inertia import Sym3
from hconv.kernels.metrics import relative_error
from hconv.solve import convert as core
from hconv.solve import methods, options
from hconv.solve.blocks import BLOCK_ROWS
from hconv.tools import leftovers, stability
from hconv.tools.scene import make_scene

PRECISIONS = (64, 32)
ACCURACY_CONDS = (1e1, 1e4, 1e8)
#: refined against lapack on rows of one condition number each: its steps grow with cond
REFINED_CONDS = (1e4, 1e8, 1e10, 1e12)
#: rows per condition number there (16 blocks)
REFINED_ROWS = 16 * BLOCK_ROWS


@dataclass
class Result:
    rows: int
    machine: str
    kernel: dict = field(default_factory=dict)  #: "method/64" -> rows/s, the method's arithmetic only
    convert: dict = field(default_factory=dict)  #: "method/64" -> rows/s, Parquet → Parquet end to end
    accuracy: dict = field(default_factory=dict)  #: "method/64" -> {cond: [median, worst]}
    refined_by_cond: dict = field(default_factory=dict)  #: cond -> refined/64 kernel ÷ lapack/64 kernel
    baselines: dict = field(default_factory=dict)  #: named reference rates and times
    #: what users call, against numpy.linalg.solve on the same rows: N -> call -> seconds per call
    user: dict = field(default_factory=dict)
    #: engine -> first call of a fresh process: {"import_s", "first_call_s", "second_call_s"}
    cold: dict = field(default_factory=dict)
    targets: list = field(default_factory=list)  #: [name, measured ratio, required, met]


def describe_machine() -> str:
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            model = next(ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    import pyarrow

    return (
        f"{model}, {os.cpu_count()} cores; Python {platform.python_version()}, "
        f"numpy {np.__version__}, pyarrow {pyarrow.__version__}"
    )


def rounds(jobs: dict, repeats: int) -> dict:
    """The fewest seconds of each job, run in interleaved rounds (every job once per round), so
    that the machine's slow drifts fall on every side of a ratio alike."""
    times: dict = {k: [] for k in jobs}
    for _ in range(repeats):
        for k, fn in jobs.items():
            t0 = time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - t0)
    return {k: min(v) for k, v in times.items()}


def _inputs(rows: int, seed: int) -> tuple[Sym3, np.ndarray, np.ndarray]:
    cols = make_scene(rows, seed=seed)
    I = Sym3(*(np.ascontiguousarray(cols[c]) for c in ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")))
    H = np.ascontiguousarray(np.stack([cols[f"H{a}"] for a in "xyz"]))
    r = np.ascontiguousarray(np.stack([cols[f"r{a}"] for a in "xyz"]))
    return I, H, r


def kernel_rates(
    I: Sym3, H: np.ndarray, r: np.ndarray, repeats: int, only: str | tuple[str, ...] | None = None
) -> dict:
    """Each method's own arithmetic over cache-sized blocks, as `convert` runs it, in rows/s;
    ``only`` ("exact/64", or several such keys) measures just those, in the same rounds."""
    n, jobs = H.shape[1], {}
    keys = {only} if isinstance(only, str) else (set(only) if only is not None else None)
    for prec in PRECISIONS:
        if keys is not None and not any(k.endswith(f"/{prec}") for k in keys):
            continue
        dt = options.DTYPES[prec]
        blocks = [
            (
                I.take(slice(lo, lo + BLOCK_ROWS)).astype(dt),
                H[:, lo : lo + BLOCK_ROWS].astype(dt),
                r[:, lo : lo + BLOCK_ROWS].astype(dt),
            )
            for lo in range(0, n, BLOCK_ROWS)
        ]
        for name, m in methods.METHODS.items():
            if keys is None or f"{name}/{prec}" in keys:
                jobs[f"{name}/{prec}"] = functools.partial(_each_block, m.kernel, blocks)
    return {k: n / v for k, v in rounds(jobs, repeats).items()}


def cond_bodies(rng: np.random.Generator, n: int, cond: float) -> tuple[Sym3, np.ndarray]:
    """n randomly turned bodies whose cond(I) is exactly ``cond`` (principal moments 1, a
    log-uniform middle one, and 1/cond, in kg·m²) and H ~ N(0, 1) of shape ``(3, n)``."""
    from hconv.tools.scene import random_rotations, rotate_tensors

    moments = np.stack([np.ones(n), 10 ** (-np.log10(cond) * rng.random(n)), np.full(n, 1 / cond)], axis=1)
    M = rotate_tensors(random_rotations(rng, n), moments)
    I = Sym3(*(np.ascontiguousarray(M[:, i, j]) for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))))
    return I, np.ascontiguousarray(rng.normal(size=(3, n)))


def refined_by_cond(rows: int, repeats: int, seed: int = 0) -> dict:
    """``refined`` ÷ ``lapack`` kernel throughput on the same rows, at each of REFINED_CONDS."""
    out = {}
    for cond in REFINED_CONDS:
        I, H = cond_bodies(np.random.default_rng(seed), rows, cond)
        rates = kernel_rates(I, H, np.zeros_like(H), repeats, only=("refined/64", "lapack/64"))
        out[f"{cond:g}"] = rates["refined/64"] / rates["lapack/64"]
    return out


def _each_block(kernel: Callable, blocks: list) -> None:
    """Run ``kernel`` on every block and drop each answer, as ``convert`` does once it has copied
    it out: keeping all of them made the allocator hand the memory back and fault it in again on
    every repeat, which slowed the kernels (docs/measurements.md)."""
    for b in blocks:
        kernel(*b)


def accuracy(rows: int = 300, seed: int = 0) -> dict:
    """Median and worst relative error vs exact I⁻¹H, per method and precision, at a few cond."""
    rng = np.random.default_rng(seed)
    out: dict = {}
    for cond in ACCURACY_CONDS:
        I, H, r = stability.slender_bodies(rng, rows, cond)
        ref = stability.exact_solve(I, H).T
        for name in methods.METHODS:
            for prec in PRECISIONS:
                with np.errstate(all="ignore"):
                    w = core.convert(H, I, r, method=name, precision=prec, diagnostics=False).w.astype(float)
                    err = relative_error(w.T, ref)
                err = err[np.isfinite(err)]
                out.setdefault(f"{name}/{prec}", {})[f"{cond:g}"] = (
                    [float(np.median(err)), float(err.max())] if err.size else [float("nan")] * 2
                )
    return out


def compiled_loop(I: Sym3, H: np.ndarray) -> Callable[[], None]:
    """The yardstick: the compiled engine's row code on one thread, ``exact`` without the
    residual, ready to time (LDLᵀ, the closed-form moments and every status in one pass)."""
    from hconv.solve import rowcode  # the compiled engine's C code

    n = H.shape[1]
    I6 = np.stack(list(I))
    out = (np.empty((n, 3)), np.empty(n), np.empty(n, np.uint8), np.empty(0), np.empty(n, bool))

    def loop() -> None:
        rowcode.convert(I6, False, H, False, False, np.inf, *out, False, 0, n)

    return loop


_YARDSTICK = """
import sys, numpy as np
from hconv.kernels import allocator
from hconv.tools import bench
allocator.tune()  # as the hconv command does at start-up
from hconv.kernels.inertia import Sym3
from hconv.kernels.metrics import relative_error
d = np.load(sys.argv[1])
I, H = Sym3(*(np.ascontiguousarray(d[k]) for k in range(6))), np.ascontiguousarray(d[6:9])
if sys.argv[2] == "compiled":
    print(H.shape[1] / bench.rounds({"c": bench.compiled_loop(I, H)}, 3)["c"])
else:
    print(bench.kernel_rates(I, H, np.zeros_like(H), 3, only="exact/64")["exact/64"])
"""


def yardstick(I: Sym3, H: np.ndarray, tmp: str, repeats: int) -> tuple[float | None, float]:
    """(compiled loop, exact kernel) in rows/s, each in fresh processes, alternating per round
    (separate processes: when the yardstick was numba, importing it slowed the float64 numpy
    kernels of the same process; docs/measurements.md)."""
    path = os.path.join(tmp, "yardstick.npy")
    np.save(path, np.stack(list(I) + list(H)))
    got: dict = {"compiled": [], "exact": []}
    for _ in range(repeats):
        for which in got:
            out = leftovers.child(
                [sys.executable, "-c", _YARDSTICK, path, which], check=True, capture_output=True, text=True
            )
            got[which].append(float(out.stdout.strip().splitlines()[-1]))
    return max(got["compiled"]), max(got["exact"])  # rates: the fastest is the highest


def _write_bytecode() -> None:
    """Compile hconv's modules to bytecode, as ``pip install`` does, so that a command starts as
    it does for users: a source checkout run with PYTHONDONTWRITEBYTECODE set (as some CI and
    container images do) compiles every module again at each start. Quietly nothing where the
    package folder cannot be written."""
    import compileall

    import hconv

    compileall.compile_dir(os.path.dirname(hconv.__file__), quiet=2)


def _command(args: list) -> Callable[[], object]:
    return lambda: subprocess.run(args, check=True, capture_output=True)


def _peak_rss_mb(args: list) -> float:
    """Peak RSS of a command, measured from a fresh wrapper process whose only child it is."""
    code = (  # the measured command dies with its wrapper, as the wrapper with the bench (leftovers.child)
        "import resource, subprocess, sys\n"
        "from hconv.tools.leftovers import die_with_parent\n"
        "subprocess.run(sys.argv[1:], check=True, capture_output=True, preexec_fn=die_with_parent)\n"
        "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
    )
    out = leftovers.child([sys.executable, "-c", code, *args], check=True, capture_output=True, text=True)
    return int(out.stdout.strip()) / 1024.0


_PLAIN_SCRIPT = """
import sys, numpy as np, pyarrow as pa, pyarrow.parquet as pq
t = pq.read_table(sys.argv[1])
g = lambda c: t.column(c).to_numpy()
I = np.empty((t.num_rows, 3, 3))
I[:, 0, 0], I[:, 1, 1], I[:, 2, 2] = g("Ixx"), g("Iyy"), g("Izz")
I[:, 0, 1] = I[:, 1, 0] = g("Ixy"); I[:, 0, 2] = I[:, 2, 0] = g("Ixz"); I[:, 1, 2] = I[:, 2, 1] = g("Iyz")
w = np.linalg.solve(I, np.column_stack([g("Hx"), g("Hy"), g("Hz")])[..., None])[..., 0]
for k, c in enumerate(("wx", "wy", "wz")):
    t = t.append_column(c, pa.array(w[:, k]))
pq.write_table(t, sys.argv[2])
"""


#: The sizes users call hconv.convert at: one body (a physics engine's step), a scene, a batch, a file.
USER_SIZES = (1, 100, 10_000, 2_000_000)
#: Rows per timed job, and the most calls in one, so that small calls are timed over many repeats
#: while a job stays well under a second.
_ROWS_PER_JOB, _MOST_CALLS = 200_000, 200


def _stacks(n: int, seed: int, cond: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """n bodies as numpy users hold them: H (n, 3) [kg·m²/s] and I (n, 3, 3) [kg·m²]; the example
    scene's mix, or bodies of exactly ``cond``."""
    if cond is None:
        cols = make_scene(n, seed=seed)
        I3 = np.empty((n, 3, 3))
        for (i, j), c in zip(
            ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)), ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
        ):
            I3[:, i, j] = I3[:, j, i] = cols[c]
        return np.column_stack([cols["Hx"], cols["Hy"], cols["Hz"]]), I3
    I, H = cond_bodies(np.random.default_rng(seed), n, cond)
    return np.ascontiguousarray(H.T), I.matrices()


def _six(I3: np.ndarray) -> np.ndarray:
    return np.stack([I3[:, 0, 0], I3[:, 1, 1], I3[:, 2, 2], I3[:, 0, 1], I3[:, 0, 2], I3[:, 1, 2]], axis=1)


def _repeated(fn: Callable[[], object], k: int) -> Callable[[], None]:
    def job() -> None:
        for _ in range(k):
            fn()

    return job


def user_engines(n: int) -> tuple[str, ...]:
    """The engines timed at ``n`` rows: auto (what users get: the compiled engine) and numpy
    (the reference)."""
    return ("auto", "numpy")


#: The calls timed at each size: I as users hold it, with the residual or without.
USER_CALLS = ("(N,3,3)", "(N,3,3), no residual", "(N,6)", "(N,6), no residual")


def user_calls(rows: int, repeats: int, seed: int = 0) -> dict:
    """``hconv.convert`` as users call it, against ``numpy.linalg.solve`` on the same rows: at each
    of USER_SIZES up to ``rows``, I as an (N, 3, 3) stack and as (N, 6), with and without the
    residual, by each engine; and ``refined`` at cond 1e12. One body is passed unstacked, as a
    physics engine calls it once per step. A process's first call is :func:`cold_start`'s.
    Returns size -> {"numpy.linalg.solve": seconds,
    call -> {engine: seconds per call}}."""
    import hconv

    out: dict = {}
    for n in [s for s in USER_SIZES if s <= rows]:
        H, I3 = _stacks(n, seed)
        I6 = _six(I3)
        h, i3, i6 = (H[0], I3[0], I6[0]) if n == 1 else (H, I3, I6)
        rhs = h if n == 1 else h[..., None]
        jobs: dict = {("numpy.linalg.solve", ""): lambda i3=i3, rhs=rhs: np.linalg.solve(i3, rhs)}
        for call in USER_CALLS:
            i = i3 if call.startswith("(N,3,3)") else i6
            for engine in user_engines(n):
                jobs[(call, engine)] = functools.partial(
                    hconv.convert, h, i, diagnostics="no residual" not in call, engine=engine
                )
        k = max(1, min(_MOST_CALLS, _ROWS_PER_JOB // n))
        # three times the rounds of the rest: on a shared machine numpy.linalg.solve, on one core,
        # slows by up to twice while another job shares that core, and hconv, whose blocks go to
        # whichever core is free, by little (docs/bench.md); the ratios are against solve's
        # fastest, which more rounds are the likelier to meet
        secs = rounds({key: _repeated(fn, k) for key, fn in jobs.items()}, 3 * repeats)
        out[str(n)] = _nest(secs, k)
    n = min(rows, REFINED_ROWS)
    H, I3 = _stacks(n, seed, cond=1e12)
    jobs = {("numpy.linalg.solve", ""): lambda: np.linalg.solve(I3, H[..., None])}
    for engine in user_engines(n):
        jobs[("refined (N,3,3), no residual", engine)] = functools.partial(
            hconv.convert, H, I3, method="refined", diagnostics=False, engine=engine
        )
    out[f"{n} at cond 1e12"] = _nest(rounds(jobs, 3 * repeats), 1)
    return out


def _nest(secs: dict, k: int) -> dict:
    """{(call, engine): seconds for k calls} as {"numpy.linalg.solve": s, call: {engine: s}} per call."""
    out: dict = {}
    for (call, engine), s in secs.items():
        if call == "numpy.linalg.solve":
            out[call] = s / k
        else:
            out.setdefault(call, {})[engine] = s / k
    return out


_COLD = """
import sys, time
t0 = time.perf_counter()
import numpy as np, hconv
t1 = time.perf_counter()
n = int(sys.argv[1])
I, H = np.tile(np.diag([1.0, 2.0, 2.5]), (n, 1, 1)), np.ones((n, 3))
res = hconv.convert(H, I, engine=sys.argv[2])
t2 = time.perf_counter()
hconv.convert(H, I, engine=sys.argv[2])
t3 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2, res.engine)
"""


def cold_start(repeats: int = 3) -> dict:
    """The first call of a process, by engine, in fresh interpreters: seconds to import hconv, for
    the first ``hconv.convert`` of 100 rows, and for the second."""
    out: dict = {}
    for engine in ("compiled", "numpy"):
        runs = []
        for _ in range(repeats):
            env = dict(os.environ)
            env.pop("HCONV_ENGINE", None)
            args = [sys.executable, "-c", _COLD, "100", engine]
            proc = leftovers.child(args, capture_output=True, text=True, env=env, check=True)
            runs.append([float(x) for x in proc.stdout.split()[:3]])
        imp, first, second = (min(r[k] for r in runs) for k in range(3))
        out[engine] = {"import_s": imp, "first_call_s": first, "second_call_s": second}
    return out


#: pyarrow alone reading the input and writing hconv's output, nothing computed: its six columns
#: (``status`` a dictionary, as hconv writes it) with hconv's Parquet settings, given as JSON by
#: :func:`_plain_io_options` (computed here, so that the script does not pay for importing hconv).
_PLAIN_IO = """
import json, sys, numpy as np, pyarrow as pa, pyarrow.parquet as pq
t = pq.read_table(sys.argv[1])
zero = pa.array(np.zeros(t.num_rows))
for c in ("wx", "wy", "wz", "residual", "cond"):
    t = t.append_column(c, zero)
t = t.append_column("status", pa.DictionaryArray.from_arrays(pa.array(np.zeros(t.num_rows, np.int8)), pa.array(["ok"])))
pq.write_table(t, sys.argv[2], **json.loads(sys.argv[3]))
"""


def _plain_io_options(src: str) -> str:
    """hconv's Parquet settings for :data:`_PLAIN_IO`'s output of ``src``, as JSON."""
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    from hconv.tables.parquetio import parquet_write_options

    schema = pq.read_schema(src)
    for name in ("wx", "wy", "wz", "residual", "cond"):
        schema = schema.append(pa.field(name, pa.float64()))
    schema = schema.append(pa.field("status", pa.dictionary(pa.int8(), pa.string())))
    return json.dumps(parquet_write_options(schema))


def _roofline(src: str, dst: str) -> None:
    """hconv's own reading and writing of the same columns, with no computation at all."""
    import pyarrow as pa

    from hconv.tables.arrow import output_fields
    from hconv.tables.job import Job
    from hconv.tables.output import Output
    from hconv.tables.pipeline import BackgroundWriter
    from hconv.tables.tableio import open_input

    job = Job()
    fields = output_fields(job)
    with open_input(src, "parquet", job) as inp, Output(dst, "parquet", force=True) as out, BackgroundWriter(out) as wr:
        for batch in inp.batches:
            n = batch.num_rows
            cols = [pa.array(np.zeros(n)) for _ in fields[:-1]]
            cols.append(pa.DictionaryArray.from_arrays(pa.array(np.zeros(n, np.int8)), pa.array(["ok"])))
            wr.write(pa.Table.from_arrays(list(batch.columns) + cols, schema=pa.schema(list(batch.schema) + fields)))


#: What users call, as (size, call, engine, required ratio numpy.linalg.solve time / call time):
#: issue 27. auto is what ``hconv.convert(H, I)`` gives (the compiled engine); the numpy engine is
#: the reference, timed but held to no speed.
USER_TARGETS = (
    ("2000000", "(N,3,3), no residual", "auto", 12.0),
    ("2000000", "(N,6), no residual", "auto", 12.0),
    ("2000000", "(N,3,3)", "auto", 8.0),
    ("2000000", "(N,6)", "auto", 8.0),
    ("10000", "(N,3,3)", "auto", 8.0),
    ("10000", "(N,6)", "auto", 8.0),
    ("100", "(N,3,3)", "auto", 3.0),
    ("1", "(N,3,3)", "auto", 1.0),
)


def user_targets(user: dict) -> list[list]:
    """The targets for what users call, as [name, measured, required] rows: each a ratio of
    numpy.linalg.solve's time to hconv's on the same rows (higher is better)."""
    rows = []
    for n, call, engine, required in USER_TARGETS:
        if n in user and engine in user[n].get(call, {}):
            label = "one body" if n == "1" else f"N = {int(n):,}"
            ratio = user[n]["numpy.linalg.solve"] / user[n][call][engine]
            rows.append([f"solve / convert {call}, {label}, engine {engine}", ratio, required])
    refined = next((v for k, v in user.items() if k.endswith("at cond 1e12")), None)
    if refined:
        for engine, secs in refined["refined (N,3,3), no residual"].items():
            if engine == "auto":
                ratio = refined["numpy.linalg.solve"] / secs
                rows.append([f"solve / convert refined, no residual, cond 1e12, engine {engine}", ratio, 8.0])
    return rows


def _first_call_target(cold: dict) -> float:
    """Issue 27's first-call target as a ratio (above 1: met): 20 ms over how much longer the
    first ``hconv.convert`` of a fresh process takes than its second, by the compiled engine."""
    extra = cold["compiled"]["first_call_s"] - cold["compiled"]["second_call_s"]
    return 0.020 / max(extra, 1e-6)


def run(
    rows: int = 2_000_000,
    repeats: int = 3,
    seed: int = 0,
    memory_rows: int = 0,
    log: Callable[[str], None] = lambda s: None,
) -> Result:
    """Measure everything; ``memory_rows`` > 0 also measures peak RSS converting that many rows."""
    from hconv.tables import pipeline
    from hconv.tools import generate

    leftovers.remove_stale_folders(log)
    res = Result(rows=rows, machine=describe_machine())
    log("what users call: hconv.convert against numpy.linalg.solve")
    res.user = user_calls(rows, repeats, seed)
    log("cold start by engine")
    _write_bytecode()  # before every fresh process this run starts
    res.cold = cold_start()
    log("generating inputs")
    I, H, r = _inputs(rows, seed)
    log("kernels")
    res.kernel = kernel_rates(I, H, r, repeats)
    log("refined by condition number")
    res.refined_by_cond = refined_by_cond(min(rows, REFINED_ROWS), repeats, seed)
    log("accuracy")
    res.accuracy = accuracy(seed=seed)
    hconv_cmd = [sys.executable, "-m", "hconv"]
    with leftovers.temporary_folder() as tmp:
        log("compiled-loop yardstick")
        compiled, exact_fresh = yardstick(I, H, tmp, repeats)
        src, dst = os.path.join(tmp, "in.parquet"), os.path.join(tmp, "out.parquet")
        generate.generate_file(src, rows, seed=seed)
        log("end-to-end conversions")
        pipeline.convert_file(src, dst, force=True)  # warm-up: page cache and first-call costs
        jobs: dict[str, Callable[[], object]] = {
            f"{name}/{prec}": functools.partial(
                pipeline.convert_file, src, dst, method=name, precision=prec, force=True
            )
            for name in methods.METHODS
            for prec in PRECISIONS
        }
        jobs["roofline"] = lambda: _roofline(src, dst)
        jobs["plain script"] = _command([sys.executable, "-c", _PLAIN_SCRIPT, src, dst])
        jobs["pyarrow read, append six, write"] = _command(
            [sys.executable, "-c", _PLAIN_IO, src, dst, _plain_io_options(src)]
        )
        jobs["hconv convert"] = _command(hconv_cmd + ["convert", src, dst, "--force", "-q"])
        tiny, tiny_out = os.path.join(tmp, "tiny.parquet"), os.path.join(tmp, "tiny-out.parquet")
        generate.generate_file(tiny, 10, seed=seed)
        jobs["hconv start-up"] = _command(hconv_cmd + ["convert", tiny, tiny_out, "--force", "-q"])
        secs = rounds(jobs, repeats)
        roof, plain_s, hconv_cli_s = rows / secs.pop("roofline"), secs.pop("plain script"), secs.pop("hconv convert")
        plain_io_s = secs.pop("pyarrow read, append six, write")
        startup_s = secs.pop("hconv start-up")
        res.convert = {k: rows / v for k, v in secs.items()}
        log("start-up")
        starts = rounds(
            {
                "one": _command(hconv_cmd + ["one", "--H", "1,2,3", "--I", "2,3,4,0,0,0"]),
                "numpy": _command([sys.executable, "-c", "import numpy"]),
            },
            10,
        )
        one_s, numpy_s = starts["one"], starts["numpy"]
        res.baselines = {
            "io_roofline_rows_per_s": roof,
            "plain_script_s": plain_s,
            "hconv_convert_cli_s": hconv_cli_s,
            "pyarrow_read_append_write_s": plain_io_s,
            "hconv_startup_s": startup_s,
            # what the plain-script ratio could be if hconv computed nothing at all
            "plain_script_ceiling": plain_s / (startup_s + rows / roof),
            "compiled_loop_rows_per_s": compiled,
            "exact_kernel_fresh_process_rows_per_s": exact_fresh,
            "hconv_one_s": one_s,
            "import_numpy_s": numpy_s,
        }
        if memory_rows:
            log(f"peak memory on {memory_rows:,} rows")
            big = os.path.join(tmp, "big.parquet")
            generate.generate_file(big, memory_rows, seed=seed)
            res.baselines["memory_rows"] = memory_rows
            res.baselines["peak_rss_mb"] = _peak_rss_mb(hconv_cmd + ["convert", big, dst, "--force", "-q"])
    k = res.kernel
    res.targets = [
        *user_targets(res.user),
        ["pyarrow read+append+write time / hconv convert time", plain_io_s / hconv_cli_s, 0.85],
        ["exact kernel / lapack kernel", k["exact/64"] / k["lapack/64"], 10.0],
        ["exact kernel / compiled loop (fresh processes)", (exact_fresh / compiled) if compiled else None, 0.5],
        ["refined kernel / lapack kernel", k["refined/64"] / k["lapack/64"], 3.0],
        *[[f"refined / lapack, same rows at cond {c}", v, 3.0] for c, v in res.refined_by_cond.items()],
        ["convert exact / I/O roofline", res.convert["exact/64"] / roof, 0.7],
        ["plain script time / hconv convert time", plain_s / hconv_cli_s, 5.0],
        ["import numpy time / hconv one time", numpy_s / one_s, 0.5],
        ["20 ms / what a new process's first call of 100 rows costs more", _first_call_target(res.cold), 1.0],
    ]
    if memory_rows:
        res.targets.append([f"400 MB / peak RSS on {memory_rows:,} rows", 400.0 / res.baselines["peak_rss_mb"], 1.0])
    for t in res.targets:
        t.append(None if t[1] is None else bool(t[1] >= t[2]))
    return res


def to_json(res: Result) -> dict:
    return asdict(res)
