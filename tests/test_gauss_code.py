"""Gauss-code invariants against independent oracles.

Oracles used here (none of them shares code with the module under test):

- spherogram (from the package index) reads our PD code and computes its own
  crossing signs, writhe and Seifert matrix V; the Alexander polynomial is
  then ``det(V - t V^T)`` (sympy) and the determinant ``|det(V + V^T)|``;
- the Jones polynomial, computed below by the Kauffman bracket state sum on
  the PD code; ``v2 = -j2/3`` and ``v3 = -j3/6`` with ``V(e^h) = 1 + j2 h^2 +
  j3 h^3 + ...``, i.e. ``v2 = -sum c_k k^2 / 6`` and ``v3 = -sum c_k k^3 / 36``.
"""

from __future__ import annotations

from collections import defaultdict

import pytest
import sympy
from hypothesis import given, settings
from hypothesis import strategies as st

from suture_engine.suture.gauss_code import (
    GaussCode,
    InvalidGaussCode,
    alexander_polynomial,
    determinant,
    diagram_determinant,
    format_polynomial,
    simplify,
    vassiliev_v2,
    vassiliev_v3,
    writhe,
)

spherogram = pytest.importorskip("spherogram")

T = sympy.Symbol("t")


# ---------------------------------------------------------------- oracles


