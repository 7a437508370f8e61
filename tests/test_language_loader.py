"""Loading the bundled procedures: SI values, scenes, use: with parameters."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from suture_engine.language.loader import load, load_procedure
from suture_engine.language.scene import GRAVITY
from suture_engine.validation.problem import ProblemError

ROOT = Path(__file__).resolve().parent.parent
PROCEDURES = ROOT / "procedures"
BUNDLED = sorted(PROCEDURES.glob("*.yaml"))


def test_the_bundled_set_is_complete() -> None:
    names = {p.stem for p in BUNDLED}
    assert {
        "stitch",
        "knot-algorithm-1",
        "knot-algorithm-2",
        "knot-algorithm-3",
        "square-knot",
        "surgeons-knot",
        "secure-knot",
        "interrupted-suture",
        "shared-control-line",
        "shared-control-circle",
    } <= names


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.stem)
def test_bundled_procedures_load_without_problems(path: Path) -> None:
    result = load(path)
    assert result.problems == []
    assert result.procedure is not None
    assert result.procedure.initial in result.procedure.states


def test_quantities_are_si_after_load() -> None:
    proc = load_procedure(PROCEDURES / "stitch.yaml")
    assert proc.params["tail"] == pytest.approx(0.030)
    bite = proc.states["bite"]
    assert bite.params is not None
    # the 120 mm bench thread less the 30 mm tail less 38 mm, all in metres
    assert bite.params.pull_length == pytest.approx(0.120 - 0.030 - 0.038)  # type: ignore[attr-defined]
    assert bite.invariant is not None and bite.invariant.max_tension == pytest.approx(3.0)
    assert bite.timeout == pytest.approx(30.0)
    assert proc.states["approach"].params.offset == pytest.approx((0, 0, 0.01))  # type: ignore[union-attr]


def test_scene_tables_and_tension_limit() -> None:
    proc = load_procedure(PROCEDURES / "stitch.yaml")
    scene = proc.scene
    assert scene is not None
    # Table 7.1: USP 2-0 is 0.30-0.339 mm and 1.44 kgf; Table 7.2: skin pulls out at 17.85 N
    assert scene.suture.diameter == pytest.approx(0.5 * (0.30 + 0.339) * 1e-3)
    assert scene.suture.knot_pull_strength == pytest.approx(1.44 * GRAVITY)
    assert scene.tissue.pullout_tension == pytest.approx(17.85)
    assert scene.tension_limit == pytest.approx(min(1.44 * GRAVITY, 17.85) * 0.5)
    assert scene.robots["endobot_1"].base.rpy[0] == pytest.approx(math.pi)
    assert scene.physics.measurement_delay == pytest.approx(0.002)


def test_square_knot_is_a_simple_knot_then_its_mirror() -> None:
    proc = load_procedure(PROCEDURES / "square-knot.yaml")
    first, second = proc.states["simple-knot"], proc.states["mirrored-knot"]
    assert first.use is not None and second.use is not None
    assert first.use.name == second.use.name == "knot-algorithm-2"
    assert first.use.params["mirror"] is False
    assert second.use.params["mirror"] is True
    # the mirror image passes the needle the other way: the first throw left it in the
    # stitcher's other jaw, so the second passes it back at the same roll (with the
    # stitcher turned 180 deg it would pass the same way: a granny knot)
    rolls = [s.use.states["under"].params.roll for s in (first, second)]  # type: ignore[union-attr]
    assert rolls[0] == pytest.approx(rolls[1])
    granny = load_procedure(PROCEDURES / "square-knot.yaml", params={"mirror": False})
    third = granny.states["mirrored-knot"].use
    assert third is not None
    assert third.states["under"].params.roll == pytest.approx(rolls[0] + math.pi)  # type: ignore[union-attr]
    # by default the stitch is already made; with stitch=true the first throw makes it,
    # and the second throw does not stitch again
    assert second.use.states["stitch"].enabled is False
    assert first.use.states["stitch"].enabled is False
    chain = load_procedure(PROCEDURES / "square-knot.yaml", params={"stitch": True})
    assert chain.states["simple-knot"].use.states["stitch"].enabled is True  # type: ignore[union-attr]
    assert chain.states["mirrored-knot"].use.states["stitch"].enabled is False  # type: ignore[union-attr]
    assert (proc.backend, chain.backend) == ("pybullet-surgical-stitched", "pybullet-surgical")


@pytest.mark.parametrize("algorithm", [1, 2, 3])
def test_square_knot_algorithm_parameter(algorithm: int) -> None:
    proc = load_procedure(PROCEDURES / "square-knot.yaml", params={"algorithm": algorithm})
    assert proc.states["simple-knot"].use.name == f"knot-algorithm-{algorithm}"  # type: ignore[union-attr]
    if algorithm == 1:
        rotate = proc.states["mirrored-knot"].use.states["rotate"].params  # type: ignore[union-attr]
        assert rotate.angle == pytest.approx(-math.pi)  # type: ignore[union-attr]
    if algorithm == 3:
        assert proc.scene is not None
        assert proc.scene.robots["endobot_2"].tool == "bent-tip-grasper"


def test_square_knot_rejects_algorithm_4() -> None:
    with pytest.raises(ProblemError) as info:
        load_procedure(PROCEDURES / "square-knot.yaml", params={"algorithm": 4})
    assert [p.code for p in info.value.problems] == ["out-of-bounds"]


def test_surgeons_knot_first_throw_has_two_turns() -> None:
    proc = load_procedure(PROCEDURES / "surgeons-knot.yaml")
    wrap = proc.states["double-knot"].use.states["over-hook"].params  # type: ignore[union-attr]
    assert wrap.turns == 2  # type: ignore[union-attr]


def test_interrupted_suture_ties_three_stitches_5mm_apart() -> None:
    proc = load_procedure(PROCEDURES / "interrupted-suture.yaml")
    assert proc.scene is not None
    points = proc.scene.tissue.points
    entries = []
    for k in (2, 1, 3):  # the halving order: the middle stitch first
        square = proc.states[f"knot-{k}"].use
        assert square is not None and square.name == "square-knot"
        assert square.params["entry"] == f"entry_{k}" and square.params["exit"] == f"exit_{k}"
        entries.append(points[square.params["entry"]])
        # each stitch's suture is cut once it is tied
        assert proc.states[f"cut-{k}"].skill == "cut-suture"
    for k in (1, 3):  # and the next one loaded at its site, the stitcher over its exit
        load = proc.states[f"load-{k}"]
        assert load.skill == "load-suture"
        assert (load.params.entry, load.params.exit) == (f"entry_{k}", f"exit_{k}")  # type: ignore[union-attr]
        assert proc.states[f"stitcher-over-{k}"].params.target == f"exit_{k}"  # type: ignore[union-attr]
    xs = sorted(e[0] for e in entries)
    assert xs[1] - xs[0] == pytest.approx(0.005) and xs[2] - xs[1] == pytest.approx(0.005)


def test_interrupted_suture_by_algorithm_3_registers_once_on_its_bench() -> None:
    """``algorithm=3``: algorithm 3's bench with the calibration posts; the first square
    registers the bases and takes the posts away, the later two do not register, and
    their mirrored holders do not go round the posts that are gone."""
    from suture_engine.runtime.plan import compile_procedure

    proc = load_procedure(PROCEDURES / "interrupted-suture.yaml", params={"algorithm": 3})
    assert proc.scene is not None and proc.scene.name == "bench-bent-tip-posts"
    assert proc.scene.posts  # the posts are in the scene the run starts with
    assert proc.scene.robots["endobot_2"].tool == "bent-tip-grasper"
    plan = compile_procedure(proc)
    assert plan.steps["knot-2.register.grasper"].enabled
    assert plan.steps["knot-2.register.remove-posts"].enabled
    for k in (1, 3):
        assert not plan.steps[f"knot-{k}.register"].enabled
        # posts in the scene, but taken away before: the holder goes straight up
        assert not plan.steps[f"knot-{k}.mirrored-knot.clear-post"].enabled
    # algorithm 2 keeps its bench and registers nowhere
    two = compile_procedure(
        load_procedure(PROCEDURES / "interrupted-suture.yaml", params={"algorithm": 2})
    )
    assert not any(
        name.endswith("remove-posts") and step.enabled for name, step in two.steps.items()
    )


def test_interrupted_suture_by_algorithm_3_holds_every_tail_grasp_until_the_jaws_shut() -> None:
    """``algorithm=3``: each square's two tail grasps dwell 0.2 s after the jaw reports
    closed (``grab_dwell``); algorithm 2's grasps do not, and ``--set grab_dwell`` wins."""
    from suture_engine.runtime.plan import compile_procedure

    def dwells(params: dict[str, object]) -> dict[str, float]:
        plan = compile_procedure(
            load_procedure(PROCEDURES / "interrupted-suture.yaml", params=params)
        )
        return {
            name: step.make_skill().params.dwell  # type: ignore[attr-defined]
            for name, step in plan.steps.items()
            if name.endswith("grab-tail") and step.enabled
        }

    three = dwells({"algorithm": 3})
    throws = ("simple-knot", "mirrored-knot")
    assert set(three) == {f"knot-{k}.{t}.grab-tail" for k in (1, 2, 3) for t in throws}
    assert sorted(three.values()) == pytest.approx([0.2] * 6)
    assert set(dwells({"algorithm": 2}).values()) == {0.0}
    assert dwells({}) == three  # algorithm 3 is the default
    assert set(dwells({"algorithm": 3, "grab_dwell": "0 s"}).values()) == {0.0}


