"""Per-tick kernels compiled by numba, or left as Python when numba is missing.

The kernels are plain scalar loops written so that their Python source and numba's
compiled code give the same numbers to the bit (no ``fastmath``): without numba they
run as they are, slower.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["compile_kernels"]


def compile_kernels(*kernels: Callable[..., Any]) -> tuple[Any, ...]:
    """The kernels compiled by numba, then whether they were (``(*kernels, compiled)``).

    Compiled once per machine and cached (beside the kernels' module, or in numba's cache
    folder); numba is imported here, on the first use of a kernel module only.

    Args:
        kernels: the Python functions to compile.
    """
    try:
        import numba
    except ImportError:  # the same numbers, slower
        return (*kernels, False)
    jit = numba.njit(cache=True, nogil=True)
    return (*(jit(k) for k in kernels), True)