def jones_from_pd(pd: list[tuple[int, int, int, int]]) -> dict[int, int]:
    """Jones polynomial {power of t: coefficient} by the Kauffman bracket.

    <X[a,b,c,d]> = A <a-b, c-d smoothing> + A^-1 <a-d, b-c smoothing>,
    loop value d = -A^2 - A^-2, V(t) = (-A^3)^-w <D> at A = t^(-1/4).
    """
    if not pd:
        return {0: 1}
    edges = sorted({e for x in pd for e in x})
    n_edges = len(edges)
    w = sum(1 if (b - d) % n_edges == 1 else -1 for _, b, _, d in pd)
    bracket: dict[int, int] = defaultdict(int)
    m = len(pd)
    for state in range(1 << m):
        parent = {e: e for e in edges}

        def find(x: int, parent: dict[int, int] = parent) -> int:
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        n_a = 0
        for k, (a, b, c, d) in enumerate(pd):
            pairs = ((a, b), (c, d)) if state >> k & 1 else ((a, d), (b, c))
            n_a += state >> k & 1
            for x, y in pairs:
                rx, ry = find(x), find(y)
                if rx != ry:
                    parent[rx] = ry
        loops = len({find(e) for e in edges})
        poly: dict[int, int] = {n_a - (m - n_a): 1}
        for _ in range(loops - 1):
            nxt: dict[int, int] = defaultdict(int)
            for e, cf in poly.items():
                nxt[e + 2] -= cf
                nxt[e - 2] -= cf
            poly = nxt
        for e, cf in poly.items():
            bracket[e] += cf
    sign = 1 if w % 2 == 0 else -1
    jones: dict[int, int] = defaultdict(int)
    for e, cf in bracket.items():
        if cf:
            power = e - 3 * w
            assert power % 4 == 0
            jones[-power // 4] += sign * cf
    return {k: v for k, v in jones.items() if v}


def vassiliev_from_jones(jones: dict[int, int]) -> tuple[int, int]:
    s2 = sum(c * k * k for k, c in jones.items())
    s3 = sum(c * k**3 for k, c in jones.items())
    assert s2 % 6 == 0 and s3 % 36 == 0
    return -s2 // 6, -s3 // 36


def seifert_alexander_coefficients(v: sympy.Matrix) -> list[int]:
    """Coefficients of det(V - t V^T), lowest degree first.

    The determinant has degree <= n (V is n x n); it is evaluated exactly at
    t = 0..n (integer matrices) and interpolated, which is much faster than
    a symbolic determinant.
    """
    n = v.shape[0]
    points = [(k, int((v - k * v.T).det(method="bareiss"))) for k in range(n + 1)]
    poly = sympy.Poly(sympy.interpolate(points, T), T)
    return [int(c) for c in reversed(poly.all_coeffs())]


def seifert_oracle(pd: list[tuple[int, int, int, int]]) -> tuple[tuple[int, ...], int, int]:
    """(normalised Alexander polynomial, determinant, writhe) computed by spherogram."""
    if not pd:
        return (1,), 1, 0  # a diagram without crossings is the unknot
    link = spherogram.Link(pd)
    v = sympy.Matrix(link.seifert_matrix())
    if v.shape[0] == 0:
        return (1,), 1, link.writhe()
    coeffs = seifert_alexander_coefficients(v)
    while coeffs and coeffs[0] == 0:
        coeffs.pop(0)
    if sum(coeffs) < 0:
        coeffs = [-c for c in coeffs]
    det = abs(int((v + v.T).det()))
    return tuple(coeffs), det, link.writhe()


# ----------------------------------------------------------- standard knots

STANDARD = {
    # name: (braid word, strands, Alexander, det, v2, v3)
    "right trefoil": ((1, 1, 1), 2, (1, -1, 1), 3, 1, 1),
    "left trefoil": ((-1, -1, -1), 2, (1, -1, 1), 3, 1, -1),
    "figure-eight": ((1, -2, 1, -2), 3, (-1, 3, -1), 5, -1, 0),
    "cinquefoil": ((1, 1, 1, 1, 1), 2, (1, -1, 1, -1, 1), 5, 3, 5),
    "square": ((1, 1, 1, -2, -2, -2), 3, (1, -2, 3, -2, 1), 9, 2, 0),
    "right granny": ((1, 1, 1, 2, 2, 2), 3, (1, -2, 3, -2, 1), 9, 2, 2),
    "left granny": ((-1, -1, -1, -2, -2, -2), 3, (1, -2, 3, -2, 1), 9, 2, -2),
}


@pytest.mark.parametrize("name", sorted(STANDARD))
def test_standard_knots_have_their_known_invariants(name: str) -> None:
    word, strands, alex, det, v2, v3 = STANDARD[name]
    code = GaussCode.from_braid(word, strands)
    assert alexander_polynomial(code) == alex
    assert determinant(alexander_polynomial(code)) == det
    assert diagram_determinant(code) == det
    assert vassiliev_v2(code) == v2
    assert vassiliev_v3(code) == v3


@pytest.mark.parametrize("name", sorted(STANDARD))
def test_standard_knots_agree_with_spherogram_and_jones(name: str) -> None:
    word, strands, *_ = STANDARD[name]
    code = GaussCode.from_braid(word, strands)
    pd = code.to_pd()
    link = spherogram.Link(pd)
    assert [c.sign for c in link.crossings] == [code.signs[lab] for lab in code.labels()]
    alex, det, link_writhe = seifert_oracle(pd)
    assert alexander_polynomial(code) == alex
    assert diagram_determinant(code) == det
    assert writhe(code) == link_writhe
    assert (vassiliev_v2(code), vassiliev_v3(code)) == vassiliev_from_jones(jones_from_pd(pd))


def test_positive_trefoil_jones_matches_the_skein_relation() -> None:
    # Jones' skein relation t^-1 V(L+) - t V(L-) = (t^1/2 - t^-1/2) V(L0)
    # gives V = t + t^3 - t^4 for the trefoil with three positive crossings;
    # this pins the chirality convention of the oracle.
    code = GaussCode.from_braid((1, 1, 1), 2)
    assert jones_from_pd(code.to_pd()) == {1: 1, 3: 1, 4: -1}


def test_spherogram_table_pd_codes() -> None:
    """spherogram's own PD codes of 3_1 and 4_1, read back as Gauss codes."""
    for name, alex in (("3_1", (1, -1, 1)), ("4_1", (-1, 3, -1)), ("5_2", (2, -3, 2))):
        link = spherogram.Link(name)
        pd = link.PD_code()
        n = 2 * len(pd)
        passages: list[tuple[int, bool]] = [(-1, False)] * n
        signs = {}
        for k, (crossing, (a, b, _c, d)) in enumerate(zip(link.crossings, pd, strict=True)):
            passages[(a + 1) % n] = (k, False)
            over_out = d if (d - b) % n == 1 else b
            passages[over_out] = (k, True)
            signs[k] = crossing.sign
        code = GaussCode(tuple(passages), signs)
        assert alexander_polynomial(code) == alex
        assert seifert_oracle(pd)[0] == alex


# ------------------------------------------------------- random diagrams

braid_words = st.integers(min_value=2, max_value=4).flatmap(
    lambda k: st.tuples(
        st.just(k),
        st.lists(
            st.integers(min_value=1, max_value=k - 1).flatmap(lambda g: st.sampled_from((g, -g))),
            min_size=2,
            max_size=10,
        ),
    )
)


def _closure(data: tuple[int, list[int]]) -> GaussCode | None:
    k, word = data
    try:
        return GaussCode.from_braid(word, k)
    except InvalidGaussCode:
        return None


@settings(max_examples=60, deadline=None)
@given(braid_words, st.integers(min_value=0, max_value=40))
def test_random_knots_match_the_oracles(data: tuple[int, list[int]], shift: int) -> None:
    code = _closure(data)
    if code is None:
        return
    code = code.rotated(shift)
    pd = code.to_pd()
    alex, det, _ = seifert_oracle(pd)
    assert alexander_polynomial(code) == alex
    assert diagram_determinant(code) == det
    assert (vassiliev_v2(code), vassiliev_v3(code)) == vassiliev_from_jones(jones_from_pd(pd))


@settings(max_examples=60, deadline=None)
@given(braid_words, st.integers(min_value=0, max_value=40))
def test_reduction_and_base_point_and_mirror(data: tuple[int, list[int]], shift: int) -> None:
    code = _closure(data)
    if code is None:
        return
    reduced = simplify(code)
    assert reduced.crossings <= code.crossings
    for other in (reduced, code.rotated(shift)):
        assert alexander_polynomial(other) == alexander_polynomial(code)
        assert vassiliev_v2(other) == vassiliev_v2(code)
        assert vassiliev_v3(other) == vassiliev_v3(code)
    mirror = code.mirrored()
    assert vassiliev_v2(mirror) == vassiliev_v2(code)
    assert vassiliev_v3(mirror) == -vassiliev_v3(code)
    assert writhe(mirror) == -writhe(code)


def test_reidemeister_moves_are_removed() -> None:
    # trefoil with an extra kink (RI) and a poke (RII) spliced in
    kinked = GaussCode.from_braid((1, 1, 1, 2), 3)  # sigma_2 is a removable kink
    assert kinked.crossings == 4
    assert simplify(kinked).crossings == 3
    poked = GaussCode.from_braid((1, 2, -2, 1, 1, 2), 3)  # sigma_2 sigma_2^-1 is a bigon
    assert simplify(poked).crossings == 3


def test_bad_codes_are_typed_errors() -> None:
    with pytest.raises(InvalidGaussCode):
        GaussCode(((1, True), (1, True)), {1: 1})
    with pytest.raises(InvalidGaussCode):
        GaussCode(((1, True), (1, False)), {1: 0})
    with pytest.raises(InvalidGaussCode):
        GaussCode.from_braid((1, 1), 2)  # a link
    with pytest.raises(InvalidGaussCode):
        GaussCode.from_braid((3,), 2)


def test_format_polynomial() -> None:
    assert format_polynomial((1, -1, 1)) == "t^2 - t + 1"
    assert format_polynomial((-1, 3, -1)) == "-t^2 + 3t - 1"
    assert format_polynomial((1,)) == "1"


def _random_polygon_codes(count: int, seed: int) -> list[GaussCode]:
    """Diagrams of random closed polygons (not braid closures), at most 12 crossings."""
    import numpy as np

    from suture_engine.suture.topology import project_gauss_code

    rng = np.random.default_rng(seed)
    codes: list[GaussCode] = []
    while len(codes) < count:
        poly = rng.normal(size=(int(rng.integers(8, 16)), 3))
        try:
            code, _ = project_gauss_code(poly, rng.normal(size=3))
        except ValueError:
            continue
        code = simplify(code)
        if 0 < code.crossings <= 12:
            codes.append(code.rotated(int(rng.integers(0, 1 + len(code.passages)))))
    return codes


def _check_against_oracles(code: GaussCode) -> None:
    pd = code.to_pd()
    assert (vassiliev_v2(code), vassiliev_v3(code)) == vassiliev_from_jones(jones_from_pd(pd))
    alex, det, _ = seifert_oracle(pd)
    assert alexander_polynomial(code) == alex
    assert diagram_determinant(code) == det


def test_random_polygon_diagrams_match_the_oracles() -> None:
    for code in _random_polygon_codes(25, seed=11):
        _check_against_oracles(code)


@pytest.mark.slow
def test_many_random_polygon_diagrams_match_the_oracles() -> None:
    for code in _random_polygon_codes(400, seed=12):
        _check_against_oracles(code)
