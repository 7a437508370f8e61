"""benchmarks/branch_sensitivity.py: a branch that changes nothing ends as a straight run
does; a changed step moves as changed; variants that cannot apply are refused by name.

Oracles: a straight ``run_procedure`` of the same seed (another code path: trace recorder,
no fork) for the unchanged branch, to the bit; the changed target's own length for the
changed branch, measured on the simulator's true tool tips.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from benchmark_modules import load_benchmark

ROOT = Path(__file__).resolve().parent.parent


bs = load_benchmark("branch_sensitivity")

PROCEDURE = """\
procedure: two-moves
version: "1"
description: The stitcher moves twice, holding after each move.
scene: scene.yaml
roles: {stitcher: endobot_1, grasper: endobot_2}
initial: move-1
states:
  move-1:
    skill: move-to
    with: {robot: stitcher, relative_to: stitcher, target: [10 mm, 0 mm, 0 mm], speed: 10 mm/s,
           tolerance: 0.5 mm}
    timeout: 10 s
    "on": {done: hold-1, failed: {retry: 0, then: abort}}
  hold-1:
    skill: hold
    with: {robot: stitcher, duration: 0.3 s}
    "on": {done: move-2, failed: {retry: 0, then: abort}}
  move-2:
    skill: move-to
    with: {robot: stitcher, relative_to: stitcher, target: [0 mm, 10 mm, 0 mm], speed: 10 mm/s,
           tolerance: 0.5 mm}
    timeout: 10 s
    "on": {done: hold-2, failed: {retry: 0, then: abort}}
  hold-2:
    skill: hold
    with: {robot: stitcher, duration: 0.3 s}
    "on": {done: finished, failed: {retry: 0, then: abort}}
  finished: {outcome: succeeded}
