"""``convert``: H and I (and r) to ω with a chosen method, plus per-row diagnostics.

Shapes: ``H`` is ``(N, 3)`` [kg·m²/s]; ``I`` is ``(N, 6)`` as (Ixx, Iyy, Izz, Ixy, Ixz, Iyz),
``(N, 3, 3)``, ``(N, 9)`` (the matrix row-major, as a file's nine columns) or ``(N, 3)``
principal/diagonal moments [kg·m²]; ``r`` is ``(N, 3)`` [m]. Each may also be one body's, without
the row axis: ``(3,)`` for H and r, ``(3,)``, ``(6,)``, ``(9,)`` or ``(3, 3)`` for I. They
broadcast as numpy broadcasts: one body's, or a stack of one row, is used for every row of the
others (one body's I over a log of its H), stacks of N rows go together, and anything else is a
ValueError naming both shapes. Only where every argument is one body's does the result come back
unstacked. The one shape both readings share is refused (ValueError): an I of shape ``(3, 3)``
beside H or r of three rows; pass ``I[None]`` for one matrix used for the three rows, or
``I[:, None] * np.eye(3)`` for three rows of principal moments.
These stacks are read into hconv's column layout at the edge (:func:`hconv.solve.forms.from_array`);
:func:`convert_columns` takes that layout directly.
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

The numpy engine, which converts in blocks of rows, is :mod:`hconv.solve.blocks`; the compiled
engine (:mod:`hconv.solve.compiled`) is dispatched here, and the rows it leaves go to the numpy
engine.
"""

from __future__ import annotations

from dataclasses import MISSING, dataclass, fields, replace

import numpy as np
from numpy.typing import ArrayLike

