"""Tests of the trace codec: deterministic JSON bytes, against json.dumps as the oracle."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from suture_engine.trace import codec


def _oracle(message: Any) -> bytes:
    """The documented encoding, by the standard library's one-shot json.dumps."""

    def plain(v: Any) -> Any:
        if isinstance(v, float):
            return v if math.isfinite(v) else None
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        if isinstance(v, np.ndarray):
            return plain(v.tolist())
        return v

    text = json.dumps(
        plain(message), sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False
    )
    return text.encode("utf-8")


_scalars = (
    st.floats(allow_nan=True, allow_infinity=True)
    | st.integers(min_value=-(2**63), max_value=2**63)
    | st.text(max_size=8)
    | st.booleans()
    | st.none()
)
_messages = st.recursive(
    _scalars,
    lambda inner: (
        st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=6), inner, max_size=5)
    ),
    max_leaves=30,
)


@settings(max_examples=300, deadline=None)
@given(_messages)
def test_encode_matches_json_dumps(message: Any) -> None:
    assert codec.encode(message) == _oracle(message)


def test_numpy_values_and_tuples() -> None:
    msg = {"q": np.array([0.1, -2.5e-7, 3.0]), "s": np.float64(1.5), "t": (1, 2)}
    assert codec.encode(msg) == b'{"q":[0.1,-2.5e-07,3.0],"s":1.5,"t":[1,2]}'
    assert codec.decode(codec.encode(msg)) == {"q": [0.1, -2.5e-07, 3.0], "s": 1.5, "t": [1, 2]}


def test_non_finite_floats_become_null() -> None:
    msg = {"a": [1.0, float("nan"), float("inf")], "b": np.array([-np.inf])}
    assert codec.encode(msg) == b'{"a":[1.0,null,null],"b":[null]}'


def test_errors_leave_the_encoder_usable() -> None:
    loop: dict[str, Any] = {}
    loop["self"] = loop
    with pytest.raises(ValueError, match="Circular"):
        codec.encode(loop)
    with pytest.raises(TypeError, match="not JSON-serialisable"):
        codec.encode({"x": object()})
    # A message sharing objects with the failed ones encodes normally afterwards.
    shared = [1.0, 2.0]
    assert codec.encode({"a": shared, "b": shared}) == b'{"a":[1.0,2.0],"b":[1.0,2.0]}'
    assert codec.encode({"k": 1}) == b'{"k":1}'


# -- encode_vectors: orjson's float formatter, laid out as the json module writes it ------


def _vector_oracle(vector: Any) -> bytes:
    """What json.dumps writes for the vector as a list of floats, without the brackets."""
    values = vector.tolist() if isinstance(vector, np.ndarray) else list(vector)
    return _oracle([float(v) for v in values])[1:-1]


def _magnitudes() -> list[float]:
    """Every decade of the float64 range, with mantissas that round differently, and
    the values at the edges of repr's positional range (1e-4, 1e16) and orjson's (1e-5)."""
    out = [0.0, -0.0, 5e-324, 2.2250738585072014e-308, 1.7976931348623157e308]
    for exponent in range(-323, 309):
        for mantissa in (1.0, 1.5, 2.2250738585072014, 4.9, 9.999999999999998):
            value = mantissa * 10.0**exponent if exponent < 308 else mantissa * 1e307 * 10.0
            if math.isfinite(value):
                out += [value, -value]
    out += [1e-4, 9.999e-5, 1e-5, 9.99999e-6, 1e16, 9999999999999998.0, 1e15 + 0.5]
    return out


def test_encode_vectors_matches_json_dumps_on_every_decade() -> None:
    values = np.array(_magnitudes())
    for start in range(0, len(values), 7):
        chunk = values[start : start + 7]
        vectors = [chunk.copy(), chunk[::-1].tolist(), np.ascontiguousarray(chunk[:3])]
        assert codec.encode_vectors(vectors) == [_vector_oracle(v) for v in vectors]


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), max_size=7),
        min_size=1,
        max_size=6,
    ),
    st.lists(st.booleans(), min_size=6, max_size=6),
)
def test_encode_vectors_matches_json_dumps(vectors: list[list[float]], arrays: list[bool]) -> None:
    given_vectors: list[Any] = [
        np.array(v, dtype=np.float64) if as_array else v
        for v, as_array in zip(vectors, arrays, strict=False)
    ]
    assert codec.encode_vectors(given_vectors) == [_vector_oracle(v) for v in given_vectors]


def test_encode_vectors_refuses_what_it_cannot_write_like_encode() -> None:
    f64 = np.array([1.0, 2.0])
    assert codec.encode_vectors([]) == []
    assert codec.encode_vectors([f64, np.array([1, 2])]) is None  # ints: "1" not "1.0"
    assert codec.encode_vectors([np.array([1.0, 2.0], dtype=np.float32)]) is None
    assert codec.encode_vectors([np.arange(6.0)[::2]]) is None  # not contiguous
    assert codec.encode_vectors([np.zeros((2, 2))]) is None
    assert codec.encode_vectors([np.array([1.0], dtype=">f8")]) is None
    assert codec.encode_vectors([[1.0, 2]]) is None  # an int in a list
    assert codec.encode_vectors([[np.float64(1.0)]]) is None
    assert codec.encode_vectors([(1.0, 2.0)]) is None  # a tuple
    assert codec.encode_vectors([f64, []]) == [b"1.0,2.0", b""]
