"""The compiled engine's extension module; everything else about the package is in pyproject.toml.

The flags make the C code round exactly as written, which the engine's bit-for-bit contract with
the numpy engine needs (docs/engines.md): no contraction of a*b + c into a fused multiply-add, no
fast-math, and no -march (the wheel runs on any CPU of its platform).
"""

import sys

import numpy
from setuptools import Extension, setup

if sys.platform == "win32":
    flags = ["/O2", "/fp:precise"]
else:
    flags = ["-O3", "-ffp-contract=off", "-fno-math-errno", "-fno-trapping-math"]

setup(
    ext_modules=[
        Extension(
            "hconv.solve.rowcode",
            ["src/hconv/solve/rowcode.c"],
            # its chunk code, included by rowcode.c: a change to it rebuilds the extension
            depends=["src/hconv/solve/rowmath.h"],
            include_dirs=[numpy.get_include()],
            extra_compile_args=flags,
            define_macros=[("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")],
        )
    ]
)
