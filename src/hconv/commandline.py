"""What every ``hconv`` command shares: the run options and how a command takes them, the
parsing of values typed on the command line, and :func:`friendly`, which turns any failure into
one line and an exit code.

The run options are the library's :class:`~hconv.tables.job.Job`, spelled once here as the
command line spells them (:data:`JOB_OPTIONS`); a command lists the ones it offers with
:func:`job_options` and is handed the Job they make, checked once, when made. Choices are the
library's own tuples, never a second list.
"""

from __future__ import annotations

import copy
import functools
import inspect
import math
import os
import re
import sys
from collections.abc import Callable, Iterable
from enum import Enum
from typing import TYPE_CHECKING, Any, NoReturn

import typer

from hconv import errors, interrupts
from hconv.errors import HconvError, UsageError, quoted
from hconv.solve import options
from hconv.solve.engines import ENGINES
from hconv.solve.methods import METHODS
from hconv.tables.formats import FORMATS, WRITES

if TYPE_CHECKING:
    from hconv.tables.job import Job


def choice_type(name: str, values: Iterable[object]) -> Any:
    """A typer choice type whose values are the library's own tuple. Its members are ``str``
    subclasses; :func:`value_of` gives the plain string."""
    return Enum(name, {str(v): str(v) for v in values}, type=str)


def completes(values: Callable[[], Iterable[object]]) -> Callable[[str], list[str]]:
    """Shell completion for an option that is not a choice type (an int, or a choice checked by
    the library): the library's own values, taken only when a shell asks."""
    return lambda incomplete: [str(v) for v in values() if str(v).startswith(incomplete)]


def body_forms() -> Iterable[str]:
    from hconv.tools.models import OUTPUT_FORMS  # not at start-up: hconv one does not need it

    return OUTPUT_FORMS


def value_of(choice: str | None) -> str | None:
    return choice.value if isinstance(choice, Enum) else choice


if TYPE_CHECKING:  # for type checkers the choices are strings; typer needs the Enum at run time
    MethodName = str
    Fmt = str
    OutFmt = str
    Frame = str
    About = str
    Products = str
    Degenerate = str
    QuatOrder = str
    Engine = str
else:
    MethodName = choice_type("MethodName", METHODS)
    Fmt = choice_type("Fmt", FORMATS)
    OutFmt = choice_type("OutFmt", WRITES)  # --to: JSON lines is read only
    Frame = choice_type("Frame", options.FRAMES)
    About = choice_type("About", options.ABOUT)
    Products = choice_type("Products", options.PRODUCTS)
    Degenerate = choice_type("Degenerate", options.DEGENERATE_MODES)
    QuatOrder = choice_type("QuatOrder", options.QUAT_ORDERS)
    Engine = choice_type("Engine", ENGINES)

