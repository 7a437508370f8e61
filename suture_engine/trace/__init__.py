"""Traces: one MCAP file per run, with JSON-schema channels (DESIGN section 8).

- :mod:`~suture_engine.trace.channels`: the channel catalogue and schemas.
- :mod:`~suture_engine.trace.writer`: :class:`TraceWriter`, deterministic and crash-safe.
- :mod:`~suture_engine.trace.reader`: :class:`TraceReader`, reads complete or truncated traces.
- :mod:`~suture_engine.trace.golden`: compares two traces with explicit tolerances.
- :mod:`~suture_engine.trace.pytest_plugin`: the ``golden_trace`` fixture.
- :mod:`~suture_engine.trace.cli_trace`: ``suture trace`` and ``suture diff``.
- :mod:`~suture_engine.trace.synthetic`: run-like synthetic traces for tests and benchmarks.
- :mod:`~suture_engine.trace.errors`: the typed ``TraceError`` family.

The submodules import the mcap package lazily; import them directly.
"""

from __future__ import annotations

__all__: list[str] = []
