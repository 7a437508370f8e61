"""The root of the engine's typed exceptions.

Every error the engine raises on purpose derives from :class:`SutureError`.
Modules define their own subclasses next to the code that raises them and
carry structured fields (the offending value, the bound, the valid names), so
that the CLI can print a located, human message and never a traceback.
"""

from __future__ import annotations

__all__ = ["SutureError"]


class SutureError(Exception):
    """Base class of every error the engine raises on purpose.

    Attributes:
        code: a short, stable, kebab-case identifier of the error kind
            (``"unknown-skill"``, ``"unit-mismatch"``), used in CLI output.
    """

    code: str = "error"

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message
