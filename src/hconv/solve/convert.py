"""``convert``: H and I (and r) to ω with a chosen method, plus per-row diagnostics.

Shapes: ``H`` is ``(N, 3)`` [kg·m²/s]; ``I`` is ``(N, 6)`` as (Ixx, Iyy, Izz, Ixy, Ixz, Iyz),
``(N, 3, 3)`` or ``(N, 3)`` principal/diagonal moments [kg·m²]; ``r`` is ``(N, 3)`` [m]. One body
may be given as ``H`` of shape ``(3,)`` with ``I`` of shape ``(6,)``, ``(3, 3)`` or ``(3,)``; its
result comes back unstacked. These stacks are read into hconv's column layout at the edge
(:func:`hconv.solve.forms.from_array`); :func:`convert_columns` takes that layout directly.
Conventions are those of :mod:`hconv.kernels.inertia`.

Diagnostics per row:

* ``residual`` = ‖ω - I⁻¹H‖ / ‖I⁻¹H‖, against a reference computed from the float64 inputs:
  iterative refinement with a residual in double the precision, within one rounding
  (≤ 1·eps, measured) to cond ≈ 1e13 (tested against mpmath and exact rational solves). For the exact family the
  refinement starts from the method's own answer, so its first correction is that answer's
  error (a ``refined`` answer that stopped too early shows as such). For the document methods
  it compares their number (in m²/s) with I⁻¹H (in rad/s).
* ``cond``: the 2-norm condition number of I, |moment|max / |moment|min.
* ``status``: see :mod:`hconv.solve.status`.

The numpy engine converts in blocks of rows: a run the row engines cover by
:mod:`hconv.solve.vectorrows` (the row code's arithmetic, a block at a time), every other run,
and the rows that module leaves, by :func:`_convert_block`; a call from the main thread shares
its blocks among the cores (:func:`block_threads`). docs/engines.md has the why and the figures.
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, fields, replace
from itertools import chain
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hconv.errors import UsageError, option
from hconv.kernels import frames, linsolve
from hconv.kernels.inertia import Sym3, max_abs, pinv_moments, principal_frame
from hconv.kernels.metrics import relative_error
from hconv.kernels.spectrum import eigenvalues
from hconv.solve import engines, forms, methods, options, rows, status, units, vectorrows

#: Rows per kernel block: small enough that a block's temporaries stay in cache.
BLOCK_ROWS = 16384
#: The numpy engine converts the runs the row engines cover by :mod:`hconv.solve.vectorrows`
#: (False: every row by the general block converter, which tests compare it with).
COMMON_PATH = True
#: Rows per block when a call's blocks run on threads: fewer numpy calls than BLOCK_ROWS, so
#: less waiting on the GIL, which each call takes between its operations (docs/engines.md).
THREADED_BLOCK_ROWS = 65536
#: Most threads one call's blocks run on: beyond a few, the Python between numpy's operations
#: (which holds the GIL) sets the pace.
MAX_BLOCK_THREADS = 4


@dataclass(frozen=True)
class Result:
    """ω and its diagnostics. Arrays are stacked ``(N, ...)`` or, for one body, unstacked."""

    w: np.ndarray  #: (N, 3) or (3,), in ``unit``; a pint Quantity of them when given Quantities
    residual: np.ndarray | None  #: (N,) or scalar; None when diagnostics were off
    cond: np.ndarray  #: (N,) or scalar
    status_code: np.ndarray  #: (N,) uint8, or scalar; names in hconv.solve.status.STATUSES
    unit: str  #: unit of w: "rad/s" or "m^2/s"
    method: str
    #: with degenerate="pinv"/"lock": the dropped axis, (N, 3) unit vectors, NaN where none or
    #: more than one was dropped; and how many axes were dropped, (N,) int8
    null_axis: np.ndarray | None = None
    null_dim: np.ndarray | None = None
    #: the engine that converted the rows: numpy, numba or python (hconv.solve.engines)
    engine: str = "numpy"
    #: --about free only: (N,) bool, rows on which taking r × m·v out of H lost digits by the bound
    #: that sets the status cancellation, also where a status before it holds the row (a row has
    #: one status); None otherwise (hconv.solve.bodies)
    cancelled: np.ndarray | None = None

    @property
    def status(self) -> str | np.ndarray:
        """Status names, shape ``(N,)``, or one name for one body."""
        s = status.names(np.asarray(self.status_code))
        return str(s) if s.ndim == 0 else s

    def counts(self) -> dict[str, int]:
        """Rows per status, in precedence order."""
        return status.counts(np.atleast_1d(self.status_code))


def _as_float(name: str, given_a: ArrayLike, quantities: list[type] | None = None) -> np.ndarray:
    """Argument ``name`` (H, I or r) as float64 numbers in SI, appending to ``quantities`` the
    class of the pint Quantity it was, if it was one. The rule for numbers that carry a unit or
    a mask is in the docstring of :func:`convert`; :mod:`hconv.solve.units` finds the units."""
    a: Any = given_a  # an array, or an object that holds one with a unit or a mask
    scale = 1.0
    if type(a) is not np.ndarray:  # a plain ndarray (the common case) holds bare numbers
        a, scale = _unwrapped(name, a, quantities)
    mask = np.ma.getmaskarray(a) if isinstance(a, np.ma.MaskedArray) else None
    try:
        given = np.asarray(np.ma.getdata(a) if mask is not None else a)
        if given.dtype.kind not in "iuf":  # float64 would drop an imaginary part, parse text, count truths
            if given.dtype.kind == "O":
                _refuse_units_numpy_drops(name, list(given.flat))
            raise UsageError(
                f"{name} must hold real numbers, got {_dtype_text(given.dtype)}; {_dtype_fix(name, given.dtype)}"
            )
        out = np.asarray(given, dtype=np.float64)
    except UsageError:
        raise
    except (TypeError, ValueError) as exc:
        if "inhomogeneous" in str(exc):  # numpy's words for nested sequences of unequal lengths
            raise ValueError(f"{name} must be a rectangular array of numbers: its rows differ in length") from None
        raise ValueError(f"{name} must be numeric: {exc}") from None
    if scale != 1.0:
        out = out * scale
    if mask is not None and mask.any():
        out = np.where(mask, np.nan, out)  # a new array: the caller's is never written
    return out


def _unwrapped(name: str, a: Any, quantities: list[type] | None) -> tuple[Any, float]:
    """The numbers that ``a`` holds and the factor from their unit to SI: a pint Quantity's
    magnitude (its class appended to ``quantities``), an xarray DataArray's values in its
    ``units``; UsageError for numbers whose unit or mask numpy would drop and hconv does not read."""
    scale = 1.0
    if units.is_xarray(a):
        unit, data = units.labelled_unit(a), getattr(a, "data", None)
        if units.is_pint(data):
            a = data  # pint-xarray: the Quantity holds the unit
        elif unit is not None:
            scale, a = units.factor(name, unit, f"{name}.attrs['units']"), a.values
    if units.is_pint(a):
        if quantities is not None:
            quantities.append(type(a))
        scale, a = units.pint_factor(name, a, name), a.magnitude
    _refuse_units_numpy_drops(name, a)
    return a, scale


def _refuse_units_numpy_drops(name: str, a: object) -> None:
    """UsageError when ``a`` carries a unit hconv does not read, or is a list or tuple holding
    numbers with units or masks, which ``np.asarray`` would make bare numbers of."""
    what = units.foreign(a)
    if what is not None:
        si = units.SI[name]
        raise UsageError(
            f"{name} is {what}, which hconv does not read; pass a pint Quantity "
            f"or plain numbers in {si} (e.g. {name}.to_value({si!r}))"
        )
    if isinstance(a, (list, tuple)):
        held = _held(a)
        if held is not None:
            raise UsageError(f"{name} holds {held}")


def _held(items: list | tuple) -> str | None:
    """What the first item of nested ``items`` that carries a unit or a mask is, and the fix;
    None when there is none. Looked at a nesting level at a time, by the set of the items' types,
    which costs plain numbers (the common case) less than ``np.asarray`` on them
    (docs/measurements.md)."""
    level, kinds = items, set(map(type, items))
    while True:
        for x in level if kinds - _PLAIN else ():
            found = None if type(x) in _PLAIN else _carried(x)
            if found is not None:
                return found
        if not kinds & _NESTED:
            return None
        inner = level if kinds <= _NESTED else [x for x in level if type(x) in _NESTED]
        kinds = set(map(type, chain.from_iterable(inner)))
        if kinds <= _PLAIN - _NESTED:  # plain numbers all: the level need not be built
            return None
        level = list(chain.from_iterable(inner))


def _carried(x: object) -> str | None:
    """What item ``x`` of a list is, and the fix, when numpy would drop its unit or mask."""
    if units.is_pint(x):
        return (
            "pint Quantities, whose units numpy would drop; pass one Quantity of the whole array, "
            "e.g. ureg.Quantity(np.array(values), 'g*cm**2/s')"
        )
    if isinstance(x, np.ma.MaskedArray):
        return "masked arrays, whose masks numpy would drop; pass one masked array, e.g. np.ma.stack(...)"
    if units.labelled_unit(x) is not None:
        return "xarray DataArrays with units, which numpy would drop; pass one DataArray"
    what = units.foreign(x)
    return (
        None if what is None else f"{what} and others like it, whose units numpy would drop; pass plain numbers in SI"
    )


#: Lists and tuples: :func:`_held` looks inside them.
_NESTED = frozenset({list, tuple})
#: Types that hold a plain number: the items of a list that :func:`_held` passes at once.
_PLAIN = frozenset({float, int, np.float64, np.float32, np.int64, np.int32, np.ndarray, list, tuple})


def _count(k: int, noun: str) -> str:
    return f"{k} {noun}" + ("" if k == 1 else "s")


def _dtype_text(dtype: np.dtype) -> str:
    kinds = {"b": "booleans", "c": "complex", "U": "text", "S": "bytes", "O": "Python objects"}
    return f"{kinds.get(dtype.kind, 'values')} (dtype {dtype})"


def _dtype_fix(name: str, dtype: np.dtype) -> str:
    if dtype.kind == "c":
        return f"pass {name}.real if the imaginary part is meant to be zero"
    return f"convert it to numbers first, e.g. np.asarray({name}, dtype=float)"


def convert(
    H: ArrayLike,
    I: ArrayLike,
    r: ArrayLike | None = None,
    *,
    method: str | methods.Method | None = None,
    precision: int | None = None,
    diagnostics: bool | None = None,
    degenerate: str | None = None,
    degenerate_rtol: float | None = None,
    extra_k: float = 0.0,
    engine: str | None = None,
    job: options.Options | None = None,
) -> Result:
    """Convert angular momentum to angular velocity with ``method`` (a name in
    :data:`hconv.METHODS`, or one of its entries; default exact); see the module docstring.

    The run configuration is ``job`` (a :class:`hconv.Options`, or a :class:`hconv.Job` whose
    table-level fields are at their defaults), or the keywords below, folded into one by
    :func:`hconv.solve.options.configure`; not both. H and I are taken as given, about one point
    and in one frame: the scene conventions ``about``, ``products`` and ``omega_frame`` are
    :func:`hconv.convert_body`'s and ``convert_table``'s.

    ``precision`` (64 or 32) sets the dtype the method computes in; diagnostics are always
    computed in float64 from the inputs as given. ``diagnostics=False`` skips the residual
    (the costliest diagnostic); cond and status are always computed.

    Diagonal tensors given as ``(N, 3)`` moments take the cheapest exact path: every method of
    the exact family answers ``H_i / I_i``, which is correctly rounded.

    Degenerate bodies (a principal moment at or below ``degenerate_rtol`` times the trace
    Σ|Ik|, or singular in the working precision): ``degenerate="error"`` gives them status
    ``singular`` and no ω; ``"pinv"`` and ``"lock"`` answer with the pseudo-inverse (no rotation
    about the dropped axis), status ``degenerate``, and fill ``null_axis`` and ``null_dim``.
    ``extra_k`` adds to the method's error constant K for the ``ill_conditioned`` test, for a
    caller that has already rounded H in a way that grows with cond (a frame rotation: 2).

    ``engine`` (auto, numpy, numba or python) picks the code that converts; see
    :mod:`hconv.solve.engines`. Every engine gives the same answers (docs/engines.md).

    Numbers that carry a unit or a mask, which ``np.asarray`` would make bare numbers of, are
    never read as bare numbers (how units are found: :mod:`hconv.solve.units`):

    * a pint Quantity (``H``, ``I`` or ``r``) is read in its own unit, and a unit of another
      quantity is a UsageError naming the argument; ω then comes back as a pint Quantity in
      ``unit`` (rad/s, or m²/s for the document methods), of the first Quantity's registry.
      Plain numbers beside a Quantity are in SI, as always;
    * an xarray DataArray with a ``units`` attribute is read in that unit;
    * any other number with a unit (astropy's Quantity, unyt's arrays) is a UsageError: pass a
      pint Quantity or plain numbers in SI;
    * a masked array's masked entries are NaN: their rows get status ``invalid_input`` and no ω,
      as a file's empty cells do;
    * a list or tuple holding Quantities, masked arrays or such DataArrays is a UsageError:
      pass one of them for the whole array.
    """
    opts = options.configure(
        options.Options,
        "hconv.convert",
        job,
        method=method,
        precision=precision,
        diagnostics=diagnostics,
        degenerate=degenerate,
        degenerate_rtol=degenerate_rtol,
        engine=engine,
    )
    _refuse_scene(opts)
    m = methods.get(opts.method)
    precision, diagnostics, engine = opts.precision, opts.diagnostics, opts.engine
    degenerate, degenerate_rtol = opts.conventions.degenerate, opts.conventions.degenerate_rtol
    quantities: list[type] = []  # the classes of the pint Quantities given, in argument order
    H = _as_float("H", H, quantities)
    I = _as_float("I", I, quantities)
    single = H.ndim == 1
    if single:
        if H.shape != (3,):
            raise ValueError(f"Expected H to have shape (3,) or (N, 3), got {H.shape}")
        if I.shape not in ((3,), (6,), (3, 3)):
            raise ValueError(f"Expected one body's I to have shape (3,), (6,) or (3, 3), got {I.shape}")
        H, I = H[None], I[None]
        r = None if r is None else _as_float("r", r, quantities)[None]
    if H.ndim != 2 or H.shape[1] != 3:
        raise ValueError(f"Expected H to have shape (3,) or (N, 3), got {H.shape}")
    n = H.shape[0]
    if I.ndim not in (2, 3) or I.shape[1:] not in ((3,), (6,), (3, 3)):
        one = "; (3,), (6,) and (3, 3) are one body's, for H of shape (3,)" if I.shape in ((3,), (6,), (3, 3)) else ""
        raise ValueError(
            f"Expected I to have shape ({n}, 3), ({n}, 6) or ({n}, 3, 3) for H of shape {H.shape}, got {I.shape}{one}"
        )
    if I.shape[0] != n:
        one = "; a (3, 3) I is one body's tensor, for H of shape (3,)" if I.shape == (3, 3) else ""
        raise ValueError(f"I holds {_count(I.shape[0], 'tensor')} but H holds {_count(n, 'vector')}{one}")
    if r is not None:
        r = _as_float("r", r, quantities)
        if r.shape != (n, 3):
            raise ValueError(
                f"Expected r to have shape {(3,) if single else (n, 3)}, got {r.shape[1:] if single else r.shape}"
            )
    elif m.needs_r:
        raise ValueError(f"method {m.name!r} needs the offset r [m]; pass r=...")
    form, values = forms.from_array(I)
    res = convert_columns(
        H.T,
        form,
        values,
        None if r is None else r.T,
        method=m,
        precision=precision,
        diagnostics=diagnostics,
        degenerate=degenerate,
        degenerate_rtol=degenerate_rtol,
        extra_k=extra_k,
        engine=engine,
    )
    if single:
        res = Result(
            res.w[0],
            None if res.residual is None else res.residual[0],
            res.cond[0],
            res.status_code[0],
            res.unit,
            res.method,
            None if res.null_axis is None else res.null_axis[0],
            None if res.null_dim is None else res.null_dim[0],
            res.engine,
        )
    if quantities:  # ω in the registry of the first Quantity given (pint refuses to mix registries)
        res = replace(res, w=quantities[0](res.w, res.unit))
    return res


def _refuse_scene(opts: options.Options) -> None:
    """UsageError for a run configuration that asks :func:`convert` for what it does not do: a
    scene convention other than H and I as given, or a table-level field of a Job (a column
    mapping, units, ω's unit), which it would silently ignore."""
    conv, plain = opts.conventions, options.Conventions()
    scene = [
        option(name, getattr(conv, name))
        for name in ("about", "products", "omega_frame")
        if getattr(conv, name) != getattr(plain, name) and not (name == "omega_frame" and conv.w_frame == conv.frame)
    ]
    base = {f.name for f in fields(options.Options)}
    default = type(opts)()
    table = [
        option(f.name, getattr(opts, f.name))
        for f in fields(opts)
        if f.name not in base and getattr(opts, f.name) != getattr(default, f.name)
    ]
    if scene:
        raise UsageError(
            f"hconv.convert takes H and I as given, about one point and in one frame: {', '.join(scene)} "
            "is for hconv.convert_body (one body) or hconv.convert_table"
        )
    if table:
        raise UsageError(
            f"hconv.convert reads no columns and gives ω in rad/s: {', '.join(table)} is for hconv.convert_table "
            "(or hconv.convert_body); give hconv.convert a hconv.Options"
        )


def _checked(
    method: str | methods.Method, precision: int, degenerate: str, degenerate_rtol: float | None
) -> methods.Method:
    """The method, resolved once here (everything below takes the Method), and the options checked."""
    m = methods.get(method)
    options.check_precision(precision)
    options.check_degenerate(degenerate, degenerate_rtol, m)
    return m


def convert_columns(
    H: np.ndarray,
    form: forms.Form,
    I: np.ndarray,
    r: np.ndarray | None = None,
    *,
    method: str | methods.Method = "exact",
    precision: int = 64,
    diagnostics: bool = True,
    degenerate: str = "error",
    degenerate_rtol: float | None = None,
    extra_k: float = 0.0,
    engine: str = "auto",
) -> Result:
    """:func:`convert` on hconv's internal layout: ``H`` and ``r`` component-major ``(3, N)``,
    I the ``(k, N)`` numbers of inertia ``form``. Each block of rows is read into :class:`Sym3`
    columns by :meth:`hconv.solve.forms.Form.as_sym3` as it is converted, so the whole input is
    never repacked and a block's reading happens while its rows are in cache. Returns a stacked
    :class:`Result`.
    """
    m = _checked(method, precision, degenerate, degenerate_rtol)
    n = H.shape[1]
    if m.needs_r and r is None:
        raise ValueError(f"method {m.name!r} needs the offset r [m]; pass r=...")
    used = engines.resolve(engine, n, m, precision, degenerate, form.name, degenerate_rtol)
    if used != "numpy":
        return _convert_rows(used, m, form, I, H, diagnostics, extra_k)
    dtype = options.DTYPES[precision]
    w = np.empty((n, 3), dtype=dtype)
    cond = np.empty(n)
    code = np.empty(n, dtype=np.uint8)
    residual = np.empty(n) if diagnostics else None
    deg = None
    if degenerate != "error":
        deg = _Degenerate(np.full((n, 3), np.nan), np.zeros(n, dtype=np.int8))
    opts = _BlockOptions(m, dtype, form.diagonal, degenerate_rtol, extra_k)
    covered = engines.covers(m, precision, degenerate, form.name, degenerate_rtol)
    start = time.perf_counter()
    _convert_blocks(n, opts, form, I, H, r, w, cond, code, residual, deg, covered)
    if covered:
        engines.spend(time.perf_counter() - start)  # auto's count of what numba would have saved
    axis, dim = (None, None) if deg is None else (deg.axis, deg.dim)
    return Result(w, residual, cond, code, m.unit, m.name, axis, dim)


def _convert_rows(
    used: str, m: methods.Method, form: forms.Form, I: np.ndarray, H: np.ndarray, diagnostics: bool, extra_k: float
) -> Result:
    """:func:`convert_columns` by a row engine (``numba`` or ``python``); the rows it leaves
    (``fallback``) are converted by the numpy engine and put in their places."""
    n = H.shape[1]
    I = np.asarray(I, dtype=np.float64)
    H = np.asarray(H, dtype=np.float64)
    w = np.empty((n, 3))
    cond = np.empty(n)
    code = np.empty(n, dtype=np.uint8)
    residual = np.empty(n if diagnostics else 0)
    fallback = np.zeros(n, dtype=bool)
    cond_limit = _cond_limit(m, extra_k)
    nine = rows.FORMS[form.name]
    if used == "numba":
        from hconv.solve import compiled  # numba's import: only here, when it runs

        compiled.convert_rows(I, nine, H, m.refines, diagnostics, cond_limit, w, cond, code, residual, fallback)
        compiled.mark()
    else:
        _python_rows(I, nine, H, m.refines, diagnostics, cond_limit, w, cond, code, residual, fallback)
    rest = np.flatnonzero(fallback)
    if rest.size:
        sub = convert_columns(
            H[:, rest], form, I[:, rest], method=m, diagnostics=diagnostics, extra_k=extra_k, engine="numpy"
        )
        w[rest], cond[rest], code[rest] = sub.w, sub.cond, sub.status_code
        if sub.residual is not None:
            residual[rest] = sub.residual
    return Result(w, residual if diagnostics else None, cond, code, m.unit, m.name, engine=used)


def _python_rows(
    I: np.ndarray,
    nine: bool,
    H: np.ndarray,
    refined: bool,
    diagnostics: bool,
    cond_limit: float,
    w: np.ndarray,
    cond: np.ndarray,
    code: np.ndarray,
    residual: np.ndarray,
    fallback: np.ndarray,
) -> None:
    """:func:`hconv.solve.rows.convert_rows` interpreted, on Python floats (numpy scalars would
    cost several times more per operation)."""
    for i, (values, (h0, h1, h2)) in enumerate(zip(I.T.tolist(), H.T.tolist())):
        if nine:
            xx, yy, zz, xy, xz, yz, asym = rows.sym_of_nine(*values)
        else:
            (xx, yy, zz, xy, xz, yz), asym = values, False
        if asym:
            fallback[i] = True
            continue
        try:
            w0, w1, w2, c, k, res, fb = rows.convert_one(
                xx, yy, zz, xy, xz, yz, h0, h1, h2, refined, diagnostics, cond_limit
            )
        except (ZeroDivisionError, ValueError):  # Python raises where IEEE gives inf or NaN
            fallback[i] = True
            continue
        w[i] = w0, w1, w2
        cond[i], code[i], fallback[i] = c, k, fb
        if diagnostics:
            residual[i] = res


def _cond_limit(m: methods.Method, extra_k: float) -> float:
    """cond above which a float64 answer of ``m`` on a full tensor is ``ill_conditioned``."""
    k = extra_k + (m.error_k or {}).get(64, 0.0)
    return status.ILL_CONDITIONED_TOL / (k * float(np.finfo(np.float64).eps)) if k else np.inf


def error_k(m: methods.Method, precision: int, diagonal: bool, extra_k: float = 0.0) -> float:
    """K of the bound K·cond(I)·eps on an exact-family answer's error (``ill_conditioned``), with
    ``extra_k`` for what the caller rounded before (0 for the other methods: no such bound).
    The division is correctly rounded, so on diagonal tensors the method adds nothing that grows
    with cond."""
    if not m.exact:
        return 0.0
    return extra_k if diagonal else extra_k + (m.error_k or {}).get(precision, 0.0)


def _convert_blocks(
    n: int,
    opts: _BlockOptions,
    form: forms.Form,
    I: np.ndarray,
    H: np.ndarray,
    r: np.ndarray | None,
    w: np.ndarray,
    cond: np.ndarray,
    code: np.ndarray,
    residual: np.ndarray | None,
    deg: _Degenerate | None,
    covered: bool,
) -> None:
    """Every block of rows: by :mod:`hconv.solve.vectorrows` when the run is ``covered`` (the
    rows it leaves by :func:`_convert_block`), else by :func:`_convert_block`; on
    :func:`block_threads` threads (numpy lets go of the GIL inside each operation on a block, so
    the blocks of one call share the cores)."""
    common = covered and COMMON_PATH
    threads = block_threads(-(-n // THREADED_BLOCK_ROWS))
    size = BLOCK_ROWS if threads == 1 else THREADED_BLOCK_ROWS
    cond_limit = _cond_limit(opts.m, opts.extra_k)

    def one(lo: int) -> None:
        sl = slice(lo, min(n, lo + size))
        # every row that would warn gets a status instead; set here, as errstate is per thread
        with np.errstate(all="ignore"):
            if common:
                res = None if residual is None else residual[sl]
                _convert_common(opts, form, I[:, sl], H[:, sl], w[sl], cond[sl], code[sl], res, cond_limit)
                return
            _convert_block(
                opts,
                *form.as_sym3(I[:, sl]),
                H[:, sl],
                None if r is None else r[:, sl],
                w[sl],
                cond[sl],
                code[sl],
                None if residual is None else residual[sl],
                None if deg is None else _Degenerate(deg.axis[sl], deg.dim[sl]),
            )

    starts = range(0, n, size)
    if threads == 1:
        for lo in starts:
            one(lo)
        return
    pool = ThreadPoolExecutor(threads, thread_name_prefix="hconv-blocks")
    try:
        for _ in pool.map(one, starts):  # re-raises a block's exception here
            pass
    finally:
        # on an exception or Ctrl-C, the blocks not yet started never start
        pool.shutdown(wait=True, cancel_futures=True)


def block_threads(blocks: int) -> int:
    """Threads for a call of ``blocks`` blocks: one per core (at most :data:`MAX_BLOCK_THREADS`)
    when called from the main thread, else 1: a call from another thread is already part of
    its caller's parallelism (the file pipeline's batch threads, a Dask worker's task)."""
    if blocks < 2 or threading.current_thread() is not threading.main_thread():
        return 1
    return max(1, min(blocks, MAX_BLOCK_THREADS, engines.available_cores()))


def _convert_common(
    opts: _BlockOptions,
    form: forms.Form,
    I: np.ndarray,
    H: np.ndarray,
    w_out: np.ndarray,
    cond_out: np.ndarray,
    code_out: np.ndarray,
    res_out: np.ndarray | None,
    cond_limit: float,
) -> None:
    """One block of a run the row engines cover: :mod:`hconv.solve.vectorrows` converts it, and
    the general :func:`_convert_block` the rows that module leaves."""
    sym, asym = form.as_sym3(I)
    Hc = np.ascontiguousarray(H)
    b = vectorrows.convert_block(sym, asym, Hc, opts.m.refines, res_out is not None, cond_limit)
    w_out[:] = b.w.T
    cond_out[:] = b.cond
    code_out[:] = b.code
    if res_out is not None:
        res_out[:] = b.residual
    rest = np.flatnonzero(b.fallback)
    if rest.size:
        k = rest.size
        w, cond, code = np.empty((k, 3)), np.empty(k), np.empty(k, dtype=np.uint8)
        res = None if res_out is None else np.empty(k)
        _convert_block(opts, sym.take(rest), asym[rest], Hc[:, rest], None, w, cond, code, res, None)
        w_out[rest], cond_out[rest], code_out[rest] = w, cond, code
        if res_out is not None:
            res_out[rest] = res


@dataclass(frozen=True)
class _BlockOptions:
    m: methods.Method
    dtype: type
    diagonal: bool  #: I holds diagonal tensors (principal moments in their own frame)
    degenerate_rtol: float | None
    extra_k: float


@dataclass(frozen=True)
class _Degenerate:
    """Outputs for pinv/lock: views into the caller's arrays."""

    axis: np.ndarray  #: (n, 3)
    dim: np.ndarray  #: (n,) int8


def _convert_block(
    o: _BlockOptions,
    I: Sym3,
    asym: np.ndarray,
    H: np.ndarray,
    r: np.ndarray | None,
    w_out: np.ndarray,
    cond_out: np.ndarray,
    code_out: np.ndarray,
    res_out: np.ndarray | None,
    deg: _Degenerate | None,
) -> None:
    """One block of rows, ``H`` and ``r`` ``(3, n)``; writes into the ``*_out`` views (and
    ``deg``'s, for pinv/lock)."""
    m, dtype = o.m, o.dtype
    n = H.shape[1]
    H = np.ascontiguousarray(H)  # a copy of the block: contiguous rows, and the caller's never written
    r_used = np.ascontiguousarray(r) if m.needs_r else None
    columns = [*I, *H] + ([] if r_used is None else list(r_used))
    limit = np.finfo(dtype).max  # a finite float64 beyond float32's range is no usable input there
    with np.errstate(invalid="ignore"):
        invalid = ~(max_abs(columns) <= limit)  # NaN compares false, so NaN rows are invalid too
    if invalid.any():
        # Stand-ins keep the kernels quiet; these rows' outputs are replaced below.
        keep = ~invalid
        I = Sym3(*(np.where(keep, c, d) for c, d in zip(I, (1.0, 1.0, 1.0, 0.0, 0.0, 0.0))))
        H = np.where(keep, H, 0.0)
        if r_used is not None:
            r_used = np.where(keep, r_used, 1.0)

    if o.diagonal:
        moments = np.stack([I.xx, I.yy, I.zz])
        lam = np.sort(moments, axis=0)
    else:
        lam = eigenvalues(I)  # (3, n), ascending
    a0, a1, a2 = np.abs(lam[0]), np.abs(lam[1]), np.abs(lam[2])
    big = np.maximum(a0, a2)
    small = np.minimum(np.minimum(a0, a1), a2)
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = np.where(small > 0, big / np.where(small > 0, small, 1.0), np.inf)
    singular = small <= status.singular_rtol(dtype) * big
    tol = np.zeros(n)  # a moment at or below tol counts as zero (degenerate)
    if o.degenerate_rtol is not None:
        tol = o.degenerate_rtol * (a0 + a1 + a2)
        singular |= small <= tol
    tol = np.maximum(tol, status.singular_rtol(dtype) * big)
    dropped = singular & ~invalid & ~asym if deg is not None else np.zeros(n, dtype=bool)
    k_extra = error_k(m, 8 * np.dtype(dtype).itemsize, o.diagonal, o.extra_k)
    cond_limit = status.ILL_CONDITIONED_TOL / (k_extra * float(np.finfo(dtype).eps)) if k_extra else np.inf
    flags = {
        "invalid_input": invalid,
        "not_symmetric": asym & ~invalid,
        "singular": singular & ~dropped,
        "not_positive_definite": (lam[0] < -tol) | ((lam[0] < 0) & ~dropped),
        "degenerate": dropped,
        "not_physical": lam[2] - lam[1] - lam[0] > status.TRIANGLE_RTOL * (a0 + a1 + a2),
        "ill_conditioned": cond > cond_limit,
    }

    if o.diagonal and m.exact:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            w = H.astype(dtype) / moments.astype(dtype)
        own: dict[str, np.ndarray] = {}
    else:
        w, own = m.kernel(I.astype(dtype), H.astype(dtype), None if r_used is None else r_used.astype(dtype))
    for name, mask in own.items():
        flags[name] = flags[name] | mask if name in flags else mask
    if deg is not None and dropped.any():
        flags["singular"] &= ~dropped  # a method's own singular flag does not apply to these rows
        w[:, dropped] = _pseudo_inverse(I.take(dropped), H[:, dropped], tol[dropped], o.diagonal, deg, dropped)
    no_answer = np.zeros(n, dtype=bool)
    for s in m.nan_on:
        if s in flags:
            no_answer |= flags[s]
    # A finite row that still gives a non-finite ω must never pass as ok.
    lost = ~(np.isfinite(w[0]) & np.isfinite(w[1]) & np.isfinite(w[2])) & ~no_answer
    flags["overflow"] = lost & ~invalid
    w[:, no_answer | lost] = np.nan

    if m.exact:
        # ω so small that the spacing of subnormal numbers alone exceeds the promise.
        grid = float(np.finfo(dtype).smallest_subnormal) / status.ILL_CONDITIONED_TOL
        wmax = max_abs(w)
        flags["inaccurate"] = (wmax > 0) & (wmax < grid)
    w_out[:] = w.T
    cond[invalid] = np.nan
    cond_out[:] = cond
    code_out[:] = status.combine(n, flags)
    if res_out is not None:
        # Rows with an answer to measure; the rest keep NaN.
        ok = ~(invalid | flags["not_symmetric"] | flags["singular"] | dropped | no_answer | lost)
        res_out[:] = np.nan
        every = bool(ok.all())
        if every or ok.any():
            rows = slice(None) if every else ok  # a slice copies nothing
            res = _residual(
                o, I if every else I.take(ok), H[:, rows], w[:, rows], moments[:, rows] if o.diagonal else None
            )
            res_out[rows] = res
            if m.exact:
                # The safety net under the a-priori statuses: an exact-family answer measured off
                # by more than the promise (subnormal numbers on the way, say) is never ok.
                bad = np.zeros(n, dtype=bool)
                bad[rows] = res > status.ILL_CONDITIONED_TOL
                code_out[:] = status.merge(code_out, bad, "inaccurate")


def _residual(o: _BlockOptions, I: Sym3, H: np.ndarray, w: np.ndarray, moments: np.ndarray | None) -> np.ndarray:
    """‖ω − I⁻¹H‖ / ‖I⁻¹H‖ for rows that have an answer: ``H``, ``w`` (and ``moments``) ``(3, k)``;
    returns ``(k,)``.

    The reference I⁻¹H is solved in float64 from the inputs. An exact-family answer is its own
    starting point: the first refinement step's correction is then its error, measured with a
    residual in double precision, and further steps run until the reference is correct to
    rounding; the error so measured is itself right to a relative cond·eps (6 digits at cond 1e10).
    The other methods answer something else, so their reference starts from scratch.
    """
    w = w.astype(np.float64, copy=False)
    if moments is not None:  # H_i / I_i in float64 is the correctly rounded reference
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            ref = H / moments
    else:
        ref = linsolve.solve_refined(I, H, x0=w if o.m.exact else None)
    # H = 0 gives I⁻¹H = 0: an answer of 0 is exact, anything else infinitely off.
    return relative_error(w, ref)


def _pseudo_inverse(
    I: Sym3, H: np.ndarray, tol: np.ndarray, diagonal: bool, deg: _Degenerate, rows: np.ndarray
) -> np.ndarray:
    """ω = I⁺·H on degenerate rows, in float64: moments at or below ``tol`` ``(k,)`` are dropped.

    ``H`` is ``(3, k)``; writes the dropped axis (when exactly one) and the count into ``deg``
    at ``rows``. Returns ω as ``(3, k)``.
    """
    # The principal frame: for a diagonal tensor the coordinate axes themselves.
    if diagonal:
        S, R = np.stack([I.xx, I.yy, I.zz]), np.broadcast_to(np.eye(3)[..., None], (3, 3, H.shape[1]))
    else:
        S, R = principal_frame(I)  # (3, k) moments; (3, 3, k) axes, column j for moment j
    inv, zero = pinv_moments(S, tol)
    w = frames.to_world(R, inv * frames.to_body(R, H))
    count = zero.sum(axis=0)
    axis = np.full((3, S.shape[1]), np.nan)
    one = count == 1
    if one.any():
        cols = np.arange(S.shape[1])
        picked = R[:, np.argmax(zero, axis=0), cols]  # (3, k): the axis of the dropped moment
        # A sign is arbitrary for an axis; make its largest component positive, so output is stable.
        sign = np.sign(picked[np.argmax(np.abs(picked), axis=0), cols])
        axis[:, one] = (picked * sign)[:, one]
    deg.axis[rows] = axis.T
    deg.dim[rows] = count
    return w
