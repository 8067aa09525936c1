"""The ``hconv`` command: thin commands over the library.

``one`` imports neither pyarrow nor rich, so that a quick check starts about as fast as numpy.
Errors print one line, ``hconv: error: ...``, and exit with the codes in :mod:`hconv.errors`.
"""

from __future__ import annotations

import functools
import json
import math
import os
import signal
import sys
from enum import Enum
from typing import TYPE_CHECKING, Any

import typer
from typer.core import TyperCommand

from hconv import interrupts, streams
from hconv.commandline import (
    COLUMNS,
    DEGENERATE,
    DIALECT,
    JOB,
    SCENE,
    Fmt,
    OutFmt,
    body_forms,
    completes,
    extra_arguments,
    fill,
    friendly,
    job_options,
    json_number,
    listing,
    numbers,
    progress_counts,
    usage_failure,
    value_of,
)
from hconv.errors import StrictError, UsageError
from hconv.kernels import allocator
from hconv.solve import forms, options, units
from hconv.tables.body import UNIT_SETS
from hconv.tools.scene import SCENES

if TYPE_CHECKING:
    from hconv.tables.job import Job


app = typer.Typer(
    add_completion=False,  # _root offers completion, for the shell named rather than one guessed
    context_settings={"help_option_names": ["-h", "--help"]},  # -h as well, as command-line tools have
    pretty_exceptions_enable=False,
    no_args_is_help=True,
    help="Angular momentum H (kg·m²/s) to angular velocity ω (rad/s), with the residual against I⁻¹H for every row.",
)


class _PlainUsage(TyperCommand):
    """A command whose usage line reads ``hconv convert [OPTIONS] IN OUT``: typer wraps a
    required argument's metavar in braces (``{IN}``), which reads like a placeholder to fill."""

    def collect_usage_pieces(self, ctx: Any) -> list[str]:  # typer's own (vendored) click Context
        return [p[1:-1] if p.startswith("{") and p.endswith("}") else p for p in super().collect_usage_pieces(ctx)]

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        """Extra arguments in one short line, their count and the fix first: typer's lists every
        one (a glob the shell expanded into 99 files: 2,400 columns), its hint at the end."""
        allowed, ctx.allow_extra_args = ctx.allow_extra_args, True
        rest = super().parse_args(ctx, args)
        ctx.allow_extra_args = allowed
        if rest and not allowed and not ctx.resilient_parsing:
            ctx.fail(extra_arguments(ctx.command_path, rest))
        return rest


def _print_version(value: bool) -> None:
    if value:
        from hconv.version import __version__

        print(f"hconv {__version__}")
        raise typer.Exit(0)


#: The shells typer writes completion scripts for.
SHELLS = ("bash", "zsh", "fish", "powershell", "pwsh")
if TYPE_CHECKING:
    Shell = str
else:
    Shell = Enum("Shell", {s: s for s in SHELLS}, type=str)


def _completion(ctx: typer.Context, param: Any, value: Any) -> None:
    """Install or print typer's completion script for the shell given. typer's own options guess
    the shell from the parent processes, and ignore one named after them."""
    if value is None or ctx.resilient_parsing:
        return
    from typer import completion

    completion.completion_init()
    run = completion.install_callback if param.name == "install_completion" else completion.show_callback
    run(ctx, param, str(value.value))


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", is_eager=True, callback=_print_version, help="print hconv's version and exit"
    ),
    install_completion: Shell | None = typer.Option(
        None,
        "--install-completion",
        metavar="SHELL",
        is_eager=True,
        expose_value=False,
        callback=_completion,
        help="install tab completion for SHELL (bash, zsh, fish, powershell or pwsh) in the shells started after",
    ),
    show_completion: Shell | None = typer.Option(
        None,
        "--show-completion",
        metavar="SHELL",
        is_eager=True,
        expose_value=False,
        callback=_completion,
        help="print the completion script for SHELL, to install it by hand",
    ),
) -> None:
    """Angular momentum H (kg·m²/s) to angular velocity ω (rad/s), with the residual against I⁻¹H for every row."""