def test_shared_control_line_uses_table_6_1() -> None:
    proc = load_procedure(PROCEDURES / "shared-control-line.yaml")
    params = proc.states["along-line"].params
    assert params.fixture == "line"  # type: ignore[union-attr]
    assert params.direction == (1.0, 1.0, -2.0)  # type: ignore[union-attr]
    assert params.point == (0.0, 0.0, 0.0)  # type: ignore[union-attr]


def test_override_of_unknown_parameter_is_reported() -> None:
    result = load(PROCEDURES / "stitch.yaml", params={"tial": "20 mm"})
    (problem,) = result.problems
    assert problem.code == "unknown-param" and "did you mean 'tail'" in problem.message


def test_includes_outside_the_tree_need_an_allowance(tmp_path: Path) -> None:
    inner = tmp_path / "mine"
    inner.mkdir()
    text = (
        "procedure: outside\n"
        f"scene: {PROCEDURES / 'scenes' / 'bench.yaml'}\n"
        "roles: {stitcher: endobot_1, grasper: endobot_2}\n"
        "initial: a\n"
        "states:\n"
        f"  a: {{use: {PROCEDURES / 'stitch.yaml'}, on: {{done: end}}}}\n"
        "  end: {outcome: succeeded}\n"
    )
    path = inner / "p.yaml"
    path.write_text(text)
    codes = [p.code for p in load(path).problems]
    assert codes == ["include-outside", "include-outside"]
    assert load(path, allow_outside=True).problems == []
    path.write_text("includes_outside: true\n" + text)
    assert load(path).problems == []


