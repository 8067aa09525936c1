"""Layer 2, solving: the methods, statuses, units, inertia forms and scene conventions, and
:func:`hconv.solve.convert.convert` over numpy arrays. Imports only :mod:`hconv.kernels` and
:mod:`hconv.errors`; never pyarrow or rich.
"""