#: Every option of the run configuration (hconv.tables.job.Job), as the command line spells it:
#: Job field (or Conventions field) -> (type, typer option). Commands take theirs through
#: :func:`job_options`, which builds the Job in one place.
JOB_OPTIONS = {
    # The long choice lists get a metavar and are listed in the help text, where they wrap between
    # names; as the metavar they were split mid-name at 80 columns.
    "method": (
        MethodName,
        typer.Option("exact", "--method", metavar="METHOD", help=f"{', '.join(METHODS)} (see hconv methods)"),
    ),
    "precision": (
        int,
        typer.Option(
            64,
            "--precision",
            help="64 or 32: the dtype the method computes in",
            autocompletion=completes(lambda: options.PRECISIONS),
        ),
    ),
    "frame": (
        Frame,
        typer.Option("world", "--frame", help="the frame of H (and r, v): world, or body (the frame of q's body)"),
    ),
    "omega_frame": (
        Frame | None,
        typer.Option(None, "--omega-frame", help="the frame of ω; default: the frame of H (another needs q)"),
    ),
    "about": (
        About,
        typer.Option(
            "same",
            "--about",
            help="same: I and H about one point; pivot: I about the centre of "
            "mass, H about a fixed pivot (needs m, r); free: H about an origin (needs m, r, v)",
        ),
    ),
    "products": (
        Products,
        typer.Option(
            "tensor",
            "--products",
            help="tensor: Ixy = -∫xy dm (hconv, URDF, engines); positive: Pxy = +∫xy dm (CAD reports)",
        ),
    ),
    "degenerate": (
        Degenerate,
        typer.Option(
            "error",
            "--degenerate",
            help="zero principal moments (rods, point masses): "
            "error (status singular), pinv or lock (no rotation about the dropped axis)",
        ),
    ),
    "degenerate_rtol": (
        float | None,
        typer.Option(
            None,
            "--degenerate-rtol",
            help="a principal moment <= this × the "
            "trace counts as zero; default: singular in the working precision "
            "(about 1e-15 in float64)",
        ),
    ),
    "mapping": (
        list[str] | None,
        typer.Option(None, "--map", help="NAME=COLUMN: read hconv's NAME from COLUMN (repeatable, or comma-separated)"),
    ),
    "unit_options": (
        list[str] | None,
        typer.Option(
            None,
            "--unit",
            help="COLUMN=UNIT or SET=UNIT (H, I, r, m, v, w_obs), e.g. I=g*cm**2 (repeatable)",
        ),
    ),
    "omega_unit": (str, typer.Option("rad/s", "--omega-unit", help="unit of ω: rad/s, deg/s, rpm, ...")),
    "engine": (
        Engine,
        typer.Option(
            "auto",
            "--engine",
            metavar="ENGINE",
            help="auto (for files: numpy; see hconv engines), compiled or numpy (the reference)",
        ),
    ),
    "quat_order": (
        QuatOrder,
        typer.Option("wxyz", "--quat-order", help="order of a 4-value list column q (named columns need none)"),
    ),
    "keep_text": (
        bool,
        typer.Option(
            False,
            "--keep-text",
            help="CSV to Parquet: keep the columns hconv does not use as text; "
            "default: typed as pyarrow would (numbers, booleans, dates), except where that changes a value",
        ),
    ),
    # A CSV's dialect is run configuration, not the command's: a dataset's manifest records it
    # (a file read with another delimiter gives another output), and Python passes it in the Job.
    "delimiter": (
        str | None,
        typer.Option(
            None,
            "--delimiter",
            metavar="CHAR",
            help="a CSV input's delimiter: , ; tab or |; default: sniffed from the file (tab for .tsv, .tab)",
        ),
    ),
    "decimal": (
        str | None,
        typer.Option(
            None,
            "--decimal",
            metavar="MARK",
            help="a CSV input's decimal mark: . or , (the latter with another delimiter); default: sniffed",
        ),
    ),
    "prefix": (
        str,
        typer.Option(
            "",
            "--prefix",
            metavar="P",
            help="put P before the name of every column hconv appends (wx → Pwx, status → Pstatus), "
            "for an input that already has one of them",
        ),
    ),
}
_CONVENTIONS = ("frame", "omega_frame", "about", "products", "degenerate", "degenerate_rtol")
SCENE = ("frame", "omega_frame", "about", "products")
DEGENERATE = ("degenerate", "degenerate_rtol")
COLUMNS = ("mapping", "unit_options", "quat_order")
DIALECT = ("delimiter", "decimal")


#: The default of a command's ``job`` parameter, which :func:`job_options` always fills in.
JOB: Any = None


