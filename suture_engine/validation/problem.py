"""The record of one problem found in a procedure.

Every check of the dry-run (schema, graph, units, expressions, scene
references, reachability, safety limits) reports :class:`Problem` records, all
of them, never only the first. Each record names the file, line and column of
the offending node, its field path, a short stable code and a message.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

__all__ = ["Problem", "ProblemError"]

from suture_engine.errors import SutureError


@dataclass(frozen=True)
class Problem:
    """One problem found in a procedure.

    Attributes:
        code: short kebab-case identifier of the problem kind (``"unit-mismatch"``).
        message: what was expected and what was found.
        file: the file the offending node comes from ("" when not known yet).
        line: 1-based line of the offending node (0 when not known).
        column: 1-based column of the offending node (0 when not known).
        path: dotted field path (``"states.tie.with.tension"``).
    """

    code: str
    message: str
    file: str = ""
    line: int = 0
    column: int = 0
    path: str = ""

    def located(self, file: str, line: int, column: int, path: str | None = None) -> Problem:
        """Return a copy placed at ``file:line:column`` (and ``path`` when given)."""
        return dataclasses.replace(
            self, file=file, line=line, column=column, path=self.path if path is None else path
        )

    def format(self) -> str:
        """The one-line text form ``file:line:col: code: message (at path)``."""
        where = f" (at {self.path})" if self.path else ""
        return f"{self.file}:{self.line}:{self.column}: {self.code}: {self.message}{where}"

    def as_dict(self) -> dict[str, Any]:
        """The JSON form: ``file``, ``line``, ``column``, ``path``, ``code``, ``message``."""
        return {
            "file": self.file,
            "line": self.line,
            "column": self.column,
            "path": self.path,
            "code": self.code,
            "message": self.message,
        }


class ProblemError(SutureError):
    """Raised when loading cannot go on; carries the problems found so far.

    Attributes:
        problems: the located problems (at least one).
    """

    def __init__(self, problems: list[Problem]) -> None:
        super().__init__("; ".join(p.format() for p in problems) or "invalid procedure")
        self.problems = list(problems)
        self.code = self.problems[0].code if self.problems else "invalid"