def test_parameter_bounds_and_bare_numbers_in_the_declared_unit(tmp_path: Path) -> None:
    sub = tmp_path / "sub.yaml"
    sub.write_text(
        "procedure: sub\n"
        "params:\n"
        "  tail: {type: quantity, unit: mm, default: 30, min: 10 mm, max: 0.1 m}\n"
        "initial: end\n"
        "states:\n"
        "  end: {outcome: succeeded}\n"
    )
    result = load(sub)
    assert result.procedure is not None
    assert result.procedure.params["tail"] == pytest.approx(0.030)  # 30 in mm
    assert [p.code for p in result.problems] == ["missing-scene"]  # a file alone needs a scene
    codes = [p.code for p in load(sub, params={"tail": "11 cm"}).problems]
    assert sorted(codes) == ["missing-scene", "out-of-bounds"]


def _defaults_file(tmp_path: Path, params: str) -> Path:
    path = tmp_path / "defaults.yaml"
    path.write_text(
        "procedure: defaults\n"
        f"scene: {PROCEDURES / 'scenes' / 'bench.yaml'}\n"
        "params:\n"
        "  algorithm: {type: int, default: 2, choices: [1, 2, 3]}\n"
        f"{params}"
        "initial: end\n"
        "states:\n"
        "  end: {outcome: succeeded}\n"
    )
    return path


