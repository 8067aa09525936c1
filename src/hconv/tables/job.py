"""The run configuration: one :class:`Job` holds everything a conversion needs besides the data.

A Job is made once, from the CLI's options or from Python, and checked when it is made: every
problem is one :class:`~hconv.errors.UsageError` with one message (the checks themselves are
:mod:`hconv.solve.options`'). ``hconv convert``, ``compare``, ``diagnose`` and ``one`` all build a
Job; the file pipeline, the Arrow adapter and the column planner (:func:`hconv.tables.layout.plan`,
a pure function of the input's schema and the Job) only read it. This module imports neither
pyarrow nor rich, so that ``hconv one`` stays quick.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from hconv.errors import UsageError, entry, option
from hconv.solve import methods, options, units
from hconv.solve.options import Options
from hconv.tables.sets import QUANTITY, all_names, quantity_of

#: The delimiters a CSV may have (DuckDB's candidates), each with the word messages use for it.
DELIMITERS = {",": "comma", ";": "semicolon", "\t": "tab", "|": "bar"}
#: How ``delimiter`` may be spelled: the character itself, or its word (a tab is hard to type).
DELIMITER_SPELLINGS = {**{d: d for d in DELIMITERS}, **{w: d for d, w in DELIMITERS.items()}, "\\t": "\t", "pipe": "|"}
#: The decimal marks a CSV's numbers may have.
DECIMALS = {".": "point", ",": "comma"}


def _pairs(what: str, value: Any) -> tuple:
    """``value`` as a tuple of (name, value) string pairs: from a dict, or from pairs."""
    items = value.items() if isinstance(value, dict) else value
    try:
        pairs = tuple((str(a), str(b)) for a, b in items)
    except (TypeError, ValueError):
        raise UsageError(
            f"{what} takes a dict such as {{'Hx': 'Lx'}} or pairs such as (('Hx', 'Lx'),), got {value!r}"
        ) from None
    return pairs


def _check_mapping(pairs: tuple) -> None:
    """--map names hconv's own columns, each once, each at its own column."""
    names = all_names()
    given: dict[str, str] = {}
    seen: dict[str, str] = {}
    for name, column in pairs:
        if name not in names:
            raise UsageError(
                f"{entry('mapping', name, column)}: hconv has no column {name!r}; map one of {', '.join(names)}"
            )
        if name in given and given[name] != column:
            raise UsageError(f"{option('mapping')} gives {name} twice ({given[name]} and {column}); give it once")
        given[name] = column
    for name, column in given.items():
        if column in seen:
            raise UsageError(
                f"{option('mapping')} points both {seen[column]} and {name} at column {column!r}; one column, one name"
            )
        seen[column] = name


def _check_units_once(pairs: tuple) -> None:
    """--unit gives each key one unit (the same one twice is fine), as --map gives each name one column."""
    given: dict[str, str] = {}
    for key, unit in pairs:
        if key in given and given[key] != unit:
            raise UsageError(f"{option('unit_options')} gives {key} twice ({given[key]} and {unit}); give it once")
        given[key] = unit