def job_options(*names: str, help: dict | None = None, **fixed: Any) -> Callable[[Callable], Callable]:
    """Give a command the Job options ``names``, shown in that order where its ``job`` parameter
    stands, and call it with the :class:`~hconv.tables.job.Job` they make as ``job``. ``help``
    rewords an option for this command; ``fixed`` sets Job fields the command does not offer.
    The Job checks itself when made, so every command's options are checked once, in one place."""

    def option(n: str) -> inspect.Parameter:
        info = JOB_OPTIONS[n][1]
        if help and n in help:
            info = copy.copy(info)
            info.help = help[n]
        return inspect.Parameter(n, inspect.Parameter.KEYWORD_ONLY, default=info, annotation=JOB_OPTIONS[n][0])

    def deco(fn: Callable) -> Callable:
        sig = inspect.signature(fn)
        params = list(sig.parameters.values())
        at = [p.name for p in params].index("job")
        params = params[:at] + [option(n) for n in names] + params[at + 1 :]
        kinds = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY) if k > at else p for k, p in enumerate(params)]

        @functools.wraps(fn)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            given = {n: kwargs.pop(n) for n in names}
            return fn(*args, job=_make_job(given, fixed), **kwargs)

        wrapper.__signature__ = sig.replace(parameters=kinds)  # type: ignore[attr-defined]
        wrapper.__annotations__ = {p.name: p.annotation for p in kinds}
        return wrapper

    return deco


def _make_job(given: dict, fixed: dict) -> Job:
    from hconv.tables.job import Job

    values: dict[str, Any] = {n: value_of(v) for n, v in given.items()}
    if "mapping" in values:
        values["mapping"] = pairs("--map", values["mapping"])
    if "unit_options" in values:
        values["unit_options"] = pairs("--unit", values["unit_options"])
    conv = options.Conventions(**{n: values.pop(n) for n in _CONVENTIONS if n in values})
    return Job(conventions=conv, **values, **fixed)


def _fail(msg: str, code: int) -> None:
    interrupts.settle()  # the run is failing: an interrupt now would not change what it leaves
    print(f"hconv: error: {msg}", file=sys.stderr)
    raise typer.Exit(code)