@app.command()
@friendly
@job_options(
    "method",
    "precision",
    *SCENE,
    *DEGENERATE,
    "unit_options",
    "omega_unit",
    help={"unit_options": f"SET=UNIT for {', '.join(UNIT_SETS)}, e.g. I=g*cm**2 (repeatable)"},
)
def one(
    H: str = typer.Option(..., "--H", help="Hx,Hy,Hz (kg·m²/s)"),
    I: str = typer.Option(..., "--I", help=f"{forms.counts_text()} values (kg·m²)"),
    r: str | None = typer.Option(
        None,
        "--r",
        help="rx,ry,rz (m): the document methods' offset; for --about, the centre of mass relative to the point of H",
    ),
    q: str | None = typer.Option(None, "--q", help="qw,qx,qy,qz: the body's orientation (body → world)"),
    mass: float | None = typer.Option(None, "--m", help="mass (kg), for --about pivot|free and the unit check"),
    v: str | None = typer.Option(None, "--v", help="vx,vy,vz (m/s): velocity of the centre of mass, for --about free"),
    job: Job = JOB,  # the run options go here (job_options)
    as_json: bool = typer.Option(False, "--json", help="print one JSON object"),
) -> None:
    """Convert one body state and print ω with its unit, the residual, cond and the status."""
    import numpy as np

    from hconv.solve import methods
    from hconv.tables import body

    i = numbers("--I", I, tuple(sorted({f.count for f in forms.FORMS.values()})))
    given = {"H": numbers("--H", H, (3,))}
    for name, text, k in (("r", r, 3), ("q", q, 4), ("v", v, 3)):
        if text is not None:
            given[name] = numbers(f"--{name}", text, (k,))
    values: dict[str, Any] = dict(r=given.get("r"), q=given.get("q"), m=mass, v=given.get("v"), job=job)
    res = body.convert_body(given["H"], i, **values)
    w = [float(x) for x in res.w]
    residual = float(res.residual) if res.residual is not None else float("nan")
    cond, state = float(res.cond), str(res.status)
    cancelled = res.cancelled is not None and bool(res.cancelled)
    unread = body.unread(job, [*given, *(["m"] if mass is not None else [])])
    if state == "invalid_input":  # the status says that, not which value: say it beside, on stderr
        causes = body.invalid_inputs(given["H"], i, **values)
        texts = {"H": H, "I": I, "r": r, "q": q, "v": v, "m": None if mass is None else f"{mass:g}"}
        print(body.invalid_hint(causes, texts, job.precision), file=sys.stderr)
    axis = None if res.null_axis is None or not np.isfinite(res.null_axis).all() else [float(x) for x in res.null_axis]
    if as_json:
        clean = json_number
        out: dict[str, Any] = {
            "w": [clean(x) for x in w],
            "unit": res.unit,
            "residual": clean(residual),
            "cond": clean(cond),
            "status": state,
            "method": job.method,
        }
        if res.null_dim is not None:
            out.update(null_axis=axis, null_dim=int(res.null_dim))
        print(json.dumps(out))
    else:
        free = job.conventions.about == "free"
        print(f"w        = [{', '.join(repr(x) for x in w)}] {res.unit}")
        print(f"residual = {residual:.3g}  {body.RESIDUAL_FREE if free else body.RESIDUAL}")
        print(f"cond     = {cond:.3g}")
        print(f"status   = {state}")
        print(f"method   = {job.method}")
        if res.null_dim is not None and res.null_dim:
            print(f"dropped  = {int(res.null_dim)} axis" + (f" {axis}" if axis else "es"))
        if res.unit == methods.M2_S:
            print(f"note: {res.unit} is not a unit of angular velocity;")
            print("      see docs/design-note.md, the design note's questions")
    if state in body.STATUS_HINTS:  # the status names the problem, not its usual causes
        sys.stdout.flush()
        hint = body.STATUS_HINTS[state]
        if job.precision == 64 and state in body.FLOAT32_HINTS:
            hint += "; " + body.FLOAT32_HINTS[state]
        print(fill(f"hconv: {state}: {hint}", sys.stderr), file=sys.stderr)
    if cancelled and not math.isnan(residual):  # the status says that digits were lost, not how many, nor what to do
        sys.stdout.flush()  # after the result on a shared terminal too
        print(fill(body.cancellation_hint(state, residual), sys.stderr), file=sys.stderr)
    if unread:
        sys.stdout.flush()
        print(fill(body.unread_note(unread), sys.stderr), file=sys.stderr)


