"""The options of a conversion: their choices, and the one check of each.

Every entry point (``hconv.convert``, :class:`Conventions`, :class:`hconv.tables.job.Job` and so
the CLI) validates an option by calling the function here, so that a bad value gets the same
:class:`~hconv.errors.UsageError` (a ``ValueError``) and the same message wherever it comes in.
The CLI builds its choices from the tuples here. Checks take an option by its Python keyword,
and messages spell it as the reader does (:func:`hconv.errors.option`): ``--degenerate-rtol``
on the command line, ``degenerate_rtol=`` in Python.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, TypeVar

import numpy as np

from hconv.errors import UsageError, option
from hconv.solve import methods

#: --precision: the dtype the method computes in (diagnostics are always float64).
DTYPES = {64: np.float64, 32: np.float32}
PRECISIONS = tuple(DTYPES)
#: --degenerate: what zero principal moments get (see hconv.solve.convert).
DEGENERATE_MODES = ("error", "pinv", "lock")
#: --frame and --omega-frame.
FRAMES = ("world", "body")
#: --about: the point H is taken about, relative to the point of I.
ABOUT = ("same", "pivot", "free")
#: --products: tensor entries (-∫xy dm) or positive products of inertia (+∫xy dm).
PRODUCTS = ("tensor", "positive")
#: --quat-order: the order of a 4-value list column q.
QUAT_ORDERS = ("wxyz", "xyzw")


def check_choice(name: str, value: object, allowed: tuple) -> None:
    """UsageError unless ``value`` of option ``name`` (its Python keyword) is one of ``allowed``."""
    if value not in allowed:
        raise UsageError(f"{option(name)} must be one of {', '.join(map(str, allowed))}, got {value!r}")


def check_precision(precision: object) -> None:
    if precision not in PRECISIONS:
        raise UsageError(f"{option('precision')} must be 64 or 32, got {precision!r}")


def check_degenerate(mode: str, rtol: float | None, method: str | methods.Method | None = None) -> None:
    """The degenerate mode and threshold and, given a method, that a mode other than error is
    only asked of the exact family."""
    check_choice("degenerate", mode, DEGENERATE_MODES)
    if rtol is not None and (isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not 0 <= rtol < 1):
        raise UsageError(f"{option('degenerate_rtol')} must be at least 0 and below 1, got {rtol!r}")
    m = None if method is None else methods.get(method)
    if m is not None and mode != "error" and not m.exact:
        raise UsageError(f"{option('degenerate', mode)} applies to the exact methods, not to {m.name!r}")


@dataclass(frozen=True)
class Conventions:
    """How a scene stores its bodies; checked when made. Defaults: hconv's own conventions (see
    :mod:`hconv.kernels.inertia` and :mod:`hconv.kernels.frames`)."""

    frame: str = "world"  #: the frame of H, r and v: world or body (body needs no q)
    omega_frame: str | None = None  #: the frame of ω; None: the frame of H
    about: str = "same"  #: same (I and H about one point), pivot or free
    products: str = "tensor"  #: tensor (Ixy = -∫xy dm) or positive (Pxy = +∫xy dm)
    degenerate: str = "error"  #: error, pinv or lock
    degenerate_rtol: float | None = None  #: a moment <= this × trace counts as zero

    def __post_init__(self) -> None:
        check_choice("frame", self.frame, FRAMES)
        check_choice("omega_frame", self.w_frame, FRAMES)
        check_choice("about", self.about, ABOUT)
        check_choice("products", self.products, PRODUCTS)
        check_degenerate(self.degenerate, self.degenerate_rtol)

    @property
    def w_frame(self) -> str:
        """The frame ω is expressed in."""
        return self.omega_frame or self.frame

    def needs(self, method: str | methods.Method) -> dict:
        """The sets, besides H and I, that a run with ``method`` cannot do without, each with
        the reason."""
        need = {}
        m = methods.get(method)
        if m.needs_r:
            need["r"] = f"method {m.name!r} needs the offset r"
        if self.about == "pivot":
            need.setdefault("r", f"{option('about', 'pivot')} needs r, the centre of mass relative to the pivot")
            need["m"] = f"{option('about', 'pivot')} needs the mass m"
        if self.about == "free":
            need.setdefault("r", f"{option('about', 'free')} needs r, the centre of mass relative to the origin of H")
            need["m"] = f"{option('about', 'free')} needs the mass m"
            need["v"] = f"{option('about', 'free')} needs v, the velocity of the centre of mass"
        if self.w_frame != self.frame:
            need["q"] = "ω in another frame than H needs the orientation q"
        return need


@dataclass(frozen=True)
class Options:
    """What a solve needs besides the data, checked when made: the method, the precision, the
    diagnostics, the scene's :class:`Conventions` and the engine. ``hconv.convert`` takes it as
    ``job=`` (or its fields as keywords, folded by :func:`configure`); the table-level run
    configuration, :class:`hconv.tables.job.Job`, extends it with columns, units and formats."""

    method: str | methods.Method = "exact"
    precision: int = 64
    diagnostics: bool = True  #: False skips the residual, the costliest diagnostic
    conventions: Conventions = field(default_factory=Conventions)
    engine: str = "auto"  #: auto, compiled or numpy (hconv.solve.engines)

    def __post_init__(self) -> None:
        from hconv.solve import engines  # engines reads this module's choices

        methods.get(self.method)
        check_precision(self.precision)
        if not isinstance(self.conventions, Conventions):
            raise UsageError(f"conventions must be a Conventions, got {type(self.conventions).__name__}")
        check_degenerate(self.conventions.degenerate, self.conventions.degenerate_rtol, self.method)
        engines.check_engine(self.engine)
        if isinstance(self.diagnostics, np.bool_):  # a numpy truth is a truth (as numpy's own APIs take it)
            object.__setattr__(self, "diagnostics", bool(self.diagnostics))
        if not isinstance(self.diagnostics, bool):  # diagnostics='no' would read as True
            raise UsageError(f"{option('diagnostics')} must be True or False, got {self.diagnostics!r}")


#: The keywords :func:`configure` folds into the run configuration's :class:`Conventions`.
CONVENTION_KEYWORDS = tuple(f.name for f in fields(Conventions))

O = TypeVar("O", bound=Options)


def configure(kind: type[O], caller: str, job: object, **keywords: Any) -> O:
    """The run configuration of entry point ``caller``: ``job`` whole, or the ``keywords`` it was
    given (None: not given; those naming a :class:`Conventions` field go into its conventions)
    made into a ``kind``; never both, so that neither silently wins. The one rule of every entry
    point that takes ``job=`` (``hconv.convert``, ``convert_body``, ``convert_table``,
    ``output_schema``, ``convert_file``, ``convert_dataset``, ``convert_path``). An
    :class:`Options` given where a richer ``kind`` (a Job) is wanted becomes one, with its
    other fields at their defaults."""
    given = {name: value for name, value in keywords.items() if value is not None}
    if job is None:
        conventions = {name: given.pop(name) for name in CONVENTION_KEYWORDS if name in given}
        if conventions:
            given["conventions"] = Conventions(**conventions)
        return kind(**given)
    if not isinstance(job, Options):
        hint = f"make one with hconv.{kind.__name__}(...)"
        if isinstance(job, str) and job in methods.METHODS:
            hint = f"for the method alone pass {option('method', job)}"
        raise UsageError(f"job takes a hconv.{kind.__name__}, got {job!r} ({type(job).__name__}); {hint}")
    if given:
        names = list(given)
        first = names[0]
        where = f"conventions=hconv.Conventions({first}=...)" if first in CONVENTION_KEYWORDS else f"{first}=..."
        raise UsageError(
            f"{caller}: {', '.join(names)} given beside job=; put them in the {kind.__name__} "
            f"({kind.__name__}({where})), which then holds the whole run configuration"
        )
    if not isinstance(job, kind):  # solve-level options where a Job is wanted: the Job they make
        return kind(**{f.name: getattr(job, f.name) for f in fields(Options)})
    return job
