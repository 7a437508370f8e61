"""Deterministic JSON encoding of trace messages.

Messages are encoded as compact UTF-8 JSON with sorted keys. Floats use
Python's shortest round-trip representation, which is exact and does not
depend on the platform, so the same values always give the same bytes.
NumPy scalars and arrays are converted to plain numbers and lists. JSON has
no NaN or infinity: a non-finite float is written as ``null``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

__all__ = ["decode", "encode"]


def _default(obj: Any) -> Any:
    """Converts what the C encoder does not know (NumPy, tuples of NamedTuples are fine)."""
    tolist = getattr(obj, "tolist", None)
    if tolist is not None:  # numpy arrays and scalars
        return tolist()
    if hasattr(obj, "_asdict"):
        return obj._asdict()
    if isinstance(obj, (set, frozenset)):
        return sorted(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON-serialisable")


def _finite(obj: Any) -> Any:
    """Replaces non-finite floats by ``None``, recursively (slow path)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    tolist = getattr(obj, "tolist", None)
    if tolist is not None:
        return _finite(tolist())
    return obj


_ENCODER_WITH_DEFAULT = json.JSONEncoder(
    sort_keys=True,
    separators=(",", ":"),
    allow_nan=False,
    ensure_ascii=False,
    default=_default,
)


def _make_fast() -> Any:
    """The C encoder that ``_ENCODER_WITH_DEFAULT.encode`` builds on every call, built once.

    Same settings, so the same bytes; ``JSONEncoder.encode`` re-creates it (and a Python
    closure) per message, which costs several times the encoding of a small message.
    None when the C accelerator is not available.
    """
    make = getattr(json.encoder, "c_make_encoder", None)
    if make is None:
        return None
    e = _ENCODER_WITH_DEFAULT
    return make(
        {},  # circular-reference markers; emptied again by every successful call
        e.default,
        json.encoder.encode_basestring,  # ensure_ascii=False
        None,  # indent
        e.key_separator,
        e.item_separator,
        e.sort_keys,
        e.skipkeys,
        e.allow_nan,
    )


_fast = _make_fast()


def encode(message: Any) -> bytes:
    """Encodes one message as deterministic JSON.

    Args:
        message: a JSON-like value (dicts with string keys, lists, numbers, strings,
            booleans, ``None``; NumPy arrays and scalars are accepted).

    Returns:
        The UTF-8 bytes.

    Raises:
        TypeError: a value cannot be represented in JSON.
        ValueError: circular references.
    """
    global _fast
    try:
        if _fast is not None and not isinstance(message, str):
            try:
                text = "".join(_fast(message, 0))
            except BaseException:
                _fast = _make_fast()  # a failed call may leave markers behind
                raise
        else:
            text = _ENCODER_WITH_DEFAULT.encode(message)
    except ValueError as exc:
        if "Out of range float" not in str(exc):
            raise
        text = _ENCODER_WITH_DEFAULT.encode(_finite(message))
    return text.encode("utf-8")


def decode(data: bytes | memoryview) -> Any:
    """Decodes one message.

    Raises:
        ValueError: the bytes are not UTF-8 JSON.
    """
    return json.loads(bytes(data))