@app.command("convert")
@friendly
@job_options(
    "method", "precision", "engine", *SCENE, *DEGENERATE, *COLUMNS, *DIALECT, "omega_unit", "keep_text", "prefix"
)
def convert_cmd(
    src: str = typer.Argument(
        ...,
        metavar="IN",
        help="input .csv or .parquet, or - for stdin; or a dataset: a directory, a quoted glob "
        "('data/*/*.parquet') or a URI (s3://bucket/prefix/)",
    ),
    dst: str = typer.Argument(
        ..., metavar="OUT", help="output .csv or .parquet, or - for stdout; for a dataset, a directory or a URI prefix"
    ),
    job: Job = JOB,  # the run options go here (job_options)
    from_: Fmt | None = typer.Option(None, "--from", help="input format; needed when IN is -"),
    to: OutFmt | None = typer.Option(
        None, "--to", help="output format; needed when OUT is -; for a dataset, default: each input's own"
    ),
    force: bool = typer.Option(
        False,
        "--force",
        help="overwrite OUT if it exists; for a dataset, convert every file again and overwrite "
        "files hconv did not write (it never deletes one)",
    ),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or summary on stderr"),
    strict: bool = typer.Option(False, "--strict", help="fail (exit 5, nothing written) if any row's status is not ok"),
    threads: int | None = typer.Option(
        None,
        "--threads",
        help="batches converted at once (in a dataset, small files, on as many worker processes "
        "from 300 files); default: the cores available, at most 4 (the output is the same for any number)",
    ),
    endpoint_url: str | None = typer.Option(
        None,
        "--endpoint-url",
        metavar="URL",
        help="an S3-compatible server for s3:// URIs (MinIO, Ceph, ...); "
        "default: AWS_ENDPOINT_URL_S3 or AWS_ENDPOINT_URL",
    ),
    cluster: str | None = typer.Option(
        None,
        "--cluster",
        metavar="local|tcp://HOST:PORT",
        help="convert a dataset's files on Dask (hconv's dask extra), one task per file: "
        "local starts worker processes here; tcp://HOST:PORT uses a running scheduler, whose "
        "workers must see IN and OUT (object storage, or a shared directory). --threads is then "
        "each worker's",
    ),
    workers: int | None = typer.Option(
        None,
        "--workers",
        help="with --cluster local: worker processes, each converting one file at a time; default: the cores available",
    ),
    cluster_timeout: float = typer.Option(
        10.0,
        "--cluster-timeout",
        metavar="SECONDS",
        help="how long a scheduler (and its first worker) may take to answer",
    ),
    task_rows: int | None = typer.Option(
        None,
        "--task-rows",
        metavar="N",
        help="with --cluster: a Parquet file of more than N rows (in 2 row groups or more) is converted "
        "by tasks of about N rows each, joined into the same output (the same bytes); "
        "default 0: one task per file (the join costs most of a conversion: docs/scaling.md)",
    ),
) -> None:
    """Convert each row of a CSV or Parquet file, or of each file of a dataset: OUT gets its columns, ω, diagnostics."""
    from hconv.tables import dataset, paths

    # the bar and the summary (hconv.report) are rich's, imported only for them: a quiet run never shows them

    files = dataset.is_dataset(src, dst)  # the library's rule (paths.convert_path): for the bar and summary

    def log(line: str) -> None:
        if not quiet or line.startswith("error: "):
            print(f"hconv: {line}", file=sys.stderr)

    run = functools.partial(
        paths.convert_path,
        src,
        dst,
        job=job,
        src_format=value_of(from_),
        dst_format=value_of(to),
        force=force,
        strict=strict,
        threads=threads,
        log=log,
        endpoint_url=endpoint_url,
        cluster=cluster,
        workers=workers,
        cluster_timeout=None if cluster is None and workers is None and task_rows is None else cluster_timeout,
        task_rows=task_rows,
    )
    if not files:
        interrupts.commit_settles()  # OUT in place ends the run: exit 0, never 130 with OUT there
    try:
        if sys.stderr.isatty() and not quiet and (files or dst != "-"):
            # for one file, its name: the path crowded out the bar
            from hconv import report

            description = "converting files" if files else f"converting {os.path.basename(src)}"
            with report.ProgressBar(description, counts=progress_counts(src, value_of(from_), files)) as bar:
                result = run(progress=bar)
        else:
            result = run()
    except dataset.DatasetError as exc:
        if not quiet:
            from hconv import report

            report.dataset_summary(exc.result, asked=job.engine)
        raise
    if quiet:
        return
    from hconv import report

    if isinstance(result, dataset.DatasetResult):
        report.dataset_summary(result, asked=job.engine)
    else:
        report.summary(result, asked=job.engine)


