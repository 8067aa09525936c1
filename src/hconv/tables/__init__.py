"""Layer 3, tables: the run configuration (Job), column plans, the Arrow adapter, file I/O and the
whole-file pipeline. pyarrow is imported by the modules that need it, never by this package or
by :mod:`hconv.tables.job`, so that ``hconv one`` can build a Job without it.
"""