@dataclass(frozen=True, kw_only=True)
class Job(Options):
    """Everything a conversion needs besides the data; checked when made.

    The solve-level part (method, precision, diagnostics, conventions, engine) is
    :class:`~hconv.solve.options.Options`', which a Job extends; its own fields are keywords only.
    Defaults are hconv's own conventions. ``mapping`` reads hconv's names from other columns
    (``--map``; a dict or (name, column) pairs); ``unit_options`` gives units by set, hconv name
    or column (``--unit``; a dict or pairs). ``observed``: the run compares with an observed ω
    (``hconv diagnose``): the ``w_obs`` columns are required, and hconv's output columns may be
    present in the input. ``keep_text`` (``--keep-text``): from CSV into Parquet, the columns
    hconv does not use stay text instead of getting types (:mod:`hconv.tables.csvtypes`).
    ``field_units`` (Python only): each column's unit as its field metadata would give it, for data
    whose engine dropped that metadata on the way (``hconv.units_of(files)``, docs/recipes.md); a
    column's own metadata and ``unit_options`` come first, and a column hconv does not read is
    left alone, as its metadata would be. ``prefix`` (``--prefix``) goes before the name of every
    column hconv appends (``wx`` becomes ``out_wx`` with ``prefix='out_'``), so that an input
    that already has a ``status`` or a ``wx`` column can be converted. ``delimiter`` and
    ``decimal`` (``--delimiter``, ``--decimal``): how a CSV input is written, where sniffing it
    would otherwise decide (docs/input.md); None: sniffed.
    """

    mapping: tuple = ()
    unit_options: tuple = ()
    quat_order: str = "wxyz"
    omega_unit: str = "rad/s"
    observed: bool = False
    keep_text: bool = False  #: CSV to Parquet: the other columns stay text, as in the CSV
    field_units: tuple = ()  #: (column, unit) pairs, as field metadata would give them
    delimiter: str | None = None  #: a CSV input's delimiter, one of DELIMITERS; None: sniffed
    decimal: str | None = None  #: a CSV input's decimal mark, one of DECIMALS; None: sniffed
    prefix: str = ""  #: put before the name of every column hconv appends (wx: Pwx), for an input that has them

    def __post_init__(self) -> None:
        object.__setattr__(self, "mapping", _pairs("mapping", self.mapping))
        object.__setattr__(self, "unit_options", _pairs("unit_options", self.unit_options))
        object.__setattr__(self, "field_units", _pairs("field_units", self.field_units))
        _check_mapping(self.mapping)
        _check_dialect(self)
        _check_units_once(self.unit_options)
        for key, unit in self.unit_options:
            quantity = quantity_of(key)
            if quantity is not None:  # a set or one of hconv's names: its unit can be checked now
                units.factor(quantity, unit, entry("unit_options", key, unit))
        super().__post_init__()  # the method, precision, diagnostics, conventions and engine
        m = methods.get(self.method)
        options.check_choice("quat_order", self.quat_order, options.QUAT_ORDERS)
        for name in ("observed", "keep_text"):  # diagnostics='no' would read as True
            if not isinstance(getattr(self, name), bool):
                raise UsageError(f"{option(name)} must be True or False, got {getattr(self, name)!r}")
        if not isinstance(self.prefix, str) or any(c in self.prefix for c in ',\n\r"'):
            raise UsageError(
                f"{option('prefix')} takes text to put before hconv's column names, without commas, quotes or "
                f"line breaks, e.g. 'out_', got {self.prefix!r}"
            )
        # an unknown unit fails now, not mid-run
        if not isinstance(self.omega_unit, str):
            raise UsageError(f"{option('omega_unit')} takes a unit as text, e.g. 'deg/s', got {self.omega_unit!r}")
        w_factor = units.factor("w", self.omega_unit, option("omega_unit"))
        if m.unit != methods.RAD_S and w_factor != 1.0:
            raise UsageError(
                f"{option('omega_unit', self.omega_unit)}: method {self.method!r} gives {m.unit}, "
                "which is not an angular velocity and cannot be converted"
            )

    @property
    def unit(self) -> str:
        """The unit of ω in the output."""
        m = methods.get(self.method)
        return self.omega_unit if m.unit == methods.RAD_S else m.unit

    @property
    def omega_scale(self) -> float:
        """The factor from the method's ω to the output's (1 unless ``omega_unit`` asks otherwise)."""
        return units.omega_factor(self.omega_unit) if methods.get(self.method).unit == methods.RAD_S else 1.0

    def needs(self) -> dict:
        """The sets, besides H and I, that this run cannot do without, each with the reason."""
        need = self.conventions.needs(self.method)
        if self.observed:
            need["w_obs"] = "diagnose compares with the ω your engine produced"
        return need

    def set_factor(self, name: str) -> float:
        """The factor to SI for a whole set given by ``--unit SET=UNIT`` (1 when none is)."""
        given = dict(self.unit_options)
        if name not in given:
            return 1.0
        return units.factor(QUANTITY[name], given[name], entry("unit_options", name, given[name]))


def _check_dialect(job: Job) -> None:
    """``delimiter`` as one of :data:`DELIMITERS` (given as a character or its word), ``decimal``
    as one of :data:`DECIMALS`; a decimal comma with a comma delimiter could not be read."""
    if job.delimiter is not None:
        d = DELIMITER_SPELLINGS.get(job.delimiter) if isinstance(job.delimiter, str) else None
        if d is None:
            raise UsageError(
                f"{option('delimiter')} takes one of {', '.join(repr(k) for k in DELIMITERS)} "
                f"(or comma, semicolon, tab, bar), got {job.delimiter!r}"
            )
        object.__setattr__(job, "delimiter", d)
    if job.decimal is not None:
        if job.decimal not in DECIMALS:
            raise UsageError(f"{option('decimal')} takes '.' or ',', got {job.decimal!r}")
        if job.decimal == "," and job.delimiter == ",":
            raise UsageError(
                f"{option('decimal', ',')} needs another delimiter than the comma; "
                f"pass {option('delimiter', ';')} (or tab) as well, or drop {option('decimal')}"
            )


def check_job(job: object) -> None:
    """UsageError unless ``job`` is a Job or None: every function that takes ``job=`` checks
    it first (by :func:`hconv.solve.options.configure`), so that ``job='exact'`` is not an
    AttributeError deep inside."""
    if job is not None and not isinstance(job, Job):
        options.configure(Job, "job", job)
