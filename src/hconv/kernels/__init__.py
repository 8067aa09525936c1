"""Layer 1, kernels: numerical routines on column arrays, with no notion of files, options or methods.

Tensors are :class:`hconv.kernels.inertia.Sym3` of ``(N,)`` columns, vectors ``(3, N)`` and
rotations ``(3, 3, N)``: component-major, so that every entry is one contiguous column. Nothing
here imports another layer of hconv.
"""
