"""One body with a :class:`~hconv.tables.job.Job`: :func:`convert_body`, what ``hconv one`` runs.

A body's values come as numbers (H, I and, where the run reads them, r, q, m, v), in the units
the Job's ``unit_options`` give by set, and go through the same scene handling as a table's rows
(:func:`hconv.solve.bodies.solve`: products, frames, pivot and free bodies, the unit check). The
texts that explain a body's result (a missing value, a value given but not read, an invalid
input, a cancellation) are here too, beside what they explain. No pyarrow: ``hconv one`` stays
quick.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from hconv import errors
from hconv.errors import UsageError, entry, option
from hconv.solve import arguments, bodies, forms, options
from hconv.solve.convert import Result
from hconv.tables.job import Job

#: The sets one body takes, each with what its value holds (as ``hconv one`` spells it).
VALUES = {"H": "Hx,Hy,Hz", "I": "I", "r": "rx,ry,rz", "m": "MASS", "v": "vx,vy,vz", "q": "qw,qx,qy,qz"}
#: The sets a Job's ``unit_options`` may give a unit for (one body has no columns to name).
UNIT_SETS = ("H", "I", "r", "m", "v")
#: The values that only some runs read (q and m are read by every run: the frame, the density
#: check), and by which.
READ_BY = {
    "r": "by the document methods (--method document|document-principal) and with --about pivot|free",
    "v": "with --about free",
}
#: What is wrong and what to give instead, per cause that :func:`hconv.solve.bodies.invalid_inputs` names.
INVALID_HINTS = {
    "not_finite": "is not finite (NaN or infinity); give finite numbers",
    "zero_quaternion": "is not a rotation (zero norm); give a unit quaternion w,x,y,z",
    "mass_not_positive": "is not positive, but a body with inertia needs m > 0 (a massless link has I = 0)",
    "mass_negative": "is a negative mass; give m >= 0",
    "beyond_float32": "is beyond float32's range (3.4e+38) for --precision 32; use --precision 64",
}
#: What a status of the tensor itself means and what to check, for ``hconv one``'s stderr (the
#: status line says which, not why nor what to do). The usual causes of a tensor no body has are
#: the order of the six numbers, the products' sign and a unit slip (docs/design-note.md).
STATUS_HINTS = {
    "not_symmetric": "I's nine numbers are not symmetric (Iij and Iji differ); give a symmetric tensor, "
    "or its six numbers xx,yy,zz,xy,xz,yz",
    "singular": "I has a zero principal moment (a rod, a point mass), so no ω turns into this H about it; "
    "--degenerate pinv or lock gives the ω of the other axes",
    "not_positive_definite": "I has a negative principal moment, which no body has; check the order of the six "
    "numbers (xx,yy,zz,xy,xz,yz) and the products' sign (--products)",
    "not_physical": "I's principal moments break the triangle inequality (each at most the sum of the other "
    "two), which no solid body does; check the order of the six numbers (xx,yy,zz,xy,xz,yz), the products' "
    "sign (--products) and the point I is about",
}
#: What to add to a hint in float64: numbers computed in float32 meet these statuses by its
#: roundings alone (docs/input.md, "Numbers computed in float32").
FLOAT32_HINTS = {
    "not_symmetric": "numbers computed in float32 are symmetric only to its roundings: give --precision 32",
    "not_physical": "a thin plate computed in float32 is on the boundary only to its roundings: give --precision 32",
}
#: What a body's residual is: measured; with --about free, measured against H_C and with the bound
#: on what taking r × m·v out of H lost added (hconv.solve.bodies), which it cannot see.
RESIDUAL = "(|w - I⁻¹H| / |I⁻¹H|)"
RESIDUAL_FREE = "(|w - I⁻¹H_C| / |I⁻¹H_C| + cond(I)·ε_C, H_C = H - r × m·v)"
#: A formula that wrapping must not split (no-break spaces, printed as spaces).
DIFFERENCE = "H\xa0-\xa0r\xa0×\xa0m·v"

Numbers = Sequence[float] | np.ndarray | float


def convert_body(
    H: Numbers,
    I: Numbers,
    r: Numbers | None = None,
    *,
    q: Numbers | None = None,
    m: float | None = None,
    v: Numbers | None = None,
    job: Job | None = None,
    method: str | None = None,
    precision: int | None = None,
    diagnostics: bool | None = None,
    frame: str | None = None,
    omega_frame: str | None = None,
    about: str | None = None,
    products: str | None = None,
    degenerate: str | None = None,
    degenerate_rtol: float | None = None,
    omega_unit: str | None = None,
) -> Result:
    """ω of one body, as ``hconv one`` gives it: a :class:`~hconv.solve.convert.Result` for one
    body (``w`` of shape ``(3,)`` in ``unit``, the Job's ω unit; ``residual``, ``cond``,
    ``status_code``, ``null_axis``, ``null_dim`` and ``cancelled`` for that body).

    ``H`` (3 numbers), ``I`` (1, 3, 6 or 9: :func:`hconv.solve.forms.by_count`; a (3, 3) tensor
    is its 9), ``r`` and ``v`` (3), ``q`` (4: w, x, y, z) and ``m`` are in SI, or in the units
    ``job.unit_options`` gives by set (``{'I': 'g*cm**2'}``). The run configuration is ``job``, or
    the keywords (scene conventions among them), folded by
    :func:`hconv.solve.options.configure`; not both. A set the run needs and was not given is
    one UsageError naming every missing value; one given but not read is :func:`unread`.
    """
    job = options.configure(
        Job,
        "convert_body",
        job,
        method=method,
        precision=precision,
        diagnostics=diagnostics,
        frame=frame,
        omega_frame=omega_frame,
        about=about,
        products=products,
        degenerate=degenerate,
        degenerate_rtol=degenerate_rtol,
        omega_unit=omega_unit,
    )
    quantities: list[type] = []  # the classes of the pint Quantities given, as hconv.convert keeps them
    sets, form = _sets(H, I, r, q, m, v, job, quantities)
    res = bodies.solve(sets, form, job.method, job.precision, job.conventions, job.diagnostics, job.engine)
    one = res.body(0)
    scale = job.omega_scale  # in float64, as a unit's factor is
    w = one.w.astype(np.float64) * scale if scale != 1.0 else one.w
    # pint refuses to mix registries: ω in the first Quantity's
    return replace(one, w=quantities[0](w, job.unit) if quantities else w, unit=job.unit)


def invalid_inputs(
    H: Numbers,
    I: Numbers,
    r: Numbers | None = None,
    *,
    q: Numbers | None = None,
    m: float | None = None,
    v: Numbers | None = None,
    job: Job,
) -> list[tuple[str, str]]:
    """Why :func:`convert_body` gives this body the status ``invalid_input``: ``(set, problem)``
    pairs, first the first given (:func:`hconv.solve.bodies.invalid_inputs`)."""
    sets, form = _sets(H, I, r, q, m, v, job, [])
    return bodies.invalid_inputs(sets, form, job.method, job.precision, job.conventions)


def unread(job: Job, given: Sequence[str]) -> list[str]:
    """The sets in ``given`` that a run with ``job`` does not read (:data:`READ_BY`). A value given
    and silently unused reads as if it had changed the answer; refusing it would break the habit
    of one command re-run with another method, so ``hconv one`` notes it after the result."""
    need = job.needs()
    return [k for k in READ_BY if k in given and k not in need]


def _sets(
    H: Numbers,
    I: Numbers,
    r: Numbers | None,
    q: Numbers | None,
    m: float | None,
    v: Numbers | None,
    job: Job,
    quantities: list[type],
) -> tuple[dict[str, np.ndarray], str]:
    """The body's values as :func:`hconv.solve.bodies.solve`'s sets, ``(k, 1)`` in SI, in the
    order H, I, r, q, v, m, and the name of I's form. A pint Quantity is read in its own unit, as
    :func:`hconv.convert` reads one (:mod:`hconv.solve.arguments`), its class appended to
    ``quantities``; a unit option for a set given as a Quantity would apply a second unit."""
    given_units = dict(job.unit_options)

    def read(name: str, value: Any, count: int | None) -> np.ndarray:
        before = len(quantities)
        x = _values(name, value, count, quantities)
        if len(quantities) > before and name in given_units:
            raise UsageError(
                f"{name} is a pint Quantity, which carries its unit: drop "
                f"{entry('unit_options', name, given_units[name])}"
            )
        return x

    i = read("I", I, None)
    form = forms.by_count(len(i))
    if form is None:
        raise UsageError(f"I takes {forms.counts_text()} values, got {len(i)}")
    values: dict[str, np.ndarray] = {"H": read("H", H, 3), "I": i}
    for name, value, k in (("r", r, 3), ("q", q, 4), ("v", v, 3), ("m", m, 1)):
        if value is not None:
            values[name] = read(name, value, k)
    for key, unit in job.unit_options:
        if key not in UNIT_SETS:
            command = "hconv one" if errors.on_command_line() else "convert_body"
            raise UsageError(
                f"{entry('unit_options', key, unit)}: {command} takes a unit per set: {', '.join(UNIT_SETS)}"
            )
    with np.errstate(over="ignore"):  # an overflow is the status invalid_input, not a warning
        sets = {name: x[:, None] * job.set_factor(name) for name, x in values.items()}
    need = job.needs()
    missing = [k for k in need if k not in sets]
    if missing:  # every value at once: one run to find them all, not one per missing value
        if errors.on_command_line():
            wanted = " ".join(f"--{k} {VALUES[k]}" for k in missing)
        else:
            wanted = ", ".join(f"{k}=..." for k in missing)
        raise UsageError(f"{needs_text([need[k] for k in missing])}; pass {wanted}")
    return sets, form.name


def _values(name: str, value: Any, count: int | None, quantities: list[type]) -> np.ndarray:
    """``value`` as float64 numbers in SI, ``count`` of them (None: any); numbers with a unit or
    a mask as :func:`hconv.solve.arguments.as_float` reads them."""
    try:
        x = arguments.as_float(name, value, quantities).ravel()
    except UsageError:
        raise
    except (TypeError, ValueError):
        raise UsageError(f"{name} takes numbers, got {value!r}") from None
    if count is not None and x.size != count:
        raise UsageError(f"{name} takes {count} number{'s' if count > 1 else ''}, got {x.size}")
    return x


def needs_text(reasons: list[str]) -> str:
    """Reasons such as "--about free needs r, ..." as one sentence, each option named once."""
    heads: dict[str, list[str]] = {}
    for reason in reasons:
        head, sep, tail = reason.partition(" needs ")
        heads.setdefault(head if sep else reason, []).append(tail if sep else "")
    parts = []
    for head, tails in heads.items():
        tails = [t for t in tails if t]
        if not tails:
            parts.append(head)
        else:
            listed = tails[0] if len(tails) == 1 else "; ".join(tails[:-1]) + "; and " + tails[-1]
            parts.append(f"{head} needs {listed}")
    return "; ".join(parts)


def unread_note(names: list[str]) -> str:
    """One note: the values given that the run did not read (:func:`unread`), and who reads them."""
    said = "; ".join(f"--{k} is read only {READ_BY[k]}" for k in names)
    return f"hconv: this run did not use {' or '.join(f'--{k}' for k in names)}: {said}"


def cancellation_hint(state: str, residual: float) -> str:
    """What losing digits to H - r × m·v means for this body, and the fix."""
    head = "hconv: cancellation" + (
        "" if state == "cancellation" else f" (the status shows {state}, which comes first)"
    )
    if residual >= 1:
        # The bound is first order: once it reaches |ω| no digit is left, and it bounds nothing
        # (a trial row was off by 48 |ω| with a residual of 10.6).
        what = (
            f"{DIFFERENCE} cancels all of H's digits that survived the inputs' rounding to float64, so ω is "
            f"unknown: not one digit of it holds, and the residual ({residual:.2g}) is no bound on its error"
        )
    else:
        what = (
            f"{DIFFERENCE} cancels most of H's digits, so the inputs' rounding to float64 may put ω off "
            f"by up to {residual:.2g} of |ω| (the residual)"
        )
    fix = option("about", "same").replace(" ", "\xa0")
    return f"{head}: {what}; give H about the centre of mass, with {fix}"


def invalid_hint(causes: list[tuple[str, str]], given: dict[str, str | None], precision: int) -> str:
    """One line: the first value that makes the body's input invalid, as given (``given``: the
    text of each value), and the fix."""
    if not causes:
        return (
            f"hconv: every value is finite, but one overflows float{precision} on the way to ω "
            "(the rotation by q or the change of point, --about); give smaller values"
        )
    name, problem = causes[0]
    text = given[name] or ""
    if problem == "not_finite" and all(math.isfinite(float(x)) for x in text.split(",")):
        return f"hconv: {name} = {text} overflows float64 once converted to SI units (--unit); give smaller values"
    return f"hconv: {name} = {text} {INVALID_HINTS[problem]}"
