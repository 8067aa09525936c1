# The compiled engine's C code (rowcode.c): what hconv.solve.compiled calls.
from typing import Any

import numpy as np

#: rows the C code converts together (its chunk, CH)
CHUNK_ROWS: int

def configure(constants: dict[str, float], /) -> None: ...
def kernels() -> list[str]: ...
def use(name: str, /) -> None: ...
def one(
    I: np.ndarray, nine: bool, H: np.ndarray, refined: bool, diagnostics: bool, cond_limit: float, /
) -> tuple[np.ndarray, Any, Any, Any, bool] | None: ...
def stack(
    I: np.ndarray, H: np.ndarray, refined: bool, diagnostics: bool, cond_limit: float, /
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None] | None: ...
def convert(
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
    stream: bool,
    start: int,
    stop: int,
    /,
) -> int: ...
def share(
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
    stream: bool,
    size: int,
    /,
) -> tuple[int, int]: ...
def serve(linger: float, /) -> int: ...
def serving() -> int: ...
def outputs(n: int, diagnostics: bool, /) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]: ...
def pool() -> dict[str, float]: ...
def release() -> None: ...
