"""The pinned BLAS kernel: when it is pinned, and what it computes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from suture_engine.arithmetic import CANONICAL_CORE, cpu_flags, pin_blas_kernel

AVX2 = frozenset({"fpu", "sse2", "avx", "avx2", "fma"})


def test_pins_on_an_x86_cpu_with_avx2_and_fma() -> None:
    env: dict[str, str] = {}
    assert pin_blas_kernel(env, flags=AVX2, machine="x86_64", numpy_loaded=False) == "pinned"
    assert env == {"OPENBLAS_CORETYPE": CANONICAL_CORE}


def test_an_avx512_cpu_is_pinned_to_the_same_kernel() -> None:
    env: dict[str, str] = {}
    flags = AVX2 | {"avx512f", "avx512dq", "avx512vl"}
    assert pin_blas_kernel(env, flags=flags, machine="x86_64", numpy_loaded=False) == "pinned"
    assert env["OPENBLAS_CORETYPE"] == CANONICAL_CORE


@pytest.mark.parametrize(
    ("env", "flags", "machine", "loaded", "outcome"),
    [
        ({"OPENBLAS_CORETYPE": "Zen"}, AVX2, "x86_64", False, "user"),
        ({}, AVX2, "x86_64", True, "numpy-first"),
        ({}, AVX2, "aarch64", False, "not-x86"),
        ({}, frozenset({"sse2", "avx"}), "x86_64", False, "cpu"),
        ({}, frozenset({"avx2"}), "x86_64", False, "cpu"),
    ],
)
def test_left_alone(
    env: dict[str, str], flags: frozenset[str], machine: str, loaded: bool, outcome: str
) -> None:
    before = dict(env)
    assert pin_blas_kernel(env, flags=flags, machine=machine, numpy_loaded=loaded) == outcome
    assert env == before


def test_cpu_flags_are_read_from_the_first_processor(tmp_path: Path) -> None:
    info = tmp_path / "cpuinfo"
    info.write_text(
        "processor\t: 0\nvendor_id\t: AuthenticAMD\nflags\t\t: fpu sse2 avx2 fma\n\n"
        "processor\t: 1\nflags\t\t: fpu\n"
    )
    assert cpu_flags(info) == frozenset({"fpu", "sse2", "avx2", "fma"})
    assert cpu_flags(tmp_path / "missing") == frozenset()


def _fresh(code: str) -> dict[str, object]:
    env = {k: v for k, v in __import__("os").environ.items() if k != "OPENBLAS_CORETYPE"}
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    return json.loads(res.stdout)


def test_import_pins_before_numpy_loads_and_norms_round_in_order() -> None:
    # Oracle: Python's own float arithmetic, each product and sum rounded in turn. The
    # Haswell kernel's dot product rounds so; the SkylakeX kernel fuses the multiply-adds
    # (on this test's vectors its norms differ in the last bit about one time in ten).
    if not {"avx2", "fma"} <= cpu_flags():
        pytest.skip("this CPU cannot run the canonical kernel")
    out = _fresh(
        "import json, math, os\n"
        "import suture_engine\n"
        "import numpy as np\n"
        "from suture_engine.arithmetic import arithmetic_record\n"
        "rng = np.random.default_rng(0)\n"
        "v = rng.standard_normal((20000, 3)) * 10.0 ** rng.integers(-4, 4, (20000, 1))\n"
        "same = sum(float(np.linalg.norm(np.array(x))) == math.sqrt(x[0]*x[0] + x[1]*x[1]"
        " + x[2]*x[2]) for x in v.tolist())\n"
        "print(json.dumps({'core': os.environ.get('OPENBLAS_CORETYPE'), 'same': same,"
        " 'record': arithmetic_record()}))\n"
    )
    assert out["core"] == CANONICAL_CORE
    assert out["record"] == {"blas_kernel": CANONICAL_CORE, "pin": "pinned"}
    assert out["same"] == 20000


def test_numpy_loaded_first_is_recorded_as_unpinned() -> None:
    out = _fresh(
        "import json, numpy, suture_engine\n"
        "from suture_engine.arithmetic import arithmetic_record\n"
        "print(json.dumps(arithmetic_record()))\n"
    )
    assert out == {"blas_kernel": "auto", "pin": "numpy-first"}


def test_row_dot_sums_its_products_in_a_fixed_order() -> None:
    # Oracle: Python's own float arithmetic on the same numbers, (x0 + x2) + x1.
    import numpy as np

    from suture_engine.arithmetic import row_dot

    rng = np.random.default_rng(5)
    a = rng.standard_normal((500, 3)) * 10.0 ** rng.integers(-6, 3, (500, 1))
    b = rng.standard_normal((500, 3))
    pairs = zip(a.tolist(), b.tolist(), strict=True)
    want = [(x[0] * y[0] + x[2] * y[2]) + x[1] * y[1] for x, y in pairs]
    assert row_dot(a, b).tolist() == want
    # broadcast, as the tissue's channel search uses it: (k, i, 3) against (i, 3)
    pts, u = rng.standard_normal((4, 1, 3)), rng.standard_normal((6, 3))
    got = row_dot(pts - u[None], u)
    assert got.shape == (4, 6)
    d = (pts - u[None]).tolist()
    assert got[2, 5] == (d[2][5][0] * u[5, 0] + d[2][5][2] * u[5, 2]) + d[2][5][1] * u[5, 1]


def test_row_dot_is_numpys_einsum_on_an_avx2_cpu() -> None:
    # The traces of the thread were made with np.einsum on AVX2; row_dot keeps their bits.
    import numpy as np

    from suture_engine.arithmetic import row_dot

    if "avx512f" in cpu_flags() or not {"avx2"} <= cpu_flags():
        pytest.skip("numpy's einsum loop is the AVX2 one only on an AVX2 CPU without AVX-512")
    rng = np.random.default_rng(6)
    for n in (1, 2, 3, 7, 8, 40, 41, 99):
        a, b = rng.standard_normal((n, 3)), rng.standard_normal((n, 3))
        assert row_dot(a, b).tolist() == np.einsum("ij,ij->i", a, b).tolist()
        x, s = rng.standard_normal((n, 3)), rng.standard_normal((5, 3))
        want = np.einsum("kij,ij->ki", x[:, None, :] - s[None], s)
        assert row_dot(x[:, None, :] - s[None], s).tolist() == want.tolist()


def test_elementwise_functions_are_the_c_librarys() -> None:
    import math

    import numpy as np

    from suture_engine.arithmetic import arcsin, cos, sin

    x = np.linspace(-7.0, 7.0, 303).reshape(3, 101)
    assert sin(x).shape == (3, 101)
    assert sin(x).ravel().tolist() == [math.sin(v) for v in x.ravel().tolist()]
    assert cos(x).ravel().tolist() == [math.cos(v) for v in x.ravel().tolist()]
    y = np.linspace(-1.0, 1.0, 201)
    assert arcsin(y).tolist() == [math.asin(v) for v in y.tolist()]
    assert float(sin(np.float64(0.5))) == math.sin(0.5)
    # and the same floats as numpy's own loops gave the traces made on AVX2 CPUs
    if {"avx2"} <= cpu_flags() and "avx512f" not in cpu_flags():
        z = np.random.default_rng(7).uniform(-20.0, 20.0, 50_000)
        assert sin(z).tolist() == np.sin(z).tolist()
        assert cos(z).tolist() == np.cos(z).tolist()
        assert arcsin(z / 20.0).tolist() == np.arcsin(z / 20.0).tolist()


# numpy functions whose float64 loops differ by CPU (SVML or other SIMD code on AVX-512)
_CPU_DEPENDENT = {
    "sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "exp", "exp2", "log",
    "log2", "log10", "log1p", "expm1", "tanh", "sinh", "cosh", "power", "einsum", "hypot",
    "cbrt",
}  # fmt: skip

# Where they may stay, and why: nothing here feeds a traced run's physics or commands,
# except the hybrid force controller's tanh (numpy's own loop already differs from the C
# library's on this machine; replacing it would change secure-knot.yaml's runs).
_ALLOWED = {
    "suture_engine/control/hybrid_force.py": {"tanh"},
    "suture_engine/control/shared_experiment.py": {"sin", "cos"},  # benchmark signals
    "suture_engine/control/tracking.py": {"sin", "cos"},  # benchmark reference circle
    "suture_engine/robot/excitation.py": {"sin", "cos", "log"},  # offline identification
    "suture_engine/robot/identification.py": {"sin", "cos"},  # offline identification
    "suture_engine/suture/curves.py": {"sin", "cos", "arctan2"},  # hand-built test knots
    "suture_engine/suture/topology.py": {"sin", "arccos"},  # the classifier (evaluation)
    "suture_engine/suture/knot.py": {"einsum"},  # segment distances (evaluation, reports)
    "suture_engine/trace/synthetic.py": {"sin", "cos"},  # synthetic test traces
}


def test_traced_code_calls_no_cpu_dependent_numpy_function() -> None:
    import ast

    root = Path(__file__).resolve().parent.parent
    found: dict[str, set[str]] = {}
    for top in ("backends", "skills", "suture_engine"):
        for path in sorted((root / top).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            names = {
                node.attr
                for node in ast.walk(tree)
                if isinstance(node, ast.Attribute)
                and isinstance(node.value, ast.Name)
                and node.value.id in ("np", "numpy")
                and node.attr in _CPU_DEPENDENT
            }
            if names:
                found[path.relative_to(root).as_posix()] = names
    extra = {f: n - _ALLOWED.get(f, set()) for f, n in found.items()}
    assert {f: n for f, n in extra.items() if n} == {}, (
        "use suture_engine.arithmetic (row_dot, sin, cos, arcsin) or math in traced code"
    )
