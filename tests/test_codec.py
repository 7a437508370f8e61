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
