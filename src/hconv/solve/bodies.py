"""Scenes as they come: body states in any inertia form, frame and reference point, to ω.

:func:`solve` takes the column sets that :meth:`hconv.tables.layout.Layout.read` returns (SI units,
component-major ``(k, N)`` arrays) and the :class:`Conventions` of the scene. It

1. negates the products of inertia if they were given as positive integrals (``products``);
2. re-expresses H (and r) in the body frame when an orientation q is given and H is in the
   world frame (``frame``); with q, the tensor is in the body frame (see :mod:`hconv.tables.layout`);
3. moves the reference point (``about``): ``pivot`` shifts I from the centre of mass to the pivot;
   ``free`` takes the centre of mass's orbital momentum out of H, in the frame H was given in,
   before any rotation (see :mod:`hconv.kernels.frames`);
4. solves with :func:`hconv.solve.convert.convert` on the cheapest form the inertia allows: a scalar or
   principal moments go straight to the division ``H_i / I_i``; a tensor is built only for a
   pivot shift, and otherwise the six or nine numbers go to the chosen method;
5. re-expresses ω (and a dropped axis) in ``omega_frame`` (default: the frame of H);
6. with a mass column, flags rows whose inertia no solid of that mass could have (``unit_suspect``).

The residual is measured in the frame and about the point where the tensor is solved, so it does
not include the (few-ulp) rounding of the rotations and of the pivot shift; ``ill_conditioned``
allows for them (:data:`ROTATION_K`, :data:`PIVOT_K`).

A free body's H_C = H_P − r × (m·v) can cancel most of H_P's digits, and what H_P's rounding to
float64 lost, no arithmetic on H_P recovers. The kernel bounds it, ε_C = ‖δH_C‖ / ‖H_C‖
(:func:`hconv.kernels.frames.momentum_about_com`), and ω = I⁻¹·H_C can then be off by
cond(I)·ε_C, on top of the solve's own K·cond(I)·eps. Where the two together could exceed
:data:`hconv.solve.status.ILL_CONDITIONED_TOL` (1e-6) the row is ``cancellation``, and its
``residual`` is the one measured against the float64 H_C plus cond(I)·ε_C: a measurement cannot
see a loss that happened before the numbers reached hconv, so the residual carries its bound.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hconv.errors import UsageError
from hconv.kernels import frames
from hconv.kernels.inertia import Sym3
from hconv.kernels.spectrum import eigenvalues
from hconv.solve import blocks, forms, methods, status, units
from hconv.solve import convert as core
from hconv.solve.options import DTYPES, Conventions

#: Rounding a vector through a rotation costs about this many cond(I)·eps in ω.
ROTATION_K = 2.0
#: The parallel-axis shift, with I_C, m and r rounded to float64, costs about this many cond(I_P)·eps
#: in ω: about twice the worst measured against 50-digit states (docs/measurements.md).
PIVOT_K = 2.0


def invalid_inputs(
    sets: dict,
    form: str,
    method: str | methods.Method = "exact",
    precision: int = 64,
    conv: Conventions = Conventions(),
) -> list[tuple[str, str]]:
    """Why :func:`solve` gives the first row of ``sets`` the status ``invalid_input``: a
    ``(set, problem)`` pair per cause, in the order of ``sets``; empty when none of the given
    values is to blame (then a value overflowed on the way, in the point shift or the rotation).

    ``problem`` is ``"not_finite"`` (NaN or ±Inf in a value used), ``"zero_quaternion"``,
    ``"mass_not_positive"`` (m <= 0 with an inertia that is not zero), ``"mass_negative"`` (m < 0
    for ``--about pivot|free``) or ``"beyond_float32"`` (with ``precision`` 32). These are the
    checks of :func:`_solve` and of :func:`hconv.solve.convert.convert_columns`, per set.
    """
    used = {"H", "I", "q"}  # q is always turned into a rotation
    if methods.get(method).needs_r or conv.about != "same":
        used.add("r")
    if conv.about == "free":
        used.add("v")
    one = {k: np.asarray(v, dtype=np.float64)[:, 0] for k, v in sets.items()}
    causes = []
    for name, x in one.items():
        if name == "m":  # an infinite mass is refused only where it moves the point (about)
            m, moved = x[0], conv.about != "same"
            if moved and not np.isfinite(m):
                causes.append((name, "not_finite"))
            elif moved and m < 0:
                causes.append((name, "mass_negative"))
            elif not m > 0 and forms.get(form).trace(sets["I"][:, :1])[0] != 0:
                causes.append((name, "mass_not_positive" if np.isfinite(m) else "not_finite"))
        elif name not in used:
            continue
        elif not np.isfinite(x).all():
            causes.append((name, "not_finite"))
        elif name == "q" and not np.any(x):
            causes.append((name, "zero_quaternion"))
        elif precision == 32 and name in ("H", "I", "r") and np.abs(x).max() > np.finfo(np.float32).max:
            causes.append((name, "beyond_float32"))
    return causes


def _given(value: np.ndarray | None, name: str) -> np.ndarray:
    """A set the conventions need (``Conventions.needs``), which must be there."""
    if value is None:
        raise UsageError(f"this conversion needs the set {name!r}")
    return value


def _pivot_shift(form: forms.Form, I_C: np.ndarray, m: np.ndarray, r_B: np.ndarray) -> tuple[str, np.ndarray]:
    """The inertia about the pivot P from the inertia about the centre of mass C (``form``'s
    numbers ``(k, N)``), in the form :attr:`forms.Form.shifted` gives (six, or nine numbers)."""
    n = I_C.shape[1]
    zero = np.zeros(n)
    d = frames.shift_to_pivot(Sym3(zero, zero, zero, zero, zero, zero), m, r_B)
    return form.shifted(I_C, d)


def solve(
    sets: dict,
    form: str,
    method: str | methods.Method = "exact",
    precision: int = 64,
    conv: Conventions = Conventions(),
    diagnostics: bool = True,
    engine: str = "auto",
) -> core.Result:
    """ω for every row of ``sets`` (see the module docstring); a stacked :class:`core.Result`.

    ``sets``: ``H`` ``(3, N)`` [kg·m²/s], ``I`` ``(k, N)`` in ``form`` (a name in
    :data:`hconv.solve.forms.FORMS`) [kg·m²] and, where given, ``q`` ``(4, N)`` (w, x, y, z),
    ``r`` ``(3, N)`` [m], ``m`` ``(1, N)`` [kg], ``v`` ``(3, N)`` [m/s]; H, r and v in the frame
    ``conv.frame``. Raises UsageError for a method or set that cannot be used.
    """
    spec = forms.get(form)
    method = methods.get(method)  # resolved once: everything below takes the Method
    for name in conv.needs(method):
        if name not in sets:
            raise UsageError(f"this conversion needs the set {name!r}")
    with np.errstate(all="ignore"):  # extreme rows get statuses, never warnings
        return _solve(sets, spec, method, precision, conv, diagnostics, engine)


def _solve(
    sets: dict,
    form: forms.Form,
    method: methods.Method,
    precision: int,
    conv: Conventions,
    diagnostics: bool,
    engine: str,
) -> core.Result:
    # Names say what a quantity is about and the frame it is in: H_P_F is the momentum about P
    # (the point of the given I), in F, the frame of the given H (world, or body when q is
    # absent or --frame body); _B is the body frame; _C about the centre of mass.
    H_P_F, I_given = sets["H"], sets["I"]
    q, r_F, v_F = sets.get("q"), sets.get("r"), sets.get("v")
    m = sets["m"][0] if "m" in sets else None
    n = H_P_F.shape[1]
    bad = np.zeros(n, dtype=bool)  # rows with no usable orientation or mass
    if conv.products == "positive":
        I_given = form.flip_products(I_given)
    R_WB = None
    if q is not None:
        R_WB, bad_q = frames.quaternion_matrix(q)
        bad |= bad_q
    rotate_in = R_WB is not None and conv.frame == "world"
    H_F, eps_C = H_P_F, None  # the momentum that is solved, still in F; ε_C for a free body
    if conv.about == "free":
        # H is about an origin P: take out the orbital term in F, before any rotation, so that the
        # bound is about the numbers as given, and the rotation only turns H_C (ROTATION_K).
        H_F, eps_C = frames.momentum_about_com(H_P_F, _given(m, "m"), _given(r_F, "r"), _given(v_F, "v"))
    if R_WB is not None and rotate_in:  # with q, the tensor is in the body frame: bring H (and r) there
        H_B = frames.to_body(R_WB, H_F)
        r_B = None if r_F is None else frames.to_body(R_WB, r_F)
    else:
        H_B, r_B = H_F, r_F
    # the tensor and momentum that are solved: about one point, in one frame
    solved_form, I_solved, H_solved = form, I_given, H_B
    extra_k = ROTATION_K if rotate_in else 0.0
    if conv.about != "same":
        m_C, r_CP = _given(m, "m"), _given(r_B, "r")
        bad |= ~(np.isfinite(m_C) & (m_C >= 0))
        if conv.about == "pivot":  # I is about C, H about the pivot P: shift I to P
            name, I_solved = _pivot_shift(form, I_given, m_C, r_CP)
            solved_form = forms.get(name)
            extra_k += PIVOT_K
    if m is not None:
        # A mass that is not positive, with an inertia that is not zero, is not a body (a zero
        # mass with a zero inertia is a massless link, which has no ω to give and goes singular).
        with np.errstate(invalid="ignore"):
            bad |= ~(m > 0) & (form.trace(I_given) != 0)
    if bad.any():
        H_solved = np.where(bad, np.nan, H_solved)  # status invalid_input, through core
    res = core.convert_columns(
        H_solved,
        solved_form,
        I_solved,
        r_B,
        method=method,
        precision=precision,
        diagnostics=diagnostics,
        degenerate=conv.degenerate,
        degenerate_rtol=conv.degenerate_rtol,
        extra_k=extra_k,
        engine=engine,
    )
    if eps_C is not None:
        res = _cancellation(res, eps_C, blocks.error_k(method, precision, solved_form.diagonal, extra_k), precision)
    w_B, axis_B, code = res.w, res.null_axis, res.status_code
    w_out, axis_out = w_B, axis_B
    if R_WB is not None and conv.w_frame == "world":
        w_out = frames.to_world(R_WB, w_B.T.astype(np.float64)).T.astype(w_B.dtype)
        if axis_B is not None:
            axis_out = frames.to_world(R_WB, axis_B.T).T
    if m is not None:
        # Without --about, I may be about a distant pivot: only "too dense" is certain then.
        slip = units.implausible(form.trace(I_given), m, both_sides=conv.about != "same")
        code = status.merge(code, slip, "unit_suspect")
    residual = res.residual
    if conv.about == "pivot":
        # The shift adds a point mass's tensor, which can make a centre-of-mass tensor that no
        # body has look valid about the pivot: symmetry and the triangle inequality are checked
        # about C too (the shift's large entries would hide the given nine numbers' skew, which
        # is measured against the largest entry).
        dtype = DTYPES[precision]
        asym = form.as_sym3(I_given, status.symmetry_rtol(dtype))[1]
        code = status.merge(code, asym, "not_symmetric")
        if asym.any():  # no answer there, as for a tensor that is not symmetric about the pivot
            gone = code == status.CODE["not_symmetric"]
            w_out, residual = w_out.copy(), None if residual is None else residual.copy()
            w_out[gone] = np.nan
            if axis_out is not None:
                axis_out = axis_out.copy()
                axis_out[gone] = np.nan
            if residual is not None:
                residual[gone] = np.nan
        six = form.as_six(I_given)
        finite = np.isfinite(six).all(axis=0)  # the others are invalid_input already
        six = np.where(finite, six, np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])[:, None])
        lam = eigenvalues(Sym3(*six))
        with np.errstate(invalid="ignore", over="ignore"):
            rtol = status.triangle_rtol(dtype)
            broken = finite & (lam[2] - lam[1] - lam[0] > rtol * np.abs(lam).sum(axis=0))
        code = status.merge(code, broken, "not_physical")
    return dataclasses.replace(res, w=w_out, residual=residual, null_axis=axis_out, status_code=code)


def _cancellation(res: core.Result, eps_C: np.ndarray, k: float, precision: int) -> core.Result:
    """A free body's result with the point change's bound carried in (the module docstring):
    ``cancellation`` where cond(I)·(ε_C + K·eps) could exceed ILL_CONDITIONED_TOL, and
    cond(I)·ε_C added to the residual. ``eps_C`` ``(N,)``; ``k``: the solve's own K."""
    with np.errstate(invalid="ignore"):
        point = np.where(eps_C == 0, 0.0, res.cond * eps_C)  # 0 also where cond is inf or NaN
        eps = float(np.finfo(np.float64 if precision == 64 else np.float32).eps)
        solve = res.cond * (k * eps)
        lost = point + solve > status.ILL_CONDITIONED_TOL
        # where the solve alone could lose them, the row is ill_conditioned (before cancellation),
        # and the point change is not what to blame
        cancelled = lost & (solve <= status.ILL_CONDITIONED_TOL)
    code = status.merge(res.status_code, lost, "cancellation")
    residual = None if res.residual is None else res.residual + point
    return dataclasses.replace(res, status_code=code, residual=residual, cancelled=cancelled)