def friendly(fn: Callable) -> Callable:
    """Turn hconv's errors, interrupts and surprises into one line and an exit code, never a traceback."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            interrupts.hand_over()  # from here an interrupt is caught below, and cleans up
            with errors.command_line():
                rv = fn(*args, **kwargs)
                sys.stdout.flush()  # here, where a full stdout is the command's failure, named
            interrupts.settle()  # done: a late interrupt changes nothing (hconv.interrupts)
            interrupts.point("returned")
            return rv
        except HconvError as exc:
            _fail(str(exc), exc.exit_code)
        except KeyboardInterrupt as exc:  # a dataset run says what it kept (hconv.tables.dataset)
            _fail(str(exc) or interrupts.interrupted(), 130)
        except BrokenPipeError:  # the reader stopped early (`| head`): its choice, not a failure
            interrupts.settle()
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            raise typer.Exit(0) from None
        except OSError as exc:
            kept = "the rows before it went to stdout" if interrupts.went_to_stdout() else "nothing was written"
            _fail(f"{exc.filename or 'output'}: {exc.strerror or exc}; {kept}", 4)
        except (typer.Exit, typer.Abort):
            interrupts.settle()
            raise
        except Exception as exc:  # noqa: BLE001 - the promise is: no traceback
            if os.environ.get("HCONV_DEBUG"):
                raise
            _fail(
                f"internal error: {type(exc).__name__}: {exc} "
                "(set HCONV_DEBUG=1 for the traceback, and please report it)",
                1,
            )

    @functools.wraps(fn)
    def guarded(*args: Any, **kwargs: Any) -> Any:
        try:
            return wrapper(*args, **kwargs)
        except KeyboardInterrupt:  # one that landed while an error was being reported: it wrote nothing
            _fail(interrupts.interrupted(), 130)

    return guarded


def numbers(option: str, text: str, allowed: tuple[int, ...]) -> list[float]:
    """The comma-separated numbers of ``option``'s ``text``, as many as one of ``allowed``.

    The numbers may stand in brackets, as Python or JSON prints them (``[1, 2, 3]``, ``(1, 2, 3)``),
    and nine may be a matrix's rows (``[[1,0,0],[0,1,0],[0,0,1]]``, read row-major). Commas
    separate them, always: ``0 1`` is an error, never the number 01."""
    flat, rows = _bracketed(option, text)
    parts = [p.strip() for p in flat.split(",")]
    if "" in parts:
        raise UsageError(f"{option} has an empty value in {text!r}; give comma-separated numbers, like 1,2,3")
    grouped = next((p for p in parts if "_" in p), None)
    if grouped is not None:  # Python's float() reads 1_0 as 10: a typo for 1,0 would pass unseen
        raise UsageError(
            f"{option}: {grouped!r} in {text!r} has an underscore; write {grouped.replace('_', '')!r} "
            f"for that number, or {grouped.replace('_', ',')!r} for two"
        )
    try:
        values = [float(v) for v in parts]
    except ValueError:
        raise UsageError(f"{option} takes comma-separated numbers, got {text!r}") from None
    if rows is not None and (len(rows) != 3 or any(k != 3 for k in rows) or 9 not in allowed):
        raise UsageError(
            f"{option} takes nested brackets only for an inertia matrix, three rows of three numbers, got {text!r}"
        )
    if len(values) not in allowed:
        counts = ", ".join(str(k) for k in allowed[:-1]) + (" or " if len(allowed) > 1 else "") + str(allowed[-1])
        raise UsageError(f"{option} takes {counts} comma-separated numbers, got {len(values)} in {text!r}")
    return values


_CLOSE = {"[": "]", "(": ")"}
#: Two numbers with only spaces between them: ``1. 0.``, as numpy prints an array.
_SPACED = re.compile(r"[0-9.]\s+[-+0-9.]")


def _bracketed(option: str, text: str) -> tuple[str, list[int] | None]:
    """``text`` without its brackets, and the numbers of each inner row when it is a list of lists
    (None when it is not nested); UsageError for brackets that do not pair, or numbers beside rows."""
    t = text.strip()
    if not t or t[0] not in _CLOSE:
        if any(c in t for c in "[]()"):
            raise UsageError(f"{option}: the brackets in {text!r} do not pair; give 1,2,3 or [1,2,3]")
        return text, None
    bad = UsageError(f"{option}: the brackets in {text!r} do not pair; give 1,2,3 or [1,2,3]")
    if t[-1] != _CLOSE[t[0]]:
        raise bad
    inner = t[1:-1].strip()
    if not inner or inner[0] not in _CLOSE:
        if any(c in inner for c in "[]()"):
            raise bad
        return inner, None
    rows, flat = [], []
    at = 0
    while at < len(inner):
        opening = inner[at]
        if opening not in _CLOSE:
            raise UsageError(f"{option}: {text!r} mixes numbers and rows in brackets; give every row in brackets")
        end = inner.find(_CLOSE[opening], at)
        row = inner[at + 1 : end] if end > 0 else "["
        if end < 0 or any(c in row for c in "[]()"):
            raise bad
        rows.append(len(row.split(",")))
        flat.append(row)
        rest = inner[end + 1 :].lstrip()
        if rest and not rest.startswith(","):
            if _SPACED.search(text):  # numpy prints a matrix so: [[1. 0. 0.]\n [0. 2. 0.] ...]
                raise UsageError(
                    f"{option}: {text!r} needs commas between the numbers of each row and between the rows, "
                    "like [[1,0,0],[0,2,0],[0,0,3]] (numpy prints none: give the matrix's .tolist())"
                )
            raise UsageError(f"{option}: {text!r} needs a comma between the rows")
        at = len(inner) - len(rest[1:].lstrip()) if rest else len(inner)
    return ",".join(flat), rows


def extra_arguments(command: str, rest: list[str]) -> str:
    """The one line for arguments ``command`` did not take: their count and the fix, then the
    first of them (an unquoted glob of 99 files would otherwise be listed whole)."""
    n = len(rest)
    what = f"{n} extra argument{'s' if n > 1 else ''}"
    if command.endswith(" convert"):  # the shell expanded a glob: hconv expands one in quotes
        what += " after IN and OUT: for several files, quote the glob so that hconv expands it, or give their directory"
    return f"{what} ({'the first: ' if n > 1 else ''}{quoted(rest[0])})"


def json_number(x: float) -> float | None:
    """``x``, or None where it is NaN or infinite: standard JSON has neither."""
    return x if math.isfinite(x) else None


def pairs(option: str, items: list[str] | None) -> tuple:
    """``NAME=VALUE`` items (repeatable, each possibly comma-separated) as a tuple of pairs."""
    pairs = []
    for item in items or ():
        for part in item.split(",") if option == "--map" else [item]:
            name, eq, value = part.partition("=")
            if not eq or not name.strip() or not value.strip():
                form = "NAME=COLUMN" if option == "--map" else "COLUMN=UNIT or SET=UNIT"
                raise UsageError(f"{option} takes {form}, got {part!r}")
            pairs.append((name.strip(), value.strip()))
    return tuple(pairs)


def width(stream: Any) -> int:
    """The width text for ``stream`` wraps at: 80 columns, or a narrower terminal's."""
    import shutil

    return min(80, shutil.get_terminal_size().columns) if stream.isatty() else 80


