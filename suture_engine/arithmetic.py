"""One floating-point arithmetic on every x86-64 machine: the BLAS kernel is pinned.

numpy's linear algebra (``@``, ``np.linalg.norm``, ``np.dot``, LAPACK through scipy)
runs in OpenBLAS, which picks its kernels for the CPU it finds at load time. Kernels
built for different CPUs round differently: the same 3-vector's norm comes out one
unit in the last place apart on an AVX-512 machine (OpenBLAS ``SkylakeX``, with fused
multiply-adds) and on an AVX2 one (``Haswell``, without them). A run amplifies such a
bit: a move's duration one ULP shorter, a guarded move that stops one tick earlier, a
knot throw that ties or does not. The same seed then gave different knots on
different machines.

:func:`pin_blas_kernel` asks OpenBLAS for its ``Haswell`` kernels on every CPU that
can run them (AVX2 and FMA: x86-64 machines since about 2013, AVX-512 ones included),
by setting ``OPENBLAS_CORETYPE`` before numpy loads OpenBLAS. ``import suture_engine``
does it, so ``suture run``, the pytest plugin and sweep workers get it. It changes
nothing where the variable is already set (the user's choice wins), on other CPUs, or
once numpy is loaded (then :func:`arithmetic_record` says so in the trace).

numpy's own SIMD loops are not pinned by it: on AVX-512 machines its elementwise
sines and cosines (SVML) and its ``einsum`` reductions run other code. The physics and
the skills use :func:`row_dot`, :func:`sin`, :func:`cos` and :func:`arcsin` for those: elementwise
products and sums, and the C library's functions, which round the same on every CPU.
Not covered: ``np.tanh`` in the hybrid force controller (numpy's own, which already
differs from the C library's here), MKL builds of numpy, non-x86 CPUs.
"""

from __future__ import annotations

import math
import os
import platform
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # numpy is not imported here at run time: the pin must come first
    from numpy.typing import NDArray

CANONICAL_CORE = "Haswell"
"""The OpenBLAS kernel set every traced run uses where the CPU can run it."""

_REQUIRED_FLAGS = frozenset({"avx2", "fma"})
"""CPU flags (``/proc/cpuinfo``) the ``Haswell`` kernels need."""

_state: dict[str, object] = {}


def cpu_flags(cpuinfo: Path = Path("/proc/cpuinfo")) -> frozenset[str]:
    """The first processor's feature flags from ``cpuinfo`` (empty when unreadable)."""
    try:
        with cpuinfo.open(encoding="ascii", errors="replace") as fh:
            for line in fh:
                if line.startswith("flags"):
                    return frozenset(line.partition(":")[2].split())
    except OSError:
        pass
    return frozenset()


def pin_blas_kernel(
    environ: dict[str, str] | None = None,
    *,
    flags: frozenset[str] | None = None,
    machine: str | None = None,
    numpy_loaded: bool | None = None,
) -> str:
    """Set ``OPENBLAS_CORETYPE`` to :data:`CANONICAL_CORE` where that is safe and useful.

    Args:
        environ: the environment to change (default: ``os.environ``).
        flags: the CPU's flags (default: read from ``/proc/cpuinfo`` on Linux).
        machine: ``platform.machine()`` (default: this one).
        numpy_loaded: whether numpy is already imported (default: look in ``sys.modules``).

    Returns:
        What was done: ``"pinned"``, ``"user"`` (the variable was already set),
        ``"numpy-first"`` (numpy was loaded before, too late to pin), ``"not-x86"``,
        or ``"cpu"`` (the CPU lacks AVX2 or FMA).
    """
    env = os.environ if environ is None else environ
    arch = (platform.machine() if machine is None else machine).lower()
    loaded = ("numpy" in sys.modules) if numpy_loaded is None else numpy_loaded
    if env.get("OPENBLAS_CORETYPE"):
        return "user"
    if loaded:
        return "numpy-first"
    if arch not in ("x86_64", "amd64"):
        return "not-x86"
    have = cpu_flags() if flags is None else flags
    if not _REQUIRED_FLAGS <= have:
        return "cpu"
    env["OPENBLAS_CORETYPE"] = CANONICAL_CORE
    return "pinned"


def arithmetic_record() -> dict[str, str]:
    """What the trace's metadata says of the run's arithmetic.

    ``blas_kernel`` is the OpenBLAS kernel set asked for (``"auto"``: OpenBLAS chose
    for the CPU, and runs are comparable only on like CPUs); ``pin`` is what
    :func:`pin_blas_kernel` did at import.
    """
    return {
        "blas_kernel": str(_state.get("kernel", "auto")),
        "pin": str(_state.get("outcome", "not-run")),
    }


def pin_at_import() -> None:
    """Pin at ``import suture_engine`` and remember the outcome for the trace."""
    outcome = pin_blas_kernel()
    _state["outcome"] = outcome
    core = os.environ.get("OPENBLAS_CORETYPE")
    if outcome in ("pinned", "user") and core:
        _state["kernel"] = core


def row_dot(a: NDArray[Any], b: NDArray[Any]) -> NDArray[Any]:
    """Dot products of 3-vectors along the last axis (broadcast), summed (x0 + x2) + x1.

    The same floats as ``np.einsum("ij,ij->i", a, b)`` (and ``"kij,ij->ki"``) gives on
    AVX2 machines, whose loop takes the three terms in that order, but from elementwise
    products and sums, which round the same on every CPU.
    """
    p = a * b
    out: NDArray[Any] = (p[..., 0] + p[..., 2]) + p[..., 1]
    return out


def _libm(fn: Any, x: NDArray[Any]) -> NDArray[Any]:
    """``fn`` (a ``math`` function) applied elementwise to ``x``."""
    import numpy as np

    arr = np.asarray(x, dtype=np.float64)
    flat = arr.ravel().tolist()
    return np.fromiter(map(fn, flat), np.float64, arr.size).reshape(arr.shape)


def sin(x: NDArray[Any]) -> NDArray[Any]:
    """Elementwise sine [-] of ``x`` [rad] by the C library (``math.sin``), on any CPU."""
    return _libm(math.sin, x)


def cos(x: NDArray[Any]) -> NDArray[Any]:
    """Elementwise cosine [-] of ``x`` [rad] by the C library (``math.cos``), on any CPU."""
    return _libm(math.cos, x)


def arcsin(x: NDArray[Any]) -> NDArray[Any]:
    """Elementwise arcsine [rad] of ``x`` [-] in [-1, 1] by the C library, on any CPU."""
    return _libm(math.asin, x)
