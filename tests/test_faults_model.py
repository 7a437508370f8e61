"""Faults as data: the ``faults:`` model, the ``--fault`` syntax, backend support, validation."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from suture_engine.faults.model import FAULT_KINDS, Fault
from suture_engine.faults.support import refusal, supported_kinds
from suture_engine.faults.syntax import (
    FaultSpecError,
    FaultSyntaxError,
    FaultValueError,
    format_fault,
    parse_fault,
)

ROOT = Path(__file__).resolve().parent.parent
TEST_SCENE = (ROOT / "tests" / "procedures" / "scene.yaml").read_text(encoding="utf-8")
STEPS = (ROOT / "tests" / "procedures" / "steps.yaml").read_text(encoding="utf-8")


# --------------------------------------------------------------------------- the syntax
@pytest.mark.parametrize(
    ("spec", "fields"),
    [
        ("ft.noise=0.05 N", {"kind": "noise", "sensor": "ft", "value": 0.05}),
        ("ft.bias=0.5 N@2 s", {"kind": "bias", "sensor": "ft", "value": 0.5, "at": 2.0}),
        ("ft.delay=2 ms", {"kind": "delay", "sensor": "ft", "value": 0.002}),
        (
            "endobot_1:enc.dropout@3 s for 20 ms",
            {"kind": "dropout", "sensor": "encoders", "robot": "endobot_1", "at": 3.0},
        ),
        ("ft.dropout@rate 2/s for 10 ms", {"rate": 2.0, "duration": 0.01}),
        ("endobot_2:grasp-slip@state tighten", {"kind": "grasp-slip", "when": "tighten"}),
        ("grasp-slip@state mirrored-knot.tighten", {"when": "mirrored-knot.tighten"}),
        ("snag=2 N@state bite+1 s for 300 ms", {"value": 2.0, "when": "bite", "at": 1.0}),
        ("endobot_1:pitch.joint-lock@1 s", {"kind": "joint-lock", "joint": "pitch", "at": 1.0}),
        ("q4.joint-weak=0.3", {"joint": "insertion", "value": 0.3}),
        ("blow-up@5 s;mode=energy", {"kind": "blow-up", "mode": "energy", "at": 5.0}),
        ("blow-up=energy@5 s", {"mode": "energy"}),
        ("enc.noise=1 mm", {"joint": "insertion", "value": 0.001}),
        ("enc.bias=1 deg;joint=yaw", {"joint": "yaw", "value": math.radians(1)}),
        ("ft.bias=1 N;axis=x", {"axis": "x"}),
        ("ft.dropout@p 0.5 in 3 s;seed=4", {"probability": 0.5, "within": 3.0, "seed": 4}),
    ],
)
def test_specs_read_as_written(spec: str, fields: dict[str, object]) -> None:
    fault = parse_fault(spec)
    for name, value in fields.items():
        got = getattr(fault, name)
        if isinstance(value, float):
            assert got == pytest.approx(value)
        else:
            assert got == value


@pytest.mark.parametrize(
    ("spec", "column", "needle", "error"),
    [
        ("ft.bais=1 N", 4, "did you mean 'bias'", FaultSyntaxError),
        ("xx.noise=1 N", 1, "a target", FaultSyntaxError),
        ("ft.noise@", 10, "a trigger", FaultSyntaxError),
        ("ft.noise=1 N;foo=2", 14, "KEY=VALUE", FaultSyntaxError),
        ("ft.dropout@rate x", 17, "a rate", FaultSyntaxError),
        ("ft.dropout@state", 17, "a state name", FaultSyntaxError),
        ("ft.bias=", 9, "a value after '='", FaultSyntaxError),
        ("ft.bias=1 s", 9, "expected length*mass/time^2 (N), found time", FaultValueError),
        ("ft.noise=-1 N", 10, "> 0", FaultValueError),
        ("ft.delay=5 s", 10, "delay <= 1 s", FaultValueError),
        ("grasp-slip=2 N", 12, "takes no value", FaultValueError),
        ("insertion.joint-weak=2", 22, "[0, 1)", FaultValueError),
        ("joint-lock@1 s", 1, "needs a joint", FaultValueError),
        ("ft.bias=1 N@-2 s", 13, "at", FaultValueError),
        ("enc.noise=1 N", 11, "an angle", FaultValueError),
        ("ft.noise=1 N;axis=w", 19, "axis", FaultValueError),
    ],
)
def test_bad_specs_name_their_column(
    spec: str, column: int, needle: str, error: type[FaultSpecError]
) -> None:
    with pytest.raises(error) as err:
        parse_fault(spec)
    assert err.value.position + 1 == column
    assert f"at column {column}" in err.value.message
    assert needle in err.value.message
    assert spec in err.value.message  # the spec with a caret under the column
    assert err.value.message.splitlines()[-1] == " " * (column + 1) + "^"


_faults = st.builds(
    lambda kind, sensor, robot, at, dur, trig, x, seed: _make(
        kind, sensor, robot, at, dur, trig, x, seed
    ),
    st.sampled_from(FAULT_KINDS),
    st.sampled_from(["ft", "encoders"]),
    st.sampled_from([None, "endobot_1", "left-arm"]),
    st.one_of(st.none(), st.floats(0.0, 100.0)),
    st.one_of(st.none(), st.floats(0.001, 10.0)),
    st.sampled_from(["at", "when", "rate", "probability"]),
    st.floats(0.01, 0.9),
    st.one_of(st.none(), st.integers(0, 2**31)),
)


def _make(
    kind: str,
    sensor: str,
    robot: str | None,
    at: float | None,
    dur: float | None,
    trig: str,
    x: float,
    seed: int | None,
) -> Fault:
    data: dict[str, object] = {"kind": kind, "robot": robot, "at": at, "duration": dur}
    if kind in ("noise", "bias", "delay", "dropout"):
        data["sensor"] = sensor
    if kind in ("noise", "bias", "delay", "snag", "joint-weak"):
        data["value"] = x
    if kind in ("joint-lock", "joint-weak"):
        data["joint"] = "roll"
    if trig == "when":
        data["when"] = "tighten"
    elif trig == "rate":
        data["rate"], data["seed"] = 1.0 + x, seed
    elif trig == "probability":
        data["probability"], data["within"], data["seed"] = x, 5.0, seed
    return Fault.model_validate(data)


@given(_faults)
def test_format_then_parse_gives_the_same_fault(fault: Fault) -> None:
    assert parse_fault(format_fault(fault)) == fault


# --------------------------------------------------------------------------- the model
def test_sensor_and_joint_rules() -> None:
    with pytest.raises(ValueError, match="needs a sensor"):
        Fault(kind="noise", value=1.0)
    with pytest.raises(ValueError, match="has no sensor"):
        Fault(kind="snag", sensor="ft", value=1.0)
    with pytest.raises(ValueError, match="has no joint"):
        Fault(kind="delay", sensor="ft", joint="yaw", value=0.002)
    with pytest.raises(ValueError, match="rate or a probability"):
        Fault(kind="blow-up", rate=1.0, probability=0.5)
    with pytest.raises(ValueError, match=r"Extra inputs"):
        Fault.model_validate({"kind": "blow-up", "magnitude": 3})
    assert Fault(kind="snag", value=2.0).default_duration == 0.2
    assert Fault(kind="dropout", sensor="ft", rate=2.0).default_duration == 0.01
    assert Fault(kind="joint-lock", joint="yaw").default_duration is None
    assert Fault(kind="joint-lock", joint="yaw").target == "yaw"
    assert Fault(kind="grasp-slip").target == "grasp"


# --------------------------------------------------------------------------- the scene
def _write(tmp_path: Path, faults_yaml: str) -> Path:
    (tmp_path / "scene.yaml").write_text(TEST_SCENE + faults_yaml, encoding="utf-8")
    proc = tmp_path / "steps.yaml"
    proc.write_text(STEPS, encoding="utf-8")
    return proc


def test_scene_faults_load_in_si(tmp_path: Path) -> None:
    from suture_engine.language.loader import load

    proc = _write(
        tmp_path,
        "faults:\n"
        "  - {kind: bias, sensor: ft, value: 500 mN, at: 200 ms}\n"
        "  - {kind: joint-lock, robot: endobot_1, joint: pitch, when: tighten}\n",
    )
    result = load(proc)
    assert not result.problems
    assert result.procedure is not None and result.procedure.scene is not None
    bias, lock = result.procedure.scene.faults
    assert (bias.value, bias.at) == (pytest.approx(0.5), pytest.approx(0.2))
    assert (lock.joint, lock.when) == ("pitch", "tighten")


@pytest.mark.parametrize(
    ("entry", "needle"),
    [
        ("  - {kind: bias, sensor: ft, value: 2 s}\n", "unit-mismatch"),
        ("  - {kind: slip}\n", "kind"),
        ("  - {kind: joint-lock, robot: endobot_9, joint: yaw}\n", "endobot_9"),
        ("  - {kind: noise, sensor: ft, value: 1 N, durtion: 1 s}\n", "unknown key 'durtion'"),
    ],
)
def test_bad_scene_faults_are_located(tmp_path: Path, entry: str, needle: str) -> None:
    from suture_engine.validation.checks import validate_file

    proc = _write(tmp_path, "faults:\n" + entry)
    problems = validate_file(proc)
    assert problems, "a bad fault must be refused"
    text = "\n".join(p.format() for p in problems)
    faults_line = (TEST_SCENE + "faults:\n").count("\n")
    assert any(p.file.endswith("scene.yaml") and p.line >= faults_line for p in problems), text
    assert needle in text


def test_faults_the_backend_cannot_simulate_are_refused_at_validation(tmp_path: Path) -> None:
    from suture_engine.validation.checks import validate_file

    proc = _write(
        tmp_path,
        "faults:\n  - {kind: noise, sensor: ft, value: 0.1 N}\n  - {kind: grasp-slip, at: 1 s}\n",
    )
    assert validate_file(proc) == []  # no backend named: nothing to refuse
    assert validate_file(proc, backend="pybullet-surgical") == []
    problems = validate_file(proc, backend="ideal")
    assert [p.code for p in problems] == ["fault-not-supported"]
    p = problems[0]
    slip_line = (TEST_SCENE + "faults:\n  - x\n  - ").count("\n") + 1
    assert (Path(p.file).name, p.line, p.path) == ("scene.yaml", slip_line, "faults[1].kind")
    assert "ideal" in p.message and "grasp-slip" in p.message


def test_backend_support_table() -> None:
    slip = Fault(kind="grasp-slip")
    energy = Fault(kind="blow-up", mode="energy")
    assert refusal(slip, "pybullet-surgical") is None
    assert refusal(slip, "pybullet-surgical-stitched") is None
    assert "pybullet" in (refusal(slip, "pybullet") or "")
    assert "replay" in (refusal(Fault(kind="noise", sensor="ft", value=1.0), "replay") or "")
    assert refusal(energy, "ideal") is None
    # a plugin backend: decided by the wrapper from the hooks it has (test_faults_backend)
    assert refusal(slip, "someone-elses") is None
    assert supported_kinds("replay") == frozenset()
