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
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["decode", "encode", "encode_vectors"]


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


_FAST: list[Any] = []
"""(orjson.dumps, its numpy option, numpy.ndarray, float64 dtype), or [None] without
orjson; filled on the first :func:`encode_vectors` call (``suture validate`` imports
neither orjson nor numpy)."""


def _fast_vectors() -> Any:
    if not _FAST:
        try:
            import numpy as np
            import orjson
        except ImportError:  # the vector fast path is then off; encode() still works
            _FAST.append(None)
        else:
            _FAST.append((orjson.dumps, orjson.OPT_SERIALIZE_NUMPY, np.ndarray, np.dtype("=f8")))
    return _FAST[0]


def _python_exponents(data: bytes) -> bytes:
    """orjson's exponents in Python's ``repr`` form: ``1e16`` -> ``1e+16``,
    ``1e-7`` -> ``1e-07`` (a sign always, two digits at least)."""
    parts = data.split(b"e")
    for i in range(1, len(parts)):
        p = parts[i]
        if p[:1] == b"-":
            if not p[2:3].isdigit():
                parts[i] = b"-0" + p[1:]
        elif p[1:2].isdigit():
            parts[i] = b"+" + p
        else:
            parts[i] = b"+0" + p
    return b"e".join(parts)


def _python_form(vector: Any) -> bytes:
    """One vector's items as :func:`encode` writes them (``repr`` of each float), for
    a vector with a number from 1e-5 to 1e-4, where orjson writes ``0.00005`` and
    ``repr`` ``5e-05``: ``str`` of a list of floats is their ``repr`` joined by ``", "``.
    """
    items = vector if type(vector) is list else vector.tolist()
    text = str(items)
    if "n" in text:  # nan, inf: null, through the generic encoder
        return encode(items)[1:-1]
    return text[1:-1].replace(", ", ",").encode()


def encode_vectors(vectors: Sequence[Any]) -> list[bytes] | None:
    """The JSON text of each float vector, exactly as :func:`encode` writes it as a list.

    One call encodes all of a tick's vectors with orjson's compiled float formatter and
    puts every number in Python's ``repr`` form (the form :func:`encode` writes): the
    same bytes at a fraction of the cost (``repr`` of a float costs about a microsecond).
    A non-finite value is ``null``, as in :func:`encode`.

    Args:
        vectors: 1-D C-contiguous native float64 NumPy arrays, or lists of Python floats.

    Returns:
        Per vector, its items without the brackets (``b"1.5,-0.25"``); None when orjson
        is not installed or a vector is of another kind (then use :func:`encode`).
    """
    fast = _FAST[0] if _FAST else _fast_vectors()
    if fast is None:
        return None
    dumps, option, ndarray, f64 = fast
    for v in vectors:
        if type(v) is list:
            if not all(type(x) is float for x in v):
                return None
        elif type(v) is not ndarray or v.ndim != 1 or not v.flags.c_contiguous:
            return None
        elif v.dtype is not f64 and v.dtype != f64:
            return None
    if not vectors:
        return []
    try:
        data: bytes = dumps(vectors, option=option)
    except TypeError:  # orjson.JSONEncodeError: an array orjson refuses
        return None
    # orjson writes the shortest round-trip digits, like repr, but lays some numbers out
    # otherwise: exponents without "+" or a leading zero, and 0.00005 for 5e-05.
    if b"e" in data:  # the text holds only numbers, "null", "[", "]" and ","
        data = _python_exponents(data)
    texts = data[2:-2].split(b"],[")
    if b"0.0000" in data:
        for i, text in enumerate(texts):
            if b"0.0000" in text:
                texts[i] = _python_form(vectors[i])
    return texts


def decode(data: bytes | memoryview) -> Any:
    """Decodes one message.

    Raises:
        ValueError: the bytes are not UTF-8 JSON.
    """
    return json.loads(bytes(data))
