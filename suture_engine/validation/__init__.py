"""Static checks of a procedure: the dry-run behind ``suture validate``."""

from __future__ import annotations

from suture_engine.validation.problem import Problem, ProblemError

__all__ = ["Problem", "ProblemError"]
