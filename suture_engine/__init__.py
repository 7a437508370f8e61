"""suture-engine: runs robotic suturing procedures written in YAML.

The engine loads a procedure (``suture_engine.language``), checks it without
running it (``suture_engine.validation``), and runs it on a backend under the
supervisory hybrid automaton (``suture_engine.runtime``), writing a trace
(``suture_engine.trace``). The thesis' math lives in ``suture_engine.robot``,
``suture_engine.control`` and ``suture_engine.suture``.

Heavy modules (pybullet, osqp, scipy, matplotlib) are imported lazily so that
``suture validate`` starts fast.

Importing the package first pins OpenBLAS to one kernel set
(``suture_engine.arithmetic``), so that a seed gives the same trace on every x86-64
machine with AVX2; it must run before numpy loads.
"""

from __future__ import annotations

from suture_engine.arithmetic import pin_at_import

pin_at_import()

__all__ = ["__version__"]

__version__ = "0.1.0"