def test_a_default_may_be_an_expression_over_the_parameters_before_it(tmp_path: Path) -> None:
    """``default: ${...}`` is evaluated over the values of the parameters declared before
    it, whether they were defaulted or set; a value set for the parameter itself wins."""
    path = _defaults_file(
        tmp_path,
        "  register: {type: bool, default: '${algorithm == 3}'}\n"
        "  gap: {type: quantity, unit: mm, default: '${2 mm if register else 5 mm}', max: 6 mm}\n"
        "  tag: {type: str, default: 'alg-${algorithm}'}\n",
    )
    cases = [
        ({}, (False, 0.005)),
        ({"algorithm": 3}, (True, 0.002)),
        ({"algorithm": 3, "register": False}, (False, 0.005)),
        ({"register": True, "gap": "4 mm"}, (True, 0.004)),
    ]
    for given, (register, gap) in cases:
        params = load_procedure(path, params=given, allow_outside=True).params
        assert params["register"] is register, given
        assert params["gap"] == pytest.approx(gap), given
        assert params["tag"] == f"alg-{given.get('algorithm', 2)}", given  # text around it


@pytest.mark.parametrize(
    ("line", "code", "says"),
    [
        (
            "  early: {type: bool, default: '${late > 1}'}\n  late: {type: int, default: 1}\n",
            "bad-expression",
            "'late', which is not declared before it",
        ),
        ("  own: {type: int, default: '${own + 1}'}\n", "bad-expression", "'own'"),
        ("  flag: {type: bool, default: '${algorithm}'}\n", "bad-param", "expected true or false"),
        (
            "  gap: {type: quantity, unit: mm, default: '${algorithm * 1 N}'}\n",
            "unit-mismatch",
            "expected length",
        ),
        (
            "  gap: {type: quantity, unit: mm, default: '${algorithm * 4 mm}', max: 10 mm}\n",
            "out-of-bounds",
            "above max",
        ),
        ("  n: {type: int, default: '${nope}'}\n", "bad-expression", "unknown name 'nope'"),
    ],
)
def test_a_bad_default_expression_is_one_problem_at_the_default(
    tmp_path: Path, line: str, code: str, says: str
) -> None:
    path = _defaults_file(tmp_path, line)
    problems = load(path, params={"algorithm": 3}, allow_outside=True).problems
    assert [(p.code, p.path.rsplit(".", 1)[-1]) for p in problems] == [(code, "default")], problems
    assert says in problems[0].message
    assert problems[0].line == 5  # the first parameter after `algorithm`, the one at fault


