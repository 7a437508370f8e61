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

Not pinned by this: numpy's own SIMD loops (its elementwise transcendental functions
and einsum pick AVX-512 code on AVX-512 machines), MKL builds of numpy, non-x86 CPUs.
"""

from __future__ import annotations

import os
import platform
import sys
from pathlib import Path

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
    """Pin once, at ``import suture_engine``, and remember the outcome for the trace."""
    if "outcome" in _state:
        return
    outcome = pin_blas_kernel()
    _state["outcome"] = outcome
    core = os.environ.get("OPENBLAS_CORETYPE")
    if outcome in ("pinned", "user") and core:
        _state["kernel"] = core
