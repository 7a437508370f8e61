"""Fault injection: faults as data, a backend wrapper that injects them, the campaign.

- :mod:`~suture_engine.faults.model`: :class:`Fault`, the scene's ``faults:`` entries;
- :mod:`~suture_engine.faults.syntax`: the ``--fault SPEC`` one-line syntax;
- :mod:`~suture_engine.faults.support`: which backend simulates which fault;
- :mod:`~suture_engine.faults.schedule`: when each fault is active (triggers, seeds);
- :mod:`~suture_engine.faults.record`: the ``/faults`` trace records;
- :mod:`~suture_engine.faults.backend`: :class:`FaultyBackend`, the injecting wrapper;
- :mod:`~suture_engine.faults.campaign`: random faults over many runs, classified.

Only the model and the syntax are imported here (``suture validate`` stays light).
"""

from __future__ import annotations

from suture_engine.faults.model import FAULT_KINDS, Fault
from suture_engine.faults.syntax import (
    FaultSpecError,
    FaultSyntaxError,
    FaultValueError,
    format_fault,
    parse_fault,
)

__all__ = [
    "FAULT_KINDS",
    "Fault",
    "FaultSpecError",
    "FaultSyntaxError",
    "FaultValueError",
    "format_fault",
    "parse_fault",
]