from hconv.errors import UsageError, option
from hconv.solve import arguments, blocks, compiled, engines, forms, methods, options, status


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
    #: the engine that converted the rows: numpy or compiled (hconv.solve.engines)
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

    def body(self, k: int) -> Result:
        """Row ``k`` of a stacked Result: one body's, each array unstacked."""

        def at(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[k]

        w, cond, code = self.w[k], self.cond[k], self.status_code[k]
        return Result(w, at(self.residual), cond, code, self.unit, self.method, at(self.null_axis),
                      at(self.null_dim), self.engine, at(self.cancelled))  # fmt: skip


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

    ``engine`` (auto, compiled or numpy) picks the code that converts; see
    :mod:`hconv.solve.engines`. Every engine gives the same answers (docs/engines.md).

    Numbers that carry a unit or a mask, which ``np.asarray`` would make bare numbers of, are
    never read as bare numbers (how units are found: :mod:`hconv.solve.units`):

    * a pint Quantity (``H``, ``I`` or ``r``) is read in its own unit, and a unit of another
      quantity is a UsageError naming the argument; ω then comes back as a pint Quantity in
      ``unit`` (rad/s, or m²/s for the document methods), of the first Quantity's registry.
      Plain numbers beside a Quantity are in SI, as always;
    * an array whose ``attrs`` hold a unit (an xarray DataArray, a pandas Series: the key
      ``units`` or ``unit``, in any case) is read in that unit;
    * any other array with a unit (astropy's Quantity, unyt's arrays, anything with a ``unit``
      or ``units`` attribute) is a UsageError: pass a pint Quantity or plain numbers in SI;
    * a masked array's masked entries are NaN: their rows get status ``invalid_input`` and no ω,
      as a file's empty cells do;
    * a list or tuple holding Quantities, masked arrays or such DataArrays is a UsageError:
      pass one of them for the whole array.
    """
    if job is None and r is None and precision is None and degenerate is None and degenerate_rtol is None:
        fast = _plain_call(H, I, method, diagnostics, extra_k, engine)
        if fast is not None:
            return fast
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
    # a bare number: a pint Quantity or text here would fail deep inside, naming nothing
    if isinstance(extra_k, bool) or not isinstance(extra_k, (int, float, np.integer, np.floating)) or not extra_k >= 0:
        raise UsageError(f"extra_k must be a number >= 0 (an error constant, no unit), got {extra_k!r}")
    m = methods.get(opts.method)
    precision, diagnostics, engine = opts.precision, opts.diagnostics, opts.engine
    degenerate, degenerate_rtol = opts.conventions.degenerate, opts.conventions.degenerate_rtol
    args = arguments.read(H, I, r)
    H, I, r, single = args.H, args.I, args.r, args.single
    if r is None and m.needs_r:
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
        res = res.body(0)
    if args.quantities:  # ω in the registry of the first Quantity given (pint refuses to mix registries)
        res = replace(res, w=args.quantities[0](res.w, res.unit))
    return res


#: The methods a plain call may name for :func:`_plain_call`: the compiled engine's.
_PLAIN_METHODS = {None: "exact", "exact": "exact", "refined": "refined"}
_F64 = np.dtype(np.float64)


def _plain_call(
    H: object, I: object, method: object, diagnostics: object, extra_k: object, engine: object
) -> Result | None:
    """:func:`convert` for the call the compiled engine answers without the checks and repacking
    that other calls need, so that one body or a few rows cost little more than the compiled
    code itself: float64 ndarrays (one body or a stack) of six or nine numbers, no offset, an
    exact-family method the engine covers, the defaults otherwise. None for any other call, and
    for one body the compiled engine leaves to numpy: the general path then takes it (and its
    checks and messages)."""
    if (
        type(H) is not np.ndarray
        or type(I) is not np.ndarray
        or H.dtype is not _F64
        or I.dtype is not _F64
        or not (extra_k == 0.0 and type(extra_k) in (int, float))
        or not (diagnostics is None or diagnostics is True or diagnostics is False)
        or not (engine is None or engine == "auto" or engine == "compiled")
        or not (method is None or (type(method) is str and method in _PLAIN_METHODS))
    ):
        return None
    forced = engines.forced()  # any other value: the general path (and its message)
    if engine != "compiled" and forced and forced not in ("auto", "compiled"):
        return None
    m = methods.METHODS[_PLAIN_METHODS[method]]
    with_residual = diagnostics is not False
    if H.ndim == 1:
        if H.shape != (3,) or I.shape not in ((3, 3), (6,)):
            return None
        one = compiled.one(I, I.ndim == 2, H, m.refines, with_residual, _cond_limit(m))
        if one is None or one[4]:
            return None
        return _compiled_result(one[0], one[3], one[1], one[2], m)
    if H.ndim != 2 or H.shape[1] != 3 or I.shape[0] != H.shape[0] or I.shape[1:] not in ((3, 3), (6,)):
        return None
    if H.shape[0] < 2 * compiled.BLOCK_ROWS:  # one thread's worth: the call's own cost counts
        small = compiled.stack(I, H, m.refines, with_residual, _cond_limit(m))
        if small is not None:
            return _compiled_result(small[0], small[3], small[1], small[2], m)
    form, values = forms.from_array(I)
    return _convert_rows("compiled", m, form, values, H.T, with_residual, 0.0)


_limits: dict[str, float] = {}
#: A compiled Result's fields but its numbers, for :func:`_compiled_result`: the defaults, and the
#: engine.
_COMPILED_FIELDS = {**{f.name: f.default for f in fields(Result) if f.default is not MISSING}, "engine": "compiled"}
_new_object, _set_field = object.__new__, object.__setattr__


def _compiled_result(w: object, residual: object, cond: object, code: object, m: methods.Method) -> Result:
    """``Result(w, residual, cond, code, m.unit, m.name, engine="compiled")``, made without the
    frozen dataclass's ``__init__``, whose guarded field-by-field setting cost half of a small
    call (2.3 µs against a 4 µs conversion of 100 rows): one dict, a copy, given to the new
    object whole (updating the object's own ``__dict__`` cost twice as much)."""
    res = _new_object(Result)
    d = _COMPILED_FIELDS.copy()
    d["w"], d["residual"], d["cond"], d["status_code"], d["unit"], d["method"] = w, residual, cond, code, m.unit, m.name
    _set_field(res, "__dict__", d)
    return res


def _cond_limit(m: methods.Method) -> float:
    """:func:`hconv.solve.blocks.ill_conditioned_above` of ``m`` with no extra K, once per method."""
    if m.name not in _limits:
        _limits[m.name] = blocks.ill_conditioned_above(m, 0.0)
    return _limits[m.name]


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
        deg = blocks.Degenerate(np.full((n, 3), np.nan), np.zeros(n, dtype=np.int8))
    opts = blocks.Options(m, dtype, form.diagonal, degenerate_rtol, extra_k)
    blocks.convert_blocks(n, opts, form, I, H, r, w, cond, code, residual, deg)
    axis, dim = (None, None) if deg is None else (deg.axis, deg.dim)
    return Result(w, residual, cond, code, m.unit, m.name, axis, dim)


def _convert_rows(
    used: str, m: methods.Method, form: forms.Form, I: np.ndarray, H: np.ndarray, diagnostics: bool, extra_k: float
) -> Result:
    """:func:`convert_columns` by the compiled engine; the rows it leaves (``fallback``) are
    converted by the numpy engine and put in their places."""
    n = H.shape[1]
    I = np.asarray(I, dtype=np.float64)
    H = np.asarray(H, dtype=np.float64)
    w, cond, code, residual, fallback = compiled.outputs(n, diagnostics)
    cond_limit = _cond_limit(m) if extra_k == 0.0 else blocks.ill_conditioned_above(m, extra_k)
    nine = engines.FORMS[form.name]
    if compiled.convert_rows(I, nine, H, m.refines, diagnostics, cond_limit, w, cond, code, residual, fallback):
        rest = np.flatnonzero(fallback)
        sub = convert_columns(
            H[:, rest], form, I[:, rest], method=m, diagnostics=diagnostics, extra_k=extra_k, engine="numpy"
        )
        w[rest], cond[rest], code[rest] = sub.w, sub.cond, sub.status_code
        if sub.residual is not None:
            residual[rest] = sub.residual
    return Result(w, residual if diagnostics else None, cond, code, m.unit, m.name, engine=used)
