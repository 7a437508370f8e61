"""Seeing runs and sweeping procedures: figures, HTML reports, parameter sweeps.

The submodules import matplotlib and numpy lazily, so that importing this package
costs nothing to ``suture validate``.
"""

from __future__ import annotations

__all__: list[str] = []