"""


@pytest.fixture(scope="module")
def procedure(tmp_path_factory: pytest.TempPathFactory) -> Path:
    work = tmp_path_factory.mktemp("branch")
    shutil.copy(ROOT / "procedures" / "scenes" / "bench.yaml", work / "scene.yaml")
    path = work / "procedure.yaml"
    path.write_text(PROCEDURE)
    return path


@pytest.fixture(scope="module")
def branches(procedure: Path) -> list[dict]:  # type: ignore[type-arg]
    variants = [
        bs.parse_variant("up: move-2.target+=[0 mm, 0 mm, 5 mm]"),
        bs.parse_variant("late: move-1.speed=5 mm/s"),  # move-1 ran before the branch point
    ]
    return bs.run_branches(
        procedure, at="hold-1", variants=variants, seed=3, backend="pybullet", max_time_s=20.0
    )


def test_the_unchanged_branch_ends_as_a_straight_run_does(
    procedure: Path,
    branches: list[dict],
    tmp_path: Path,  # type: ignore[type-arg]
) -> None:
    from suture_engine.runtime.run import run_procedure

    straight = run_procedure(procedure, backend="pybullet", seed=3, out=tmp_path, max_time_s=20.0)
    unchanged = branches[0]
    assert unchanged["variant"] == bs.AS_WRITTEN
    assert unchanged["outcome"] == straight.summary.outcome == "succeeded"
    assert unchanged["final_state"] == straight.summary.final_state
    assert unchanged["ticks"] == straight.summary.ticks
    # the largest tension estimate of the whole run, to the bit: the same sensor noise,
    # the same motion, before and after the fork
    assert unchanged["max_tension_N"] == straight.summary.max_tension_N
    assert [s["step"] for s in unchanged["steps"]] == ["hold-1", "move-2", "hold-2"]
    assert unchanged["branch_s"] > 0.5  # after move-1's ~1 s of motion


def test_a_changed_step_moves_as_changed(branches: list[dict]) -> None:  # type: ignore[type-arg]
    unchanged, up = branches[0], branches[1]
    assert up["variant"] == "up" and up["outcome"] == "succeeded"
    assert up["changes"] == [
        {"step": "move-2", "field": "target", "value": [0.0, 0.0, 0.005], "add": True}
    ]
    # true tool-tip travel against the commanded offsets (0.5 mm arrival tolerance)
    assert move_2_travel(unchanged) == pytest.approx(10.0, abs=0.6)
    assert move_2_travel(up) == pytest.approx(math.hypot(10.0, 5.0), abs=0.6)
    # the first move is shared: it ran once, before the branch
    assert up["branch_s"] == unchanged["branch_s"]


def test_a_step_that_already_ran_is_refused(branches: list[dict]) -> None:  # type: ignore[type-arg]
    late = branches[2]
    assert late["variant"] == "late"
    assert "move-1" in late["error"] and "ran before the branch point" in late["error"]


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("no-colon move-2.speed=1 mm/s", "expected 'NAME: STEP.FIELD=VALUE"),
        ("x: move-2speed", "expected STEP.FIELD=VALUE"),
        ("x:", "no change given"),
        ("as-written: move-2.speed=1 mm/s", "changes nothing"),
        ("x: move-2.speed=fast mm", "expected a quantity"),
    ],
)
def test_malformed_variants_are_refused(spec: str, message: str) -> None:
    with pytest.raises(bs.VariantError, match=message):
        bs.parse_variant(spec)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("x: move-3.speed=1 mm/s", "no step 'move-3'"),
        ("x: move-2.sped=1 mm/s", "no field 'sped'"),
        ("x: move-2.speed=-1 mm/s", "move-2: .*speed"),
        ("x: move-2.speed+=[1 mm, 2 mm]", "cannot add"),
        # the branch step itself has started at the branch point
        ("x: hold-1.duration=1 s", "'hold-1' ran before the branch point"),
    ],
)
def test_variants_that_cannot_apply_are_refused_before_the_run(
    procedure: Path, spec: str, message: str
) -> None:
    with pytest.raises(bs.VariantError, match=message):
        bs.run_branches(
            procedure, at="hold-1", variants=[bs.parse_variant(spec)], backend="pybullet"
        )


def test_a_branch_point_never_reached_is_an_error(procedure: Path) -> None:
    with pytest.raises(bs.VariantError, match="no step 'nowhere'"):
        bs.run_branches(procedure, at="nowhere", variants=[], backend="pybullet")
    with pytest.raises(RuntimeError, match="before step 'move-2'"):
        bs.run_branches(procedure, at="move-2", variants=[], backend="pybullet", max_time_s=0.2)


def test_the_table_and_the_command_line(
    procedure: Path,
    branches: list[dict],  # type: ignore[type-arg]
    capsys: pytest.CaptureFixture[str],
) -> None:
    table = bs.format_results(branches).splitlines()
    assert table[0].startswith("as-written: succeeded (finished)")
    assert any(line.startswith("up: succeeded") for line in table)
    assert any(line.startswith("late: --variant 'late'") for line in table)
    assert sum("move-2" in line and "travel endobot_1" in line for line in table) == 2
    assert bs.main([str(procedure), "--at", "hold-1", "--variant", "x: y"]) == 2
    assert "error: --variant 'x: y'" in capsys.readouterr().err


def test_the_per_step_knot_is_the_threads_topology() -> None:
    from suture_engine.suture.curves import trefoil

    line = trefoil(120)
    assert bs._knot({"centerline": line}) == "trefoil"
    assert bs._knot({"centerline": line[:, [0, 1]] * [1.0, 0.0]}) is None  # degenerate
    assert bs._knot({}) is None  # the robots alone: no thread


def test_a_branchs_knot_centre_is_reported_in_millimetres() -> None:
    knot = {"type": "trefoil", "centre": [0.0024, -0.02294, 0.0027]}
    assert bs._centre_mm(knot) == [2.4, -22.9, 2.7]
    assert bs._centre_mm({"type": "unknot", "centre": None}) is None
    assert bs._centre_mm(None) is None  # the robots alone: no knot entry
    row = {"variant": "v", "outcome": "succeeded", "final_state": "tied", "sim_time_s": 80.0,
           "knot": "trefoil", "knot_centre_mm": [2.4, -22.9, 2.7], "peak_true_tension_N": 1.0,
           "branch_s": 50.0, "steps": []}  # fmt: skip
    assert "knot trefoil at (2.4, -22.9, 2.7) mm, true peak" in bs.format_results([row])
    assert "knot unknot, true peak" in bs.format_results(
        [{**row, "knot": "unknot", "knot_centre_mm": None}]
    )


def test_a_branchs_knot_lay_is_reported() -> None:
    """A square's lay (the summary's ``lay``: square, or two half hitches when its post
    strand is not straight) is printed with its type; no lay, nothing printed."""
    row = {"variant": "v", "outcome": "succeeded", "final_state": "tied", "sim_time_s": 80.0,
           "knot": "square", "knot_lay": "half-hitches", "knot_centre_mm": [1.2, 7.8, 3.1],
           "peak_true_tension_N": 1.0, "branch_s": 50.0, "steps": []}  # fmt: skip
    assert "knot square lying as half-hitches at (1.2, 7.8, 3.1) mm" in bs.format_results([row])
    assert "knot square at (1.2" in bs.format_results([{**row, "knot_lay": None}])


def test_a_branch_from_a_sweeps_run_starts_as_that_run(procedure: Path, tmp_path: Path) -> None:
    from suture_engine.runtime.run import run_procedure

    ks = load_benchmark("knot_success")
    seed, options = bs.sweep_run("2:5", "pybullet")
    # the run as the sweep lists it (20 runs: the draw does not depend on the sweep's size)
    job = ks.make_jobs(
        [2], 20, base_seed=0, backend="pybullet", out=tmp_path, max_time_s=20.0, perturb=True,
        accepted=ks.accepted_options("pybullet"),
    )[5]  # fmt: skip
    assert (seed, options) == (job.seed, job.options)
    assert set(options) >= {"base_error", "friction_scale"}  # the robots alone take these
    (unchanged,) = bs.run_branches(
        procedure, at="hold-1", variants=[], seed=seed, backend="pybullet", max_time_s=20.0,
        backend_options=options,
    )  # fmt: skip
    straight = run_procedure(
        procedure, backend="pybullet", seed=seed, out=tmp_path / "straight", max_time_s=20.0,
        backend_options=options,
    )  # fmt: skip
    assert unchanged["ticks"] == straight.summary.ticks
    assert unchanged["max_tension_N"] == straight.summary.max_tension_N  # to the bit


def move_2_travel(result: dict) -> float:  # type: ignore[type-arg]
    (step,) = [s for s in result["steps"] if s["step"] == "move-2"]
    return float(step["travel_mm"]["endobot_1"])


def test_backend_options_reach_the_branches_backend(
    procedure: Path,
    branches: list[dict],  # type: ignore[type-arg]
) -> None:
    (stiff,) = bs.run_branches(
        procedure, at="hold-1", variants=[], seed=3, backend="pybullet", max_time_s=20.0,
        backend_options={"friction_scale": 1.3},
    )  # fmt: skip
    # 30 % more joint friction: the same 10 mm move ends a little shorter (true tool tips)
    assert move_2_travel(branches[0]) == pytest.approx(10.0, abs=0.005)
    assert move_2_travel(stiff) < 9.99


@pytest.mark.parametrize("spec", ["3", "3:", "a:1", "3:-1", "3:1:2"])
def test_a_malformed_sweep_run_is_refused(
    spec: str, procedure: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(bs.SweepRunError, match="expected ALG:RUN"):
        bs.sweep_run(spec, "pybullet")
    argv = [str(procedure), "--at", "hold-1", "--backend", "pybullet", "--sweep-run", spec]
    assert bs.main(argv) == 2
    assert f"error: --sweep-run {spec!r}: expected ALG:RUN" in capsys.readouterr().err
    assert bs.main([*argv[:3], "--sweep-run", "3:1"]) == 2  # no --backend
    assert "error: --sweep-run '3:1': needs --backend" in capsys.readouterr().err


def test_a_branch_from_an_ablation_run_keeps_only_its_perturbations(tmp_path: Path) -> None:
    """``--sweep-only friction``: the run of the sweep with ``--only friction``, whose base
    stays nominal and whose friction factor is the full sweep's draw."""
    ks = load_benchmark("knot_success")
    full_seed, full = bs.sweep_run("3:1", "pybullet-surgical-stitched")
    seed, friction = bs.sweep_run("3:1", "pybullet-surgical-stitched", only=" friction")
    job = ks.make_jobs(
        [3], 20, base_seed=0, backend="pybullet-surgical-stitched", out=tmp_path,
        max_time_s=1.0, perturb=True, accepted=ks.accepted_options("pybullet-surgical-stitched"),
        only=["friction"],
    )[1]  # fmt: skip
    assert (seed, friction) == (job.seed, job.options) and seed == full_seed
    assert friction["friction_scale"] == full["friction_scale"] != 1.0
    assert any(any(v) for v in full["base_error"].values())
    assert not any(any(v) for v in friction.get("base_error", {}).values())
    for bad in ("gravity", "friction,gravity", ","):
        with pytest.raises(bs.SweepRunError, match="--sweep-only: comma-separated from"):
            bs.sweep_run("3:1", "pybullet-surgical-stitched", only=bad)


