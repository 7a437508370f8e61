"""The runtime: the supervisory hybrid automaton and the tick loop (thesis 4.6).

Modules (imported on demand; nothing heavy is imported here):

- :mod:`~suture_engine.runtime.observation`: what skills see and return.
- :mod:`~suture_engine.runtime.automaton`: Lock / Manual / Autonomous, steps and NOT-BE states.
- :mod:`~suture_engine.runtime.plan`: a loaded procedure compiled into the automaton's plan.
- :mod:`~suture_engine.runtime.interpreter`: the tick loop.
- :mod:`~suture_engine.runtime.controller`: the joint laws of each mode (chapter 5).
- :mod:`~suture_engine.runtime.monitor`: invariants (4.43-4.45), the base-sensor tension
  estimate (7.6-7.9) and the emergency lock (tension near the limit, non-finite or stale sensors).
- :mod:`~suture_engine.runtime.operator`: scripted and interactive operator events.
- :mod:`~suture_engine.runtime.recorder`, :mod:`~suture_engine.runtime.summary`: trace, summary.
- :mod:`~suture_engine.runtime.evaluation`: knots per stitch and stitch metrics from ground truth.
- :mod:`~suture_engine.runtime.run`: ``suture run`` / ``suture replay``.
- :mod:`~suture_engine.runtime.testing`: the ideal backend and stub skills for tests.
"""

__all__: list[str] = []
