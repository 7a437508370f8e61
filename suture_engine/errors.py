"""The root of the engine's typed exceptions.

Every error the engine raises on purpose derives from :class:`SutureError`.
Modules define their own subclasses next to the code that raises them and
carry structured fields (the offending value, the bound, the valid names), so
that the CLI can print a located, human message and never a traceback.
"""

from __future__ import annotations

__all__ = ["InvalidValue", "SutureError"]


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


class InvalidValue(SutureError):
    """An argument outside what a function or an object accepts.

    Attributes:
        name: the offending argument.
        value: its value.
        expected: what was expected, in words ("> 0", "a finite number").
    """

    code = "bad-value"

    def __init__(self, name: str, value: object, expected: str) -> None:
        super().__init__(f"{name} must be {expected}, found {value!r}")
        self.name = name
        self.value = value
        self.expected = expected