def test_a_branch_from_a_calibration_sweep_run_moves_the_belief_not_the_robot(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``--sweep-base-error-as calibration``: the backend builds the robots where declared,
    and the interpreter plans from bases off by minus that run's draw."""
    backend = "pybullet-surgical-stitched"
    seed, placed = bs.sweep_run("3:4", backend)
    assert bs.sweep_calibration("3:4", backend) is None
    cal_seed, options = bs.sweep_run("3:4", backend, base_error_as="calibration")
    calibration = bs.sweep_calibration("3:4", backend, base_error_as="calibration")
    assert cal_seed == seed and "base_error" not in options
    assert options["friction_scale"] == placed["friction_scale"]
    assert calibration is not None
    for robot, error in placed["base_error"].items():
        np.testing.assert_array_equal(calibration[robot], -np.asarray(error))
    with pytest.raises(bs.SweepRunError, match="--sweep-base-error-as"):
        bs.sweep_run("3:4", backend, base_error_as="belief")
    argv = ["procedures/square-knot.yaml", "--at", "mirrored-knot.clear-jaws", "--sweep-run",
            "3:4", "--backend", backend, "--sweep-base-error-as", "belief"]  # fmt: skip
    assert bs.main(argv) == 2  # refused before any run
    assert "--sweep-base-error-as: one of placement, calibration" in capsys.readouterr().err


def test_each_steps_true_peak_is_its_own() -> None:
    """The recorder keeps the largest true tension per step after the branch point, reset
    at every transition: a high first step does not show in the calm second one."""

    class Backend:
        def ground_truth(self) -> dict[str, object]:
            return {"endobot_1/tool_tip": np.zeros(3)}

    class Record:
        def __init__(self, dest: str) -> None:
            self.dest = dest

    rec = bs.BranchRecorder(Backend())
    rec.tick(0, None, None, None, None, {"tension_N": 9.0})  # before the branch point
    rec.start("autonomous/pull", 1.0)
    for k, value in enumerate((0.5, 3.25, 1.0)):
        rec.tick(1_000_000_000 + k, None, None, None, None, {"tension_N": value})
    rec.transition(2_000_000_000, Record("autonomous/rest"))
    rec.tick(2_000_000_001, None, None, None, None, {"tension_N": 0.25})
    rec.tick(2_000_000_002, None, None, None, None, {})  # no thread this tick
    rec.transition(3_000_000_000, Record("done"))
    assert [(s["step"], s["peak_true_N"]) for s in rec.steps] == [("pull", 3.25), ("rest", 0.25)]
    assert rec.peak_true_N == 3.25
    row = {"variant": "v", "outcome": "succeeded", "final_state": "done", "sim_time_s": 3.0,
           "knot": None, "knot_centre_mm": None, "peak_true_tension_N": 3.25, "branch_s": 1.0,
           "steps": rec.steps}  # fmt: skip
    assert "true peak 3.25 N" in bs.format_results([row]).splitlines()[1]


def test_the_thread_flags_reach_the_branches_backend(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    seen: dict = {}  # type: ignore[type-arg]

    def fake_run_branches(procedure: str, **kwargs: object) -> list[dict]:  # type: ignore[type-arg]
        seen.update(kwargs)
        return []

    monkeypatch.setattr(bs, "run_branches", fake_run_branches)
    argv = ["p.yaml", "--at", "s", "--thread-damping", "20", "--thread-weight", "4"]
    assert bs.main(argv) == 0
    assert seen["backend_options"] == {"thread_damping": 20.0, "thread_weight": 4e-3}
    seen.clear()
    # a sweep run's perturbation keeps its own options beside the thread's
    argv = [*argv, "--sweep-run", "3:1", "--backend", "pybullet-surgical-stitched"]
    assert bs.main(argv) == 0
    assert seen["backend_options"]["thread_weight"] == 4e-3
    assert "friction_scale" in seen["backend_options"]
    for flag, value, message in (
        ("--thread-damping", "-1", "a rate >= 0 [1/s], got -1.0"),
        ("--thread-weight", "0", "a mass per length > 0 [g/m], got 0.0"),
    ):
        with pytest.raises(SystemExit):
            bs.main(["p.yaml", "--at", "s", flag, value])
        assert f"{flag}: {message}" in capsys.readouterr().err