def test_a_requirement_over_the_parameters_is_one_problem_where_the_value_was_set(
    tmp_path: Path,
) -> None:
    """``requires: ${...}`` must hold over the parameter and those before it. Broken by a
    value the caller set, it is reported at that value (the override, or a ``use:``'s
    ``with``); broken by a default, at the ``requires`` (line 5)."""
    path = _defaults_file(
        tmp_path,
        "  hook: {type: bool, default: false, requires: '${not hook or algorithm == 2}',\n"
        "         description: algorithm 2's hook}\n",
    )
    for given in ({}, {"hook": True}, {"algorithm": 2, "hook": True}, {"algorithm": 3}):
        assert load(path, params=given, allow_outside=True).problems == [], given
    for given, setter in (
        ({"algorithm": 3, "hook": True}, "hook"),
        ({"hook": True, "algorithm": 1}, "hook"),
    ):
        (problem,) = load(path, params=given, allow_outside=True).problems
        assert problem.code == "unmet-requirement"
        assert problem.message.startswith("(override)")
        assert f"here algorithm={given['algorithm']}, hook=true" in problem.message
        assert problem.message.endswith("algorithm 2's hook")
        assert problem.path.endswith(setter)
    # a use:'s with is a caller too: reported at its value, in the calling file
    parent = tmp_path / "parent.yaml"
    parent.write_text(
        "procedure: parent\n"
        f"scene: {PROCEDURES / 'scenes' / 'bench.yaml'}\n"
        "initial: sub\n"
        "states:\n"
        "  sub: {use: defaults.yaml, with: {algorithm: 3, hook: true}, on: {done: end}}\n"
        "  end: {outcome: succeeded}\n"
    )
    (problem,) = load(parent, allow_outside=True).problems
    assert problem.code == "unmet-requirement" and problem.file.endswith("parent.yaml")
    assert problem.line == 5 and problem.path.endswith("with.hook"), problem
    # the default breaks it once algorithm is set: reported at the algorithm the caller set
    defaulted = _defaults_file(
        tmp_path, "  hook: {type: bool, default: true, requires: '${not hook or algorithm == 2}'}\n"
    )
    (problem,) = load(defaulted, params={"algorithm": 3}, allow_outside=True).problems
    assert problem.code == "unmet-requirement" and problem.path.endswith("algorithm")
    # and by the file alone: at the requirement itself
    alone = _defaults_file(
        tmp_path, "  hook: {type: bool, default: true, requires: '${not hook or algorithm == 3}'}\n"
    )
    (problem,) = load(alone, allow_outside=True).problems
    assert (problem.code, problem.path, problem.line) == (
        "unmet-requirement", "params.hook.requires", 5,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("requires", "says"),
    [
        ("hook", "must be one `${...}` condition"),
        ("${later > 1}", "'later', which is not declared before it"),
        ("${algorithm}", "gives 2, not true or false"),
        ("${nope}", "unknown name 'nope'"),
    ],
)
def test_a_bad_requirement_is_a_problem_at_the_requirement(
    tmp_path: Path, requires: str, says: str
) -> None:
    path = _defaults_file(
        tmp_path,
        f"  hook: {{type: bool, default: false, requires: '{requires}'}}\n"
        "  later: {type: int, default: 1}\n",
    )
    (problem,) = load(path, allow_outside=True).problems
    assert (problem.code, problem.path) == ("bad-expression", "params.hook.requires"), problem
    assert says in problem.message


def test_the_interrupted_suture_secures_only_on_algorithm_2s_tools() -> None:
    """``secure`` ties with secure-knot.yaml, on algorithm 2's hook and stitcher: with the
    default algorithm 3 it is one problem at the override, not the tools' mismatches."""
    path = PROCEDURES / "interrupted-suture.yaml"
    (problem,) = load(path, params={"secure": True}).problems
    assert problem.code == "unmet-requirement" and "algorithm=3, secure=true" in problem.message
    assert load(path, params={"secure": True, "algorithm": 2}).problems == []


@pytest.mark.parametrize(("scene", "posts"), [("bench.yaml", 0), ("bench-posts.yaml", 4)])
def test_scene_posts_counts_the_calibration_posts_for_every_included_file(
    tmp_path: Path, scene: str, posts: int
) -> None:
    """``${scene.posts}`` is the number of posts the scene file declares (bench.yaml none,
    bench-posts.yaml four), and a ``use:``d procedure reads its caller's scene."""
    hold = "skill: hold, with: {robot: grasper, duration: '${scene.posts * 1 s}'}"
    sub = tmp_path / "sub.yaml"
    sub.write_text(
        "procedure: sub\n"
        "initial: b\n"
        "states:\n"
        f"  b: {{{hold}, on: {{done: end}}}}\n"
        "  end: {outcome: succeeded}\n"
    )
    top = tmp_path / "top.yaml"
    top.write_text(
        "procedure: top\n"
        f"scene: {PROCEDURES / 'scenes' / scene}\n"
        "roles: {stitcher: endobot_1, grasper: endobot_2}\n"
        "initial: a\n"
        "states:\n"
        f"  a: {{{hold}, on: {{done: b}}}}\n"
        "  b: {use: sub.yaml, on: {done: end}}\n"
        "  end: {outcome: succeeded}\n"
    )
    result = load(top, allow_outside=True)
    assert result.problems == []
    assert result.procedure is not None
    assert result.procedure.states["a"].params.duration == posts
    assert result.procedure.states["b"].use.states["b"].params.duration == posts
