"""Property tests: the loader and validator never raise on any input, only report problems."""

from __future__ import annotations

import atexit
import random
import shutil
import tempfile
from pathlib import Path

import yaml
from hypothesis import given
from hypothesis import strategies as st

from suture_engine.language.loader import load_text
from suture_engine.language.source import load_yaml_text
from suture_engine.validation.checks import check_procedure, validate_file
from suture_engine.validation.problem import Problem, ProblemError

ROOT = Path(__file__).resolve().parent.parent
PROCEDURES = ROOT / "procedures"
BUNDLED = sorted(PROCEDURES.glob("*.yaml"))
TEXTS = {p.name: p.read_text(encoding="utf-8") for p in BUNDLED}
# a private copy of the bundled tree, so that mutants' use: and scene paths resolve
_COPY = Path(tempfile.mkdtemp(prefix="suture-fuzz-"))
atexit.register(shutil.rmtree, _COPY, ignore_errors=True)
COPY = Path(shutil.copytree(PROCEDURES, _COPY / "procedures"))


def _only_problems(text: str) -> None:
    try:
        load_yaml_text(text, "fuzz.yaml")
    except ProblemError as exc:
        assert exc.problems and all(isinstance(p, Problem) for p in exc.problems)
    result = load_text(text, "fuzz.yaml", base=PROCEDURES)
    assert all(isinstance(p, Problem) and p.file for p in result.problems)
    if result.procedure is not None:
        for p in check_procedure(result.procedure):
            assert isinstance(p, Problem)


@given(st.text(max_size=400))
def test_arbitrary_text(text: str) -> None:
    _only_problems(text)


_scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(["20 mm", "3 N", "180 deg", "${mirror}", "${1/0}", "x", "done", "end", ""]),
    st.text(max_size=20),
)
_values = st.recursive(
    _scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4),
        st.dictionaries(
            st.sampled_from(["skill", "with", "on", "use", "outcome", "robot", "target", "x"]),
            inner,
            max_size=4,
        ),
    ),
    max_leaves=20,
)


@given(_values)
def test_arbitrary_yaml_documents(value: object) -> None:
    _only_problems(yaml.safe_dump(value))


@given(
    st.dictionaries(
        st.sampled_from(["procedure", "scene", "params", "roles", "initial", "states", "version"]),
        _values,
        max_size=7,
    )
)
def test_arbitrary_procedure_shaped_documents(doc: dict[str, object]) -> None:
    _only_problems(yaml.safe_dump(doc))


def _mutate(text: str, rng: random.Random) -> str:
    lines = text.splitlines()
    for _ in range(rng.randint(1, 3)):
        if not lines:
            break
        i = rng.randrange(len(lines))
        op = rng.randrange(6)
        if op == 0:
            del lines[i]
        elif op == 1:
            lines.insert(i, lines[rng.randrange(len(lines))])
        elif op == 2 and lines[i]:
            j = rng.randrange(len(lines[i]))
            lines[i] = lines[i][:j] + lines[i][j + 1 :]
        elif op == 3:
            lines[i] = lines[i].replace("mm", "deg").replace(" N", " mm")
        elif op == 4:
            lines[i] = "  " + lines[i]
        else:
            tokens = ["${", "}", "[", "]", "{", ":", "&a", "*a", "!!python/object", "-1", "done"]
            j = rng.randrange(len(lines[i]) + 1)
            lines[i] = lines[i][:j] + rng.choice(tokens) + lines[i][j:]
    return "\n".join(lines) + "\n"


@given(st.sampled_from(sorted(TEXTS)), st.integers(0, 2**32 - 1))
def test_mutated_bundled_procedures(name: str, seed: int) -> None:
    text = _mutate(TEXTS[name], random.Random(seed))
    path = COPY / "mutant.yaml"
    path.write_text(text, encoding="utf-8")
    for p in validate_file(path):
        assert isinstance(p, Problem) and p.file and p.line >= 0