@app.command("diagnose")
@friendly
@job_options(
    *SCENE,
    *DEGENERATE,  # as convert: an engine's rods and point masses are diagnosed as it treated them
    *COLUMNS,
    *DIALECT,
    observed=True,
    help={"omega_frame": "the frame of wx_obs, wy_obs, wz_obs; default: the frame of H (another needs q)"},
)
def diagnose_cmd(
    src: str = typer.Argument(..., metavar="IN", help="input .csv or .parquet with H, I and wx_obs, wy_obs, wz_obs"),
    tol: float = typer.Option(1e-3, "--tol", help="a row is explained when |ω - ω_obs| / |ω_obs| <= this"),
    from_: Fmt | None = typer.Option(None, "--from", help="input format; needed when IN is -"),
    as_json: bool = typer.Option(False, "--json", help="print the ranking as JSON, best first"),
    job: Job = JOB,  # the run options go here (job_options)
) -> None:
    """Find which convention explains the ω your engine produced (columns wx_obs, wy_obs, wz_obs).

    The scene options say what you believe the file holds; every hypothesis is one mistake away."""
    from hconv.tools import diagnose

    d = diagnose.diagnose_file(src, src_format=value_of(from_), tol=tol, job=job)
    if as_json:
        print(json.dumps(d.to_json(), indent=1))
        return
    from hconv import report

    report.diagnosis_tables(d)


@app.command("compare")
@friendly
@job_options(*SCENE, *COLUMNS, *DIALECT)
def compare_cmd(
    src: str = typer.Argument(..., metavar="IN", help="input .csv or .parquet"),
    dst: str | None = typer.Argument(
        None, metavar="[OUT]", help="also write per-row figures here (.csv or .parquet, - for stdout)"
    ),
    from_: Fmt | None = typer.Option(None, "--from", help="input format; needed when IN is -"),
    to: OutFmt | None = typer.Option(None, "--to", help="output format; needed when OUT is -"),
    force: bool = typer.Option(False, "--force", help="overwrite OUT if it exists"),
    job: Job = JOB,  # the run options go here (job_options)
) -> None:
    """Run every method on the same rows: how far each is from exact, and where the shortcuts fail."""
    from hconv import report
    from hconv.tools import compare

    interrupts.commit_settles()  # OUT in place ends the run (hconv.interrupts)
    c = compare.compare_file(src, dst, src_format=value_of(from_), dst_format=value_of(to), force=force, job=job)
    from rich.console import Console

    report.comparison_tables(c, Console(stderr=True) if dst == "-" else None)