def fill(text: str, stream: Any, indent: str = "  ", first: str = "") -> str:
    """``text`` wrapped at spaces to ``stream``'s width, after ``first`` and with later lines
    indented by ``indent``, with no trailing spaces. A no-break space keeps a number with its unit."""
    import textwrap

    lines = textwrap.fill(text, width(stream), initial_indent=first, subsequent_indent=indent, break_on_hyphens=False)
    return lines.replace("\xa0", " ")


def listing(entries: list[tuple[str, ...]]) -> None:
    """Print ``(name, paragraph, ...)`` entries as a name column beside paragraphs wrapped at
    spaces to 80 columns, or to a narrower terminal, so that no line is cut or runs over. A
    no-break space keeps a number with its unit."""
    width = max(len(name) for name, *_ in entries) + 2
    for name, *paragraphs in entries:
        for k, text in enumerate(paragraphs):
            first = f"{name:<{width}}" if k == 0 else " " * width
            print(fill(text, sys.stdout, " " * width, first))


def usage_failure(exc: Any) -> NoReturn:
    """Exit on click's usage error ``exc`` (it has ``format_message`` and ``exit_code``) with one
    line, like every other hconv error, naming the command's help; a command that needs arguments
    and got none prints its help and exits 0."""
    interrupts.settle()  # the exit code is decided: an interrupt now changes nothing
    ctx = getattr(exc, "ctx", None)
    if type(exc).__name__ == "NoArgsIsHelpError" and ctx is not None:
        print(ctx.get_help())
        sys.exit(0)
    command = getattr(ctx, "command_path", "hconv")
    message = " ".join(exc.format_message().split())
    # click quotes the value it refused whole: a pasted page would be echoed whole
    message = re.sub(rf"'([^']{{{errors.ECHOED + 1},}})'", lambda m: errors.quoted(m.group(1), errors.ECHOED), message)
    print(f"hconv: error: {message} (see '{command} --help')", file=sys.stderr)
    sys.exit(exc.exit_code)


def progress_counts(src: str, fmt: str | None, files: bool) -> str:
    """What a convert run's progress counts: a CSV file's bytes read, else rows or files."""
    from hconv.tables.sniff import format_of

    if files:
        return "files"
    try:
        return "bytes" if format_of(src, fmt, "src_format") == "csv" else "rows"
    except HconvError:  # the run says what is wrong with the input
        return "rows"
