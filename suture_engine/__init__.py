"""suture-engine: runs robotic suturing procedures written in YAML.

The engine loads a procedure (``suture_engine.language``), checks it without
running it (``suture_engine.validation``), and runs it on a backend under the
supervisory hybrid automaton (``suture_engine.runtime``), writing a trace
(``suture_engine.trace``). The thesis' math lives in ``suture_engine.robot``,
``suture_engine.control`` and ``suture_engine.suture``.

Heavy modules (pybullet, osqp, scipy, matplotlib) are imported lazily so that
``suture validate`` starts fast.
"""

from __future__ import annotations

__all__ = ["__version__"]

__version__ = "0.1.0"