@app.command("bodies")
@friendly
def bodies_cmd(
    model: str = typer.Argument(..., metavar="MODEL", help="a URDF, SDF or MJCF (MuJoCo) model file"),
    dst: str | None = typer.Argument(
        None, metavar="[OUT]", help="write a row per body to .csv or .parquet (- for stdout); without it, a table"
    ),
    form: str | None = typer.Option(
        None,
        "--form",
        autocompletion=completes(body_forms),
        help="the inertia in OUT: sym6 (Ixx, Iyy, Izz, Ixy, Ixz, Iyz in the body frame; the default) or "
        "principal (I1, I2, I3 and qw, qx, qy, qz: principal axes to body frame)",
    ),
    to: OutFmt | None = typer.Option(None, "--to", help="output format; needed when OUT is -"),
    force: bool = typer.Option(False, "--force", help="overwrite OUT if it exists"),
    strict: bool = typer.Option(False, "--strict", help="exit 5 when a body is not ok"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no summary on stderr when writing OUT"),
    root: str | None = typer.Option(
        None, "--root", metavar="DIR", help="a folder holding the model's, within which MJCF includes may go"
    ),
) -> None:
    """Check the inertia of every body of a URDF, SDF or MJCF model; list them, or write them for hconv convert."""
    from hconv import modelview
    from hconv.tools import models

    # Options are checked before the model is read, and the same way with or without OUT: an
    # option that only shapes OUT is refused without it, as --endpoint-url is without a URI,
    # since ignoring it would let the user believe it did something.
    if form is not None:
        options.check_choice("form", form, models.OUTPUT_FORMS)
    if dst is None:
        given = [name for name, value in (("--form", form), ("--to", to), ("--force", force)) if value]
        if given:
            raise UsageError(
                f"{' and '.join(given)} {'is' if len(given) == 1 else 'are'} for OUT, which is not given; "
                "give OUT (- for stdout), or drop " + ("it" if len(given) == 1 else "them") + " to list the bodies"
            )
    m = models.read_model(model, root=root)
    bad = [b for b in m.bodies if b.status != "ok"]
    if strict and not m.bodies:  # a model with nothing to check passes no check
        raise StrictError(
            f"{model}: has no bodies to check (--strict); is it a fragment that another model includes?"
            + ("; nothing was written" if dst is not None else "")
        )
    if dst is None:
        modelview.show(m)
    elif not (strict and bad):  # as convert --strict: no output when a row is not ok
        interrupts.commit_settles()  # OUT in place ends the run (hconv.interrupts)
        models.write_bodies(m, dst, form=form or "sym6", dst_format=value_of(to), force=force)
        if not quiet:
            print(f"hconv bodies: {model} ({m.format}) to {dst}: {modelview.summary_line(m)}", file=sys.stderr)
            for note in m.notes:
                print(f"note: {note}", file=sys.stderr)
    if strict and bad:
        from hconv.tools.modelxml import clip

        first = ", ".join(f"{clip(b.name)} ({b.status})" for b in bad[:5])  # a name can be megabytes long
        raise StrictError(
            f"{len(bad)} of {len(m.bodies)} bodies are not ok (--strict): {first}"
            + ("; nothing was written" if dst is not None else "")
        )


@app.command("generate")
@friendly
def generate_cmd(
    dst: str = typer.Argument(..., metavar="OUT", help="output .csv or .parquet, or - for stdout"),
    rows: int = typer.Option(..., "--rows", "-n", help="number of bodies"),
    scene: str = typer.Option(
        "mix", "--scene", help=f"{', '.join(SCENES[:-1])} or {SCENES[-1]}", autocompletion=completes(lambda: SCENES)
    ),
    cond_max: float = typer.Option(
        1e3, "--cond-max", help="cond(I) is log-uniform from 1 to this (as the body kind allows)"
    ),
    seed: int = typer.Option(0, "--seed", help="the random draw; the same seed gives the same rows"),
    # FORMAT, its choices in the help: their list widened the metavar column until --seed's help wrapped
    to: OutFmt | None = typer.Option(
        None, "--to", metavar="FORMAT", help="output format, csv, parquet or arrow; needed when OUT is -"
    ),
    force: bool = typer.Option(False, "--force", help="overwrite OUT if it exists"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no summary on stderr"),
) -> None:
    """Write a synthetic scene of physically valid bodies with their known ω (w_true_x, ...)."""
    from hconv.tools import generate

    interrupts.commit_settles()  # OUT in place ends the run (hconv.interrupts)
    seconds = generate.generate_file(
        dst, rows, scene=scene, cond_max=cond_max, seed=seed, dst_format=value_of(to), force=force
    )
    rate = f", {rows / seconds:,.0f} rows/s" if seconds > 0 and rows else ""
    where = "stdout" if dst == "-" else dst
    if not quiet:
        print(f"hconv generate: {rows:,} rows to {where} in {seconds:.2f} s{rate}", file=sys.stderr)


@app.command("bench")
@friendly
def bench_cmd(
    rows: int = typer.Option(2_000_000, "--rows", "-n", min=1, help="rows per measurement"),
    repeats: int = typer.Option(
        3,
        "--repeats",
        min=1,
        help="each speed is the fastest of this many interleaved rounds (the calls users make: 3x as many)",
    ),
    memory_rows: int = typer.Option(
        0, "--memory-rows", min=0, help="also measure peak RSS converting this many rows (0: do not)"
    ),
    out: str | None = typer.Option("speed-vs-accuracy.png", "--out", "-o", help="chart file, .png or .svg"),
    no_chart: bool = typer.Option(False, "--no-chart", help="print the tables only"),
    json_out: str | None = typer.Option(None, "--json", help="also write every figure to this JSON file"),
    seed: int = typer.Option(0, "--seed"),
) -> None:
    """Measure speed and accuracy of every method and precision, and the speed targets."""
    from hconv import charts, report
    from hconv.tools import bench

    chart = charts.requested(out, no_chart)
    res = bench.run(
        rows=rows,
        repeats=repeats,
        seed=seed,
        memory_rows=memory_rows,
        log=lambda s: print(f"bench: {s}", file=sys.stderr),
    )
    report.bench_tables(res)
    if json_out:
        with open(json_out, "w") as f:
            json.dump(bench.to_json(res), f, indent=1, default=lambda x: None)
    if chart is not None:
        charts.speed_accuracy_chart(res, chart)
        print(f"chart written to {chart}", file=sys.stderr)


@app.command("engines")
@friendly
def engines_cmd(
    compile_now: bool = typer.Option(False, "--compile", hidden=True, help="nothing to do: kept for old instructions"),
) -> None:
    """List the engines that convert rows, and what auto picks."""
    from hconv.solve import engines

    if compile_now:  # the compiled engine is built when hconv is installed
        print("nothing to compile: the compiled engine is built when hconv is installed")
    listing(engines.listing())


@app.command("methods")
@friendly
def methods_cmd(as_json: bool = typer.Option(False, "--json", help="print a JSON list")) -> None:
    """List the methods: the unit of each result, whether it is exact, its cost and when it fails."""
    if as_json:
        from hconv.solve import methods

        print(json.dumps(methods.listing(), indent=1))
        return
    from hconv import report

    report.methods_table()


@app.command("stability")
@friendly
def stability_cmd(
    out: str | None = typer.Option("stability.png", "--out", "-o", help="chart file, .png or .svg"),
    no_chart: bool = typer.Option(False, "--no-chart", help="print the tables only"),
    rows: int = typer.Option(48, "--rows", min=4, help="bodies per sweep point"),
    seed: int = typer.Option(0, "--seed"),
    as_json: bool = typer.Option(False, "--json", help="print every sweep point as JSON instead of tables"),
) -> None:
    """Sweep every method over hard inputs and show where each stops being trustworthy."""
    from hconv import charts
    from hconv.tools import stability

    chart = charts.requested(out, no_chart)
    points = stability.run(rows=rows, seed=seed)
    if as_json:
        print(json.dumps(stability.to_json(points)))
    else:
        from hconv import report

        report.stability_tables(points, stability.SWEEPS)
    if chart is not None:
        charts.stability_chart(points, stability.SWEEPS, chart)
        print(f"chart written to {chart}", file=sys.stderr)


def _sigterm(signum: int, frame: object) -> None:  # let the atomic writer clean up as for Ctrl-C
    raise KeyboardInterrupt


def main() -> None:
    try:
        with streams.standard_streams():
            _main()
    except KeyboardInterrupt:  # after the command, before the exit
        print(f"hconv: error: {interrupts.interrupted()}", file=sys.stderr)
        sys.exit(130)
    finally:
        interrupts.ending()


def _main() -> None:
    if not interrupts.starting():  # in the hconv command SIGTERM ends it until friendly hands it over
        signal.signal(signal.SIGTERM, _sigterm)
    allocator.tune()
    units.PINT_WITHOUT_DASK = True
    if os.environ.get("_HCONV_COMPLETE"):  # the shell asks for completions (hconv --install-completion)
        from typer import completion

        completion.completion_init()
    try:
        rv = app(prog_name="hconv", standalone_mode=False)
    except Exception as exc:  # click's usage errors: one line, like every other hconv error
        if not (hasattr(exc, "format_message") and hasattr(exc, "exit_code")):
            raise
        usage_failure(exc)
    sys.exit(rv if isinstance(rv, int) else 0)


for _command in app.registered_commands:  # every command, as registered above: plain usage lines
    if _command.cls in (None, TyperCommand):
        _command.cls = _PlainUsage
