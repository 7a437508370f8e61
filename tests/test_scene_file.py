"""Scene files that extend another (``extends:``): merging, locations, and bad input."""

from __future__ import annotations

from pathlib import Path

import pytest

from suture_engine.language.loader import load
from suture_engine.language.scene_file import MAX_EXTENDS, load_scene, read_scene
from suture_engine.validation.problem import ProblemError

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "procedures" / "scenes"
BENCH = (SCENES / "bench.yaml").read_text(encoding="utf-8")

PROCEDURE = """\
procedure: p
version: "1"
scene: {scene}
roles: {{stitcher: endobot_1}}
initial: wait
states:
  wait:
    skill: hold
    with: {{robot: stitcher, duration: 0.1 s}}
    on: {{done: end}}
  end: {{outcome: succeeded}}
"""


def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def _problems(tmp_path: Path, scene_ref: str) -> list:
    proc = _write(tmp_path, "p.yaml", PROCEDURE.format(scene=scene_ref))
    return load(proc).problems


def test_a_child_changes_one_field_and_keeps_the_rest_of_its_section(tmp_path: Path) -> None:
    _write(tmp_path, "bench.yaml", BENCH)
    child = _write(
        tmp_path, "long.yaml", "extends: bench.yaml\nname: long\nsuture: {length: 140 mm}\n"
    )
    base, scene = load_scene(tmp_path / "bench.yaml"), load_scene(child)
    assert scene.name == "long"
    assert scene.suture.length == pytest.approx(0.14)
    # the rest of `suture` and every other section come from the extended file
    assert scene.suture.usp == base.suture.usp and scene.suture.start == "tail-held"
    assert scene.model_dump(exclude={"name", "suture"}) == base.model_dump(
        exclude={"name", "suture"}
    )


def test_null_resets_a_field_and_lists_are_replaced_whole(tmp_path: Path) -> None:
    _write(tmp_path, "bench.yaml", BENCH)
    child = _write(
        tmp_path,
        "c.yaml",
        "extends: bench.yaml\nsuture: {start: null}\n"
        "tissue: {wound: {start: [-5 mm, 0 mm, 0 mm], end: [5 mm, 0 mm, 0 mm]}}\n",
    )
    scene = load_scene(child)
    assert scene.suture.start is None
    assert scene.tissue.wound.start == pytest.approx((-0.005, 0.0, 0.0))
    assert scene.tissue.stiffness == pytest.approx(200.0)  # kept from bench.yaml


def test_chains_and_the_scene_wrapper(tmp_path: Path) -> None:
    _write(
        tmp_path,
        "base/bench.yaml",
        "scene:\n" + "".join("  " + ln + "\n" for ln in BENCH.splitlines()),
    )
    _write(tmp_path, "mid.yaml", "extends: base/bench.yaml\nsuture: {length: 130 mm}\n")
    top = _write(tmp_path, "top.yaml", "scene:\n  extends: mid.yaml\n  name: top\n")
    scene = load_scene(top)
    assert (scene.name, scene.suture.length) == ("top", pytest.approx(0.13))


def test_the_bundled_variants_equal_their_written_out_form() -> None:
    """The bundled scenes that extend bench.yaml give what their comments say, checked
    against bench.yaml's own values (not against the merge)."""
    bench = load_scene(SCENES / "bench.yaml")
    square = load_scene(SCENES / "bench-square.yaml")
    assert square.suture.length == pytest.approx(0.14) and square.suture.start is None
    assert square.robots == bench.robots and square.tissue == bench.tissue
    posts = load_scene(SCENES / "bench-square-posts.yaml")
    assert sorted(posts.posts) == ["grasper_far", "grasper_near", "stitcher_far", "stitcher_near"]
    assert posts.suture == square.suture and posts.robots == bench.robots
    bent = load_scene(SCENES / "bench-bent-tip.yaml")
    assert (bent.robots["endobot_1"].tool, bent.robots["endobot_2"].tool) == (
        "grasper",
        "bent-tip-grasper",
    )
    assert bent.robots["endobot_1"].base == bench.robots["endobot_1"].base


def test_a_bad_value_is_located_in_the_file_that_wrote_it(tmp_path: Path) -> None:
    _write(tmp_path, "scenes/bench.yaml", BENCH.replace("stiffness: 200 N/m", "stiffness: -1 N/m"))
    _write(
        tmp_path,
        "scenes/child.yaml",
        "extends: bench.yaml\nname: child\n\nsuture: {length: -3 mm}\n",
    )
    problems = _problems(tmp_path, "scenes/child.yaml")
    where = {(Path(p.file).name, p.line, p.path) for p in problems}
    assert ("child.yaml", 4, "suture.length") in where
    line = BENCH.splitlines().index("  stiffness: 200 N/m") + 1
    assert ("bench.yaml", line, "tissue.stiffness") in where


@pytest.mark.parametrize(
    ("files", "code", "words"),
    [
        ({"c.yaml": "extends: nowhere.yaml\n"}, "missing-scene", "nowhere.yaml"),
        ({"c.yaml": "extends: [bench.yaml]\n"}, "scene-extends", "path"),
        ({"c.yaml": "extends: c.yaml\n"}, "scene-extends", "cycle"),
        ({"c.yaml": "extends: d.yaml\n", "d.yaml": "extends: c.yaml\n"}, "scene-extends", "cycle"),
        ({"c.yaml": "extends: d.yaml\n", "d.yaml": "- a list\n"}, "scene-extends", "mapping"),
        ({"c.yaml": "extends: ../../outside.yaml\n"}, "include-outside", "outside"),
        ({"c.yaml": "extends: d.yaml\n", "d.yaml": "a: [unclosed\n"}, "yaml-syntax", ""),
    ],
)
def test_bad_extends_is_a_located_problem(
    tmp_path: Path, files: dict[str, str], code: str, words: str
) -> None:
    _write(tmp_path, "outside.yaml", BENCH)
    for name, text in files.items():
        _write(tmp_path, "proc/scenes/" + name, text)
    problems = _problems(tmp_path / "proc", "scenes/c.yaml")
    assert [p.code for p in problems] == [code], problems
    assert words in problems[0].message
    assert problems[0].line >= 1 and problems[0].file.endswith(".yaml")


def test_a_chain_longer_than_the_limit_is_refused(tmp_path: Path) -> None:
    _write(tmp_path, "s0.yaml", BENCH)
    for i in range(1, MAX_EXTENDS + 2):
        _write(tmp_path, f"s{i}.yaml", f"extends: s{i - 1}.yaml\n")
    assert load_scene(tmp_path / f"s{MAX_EXTENDS}.yaml").name == "bench"
    with pytest.raises(ProblemError) as err:
        read_scene(tmp_path / f"s{MAX_EXTENDS + 1}.yaml")
    assert err.value.problems[0].code == "scene-extends"


def test_an_inline_scene_can_extend_a_file(tmp_path: Path) -> None:
    _write(tmp_path, "scenes/bench.yaml", BENCH)
    result = load(
        _write(tmp_path, "p.yaml", PROCEDURE.format(scene="{extends: scenes/bench.yaml, name: x}"))
    )
    assert result.problems == []
    assert result.procedure is not None and result.procedure.scene.name == "x"


def test_an_inline_scene_that_extends_is_located_in_the_procedure(tmp_path: Path) -> None:
    _write(tmp_path, "scenes/bench.yaml", BENCH)
    problems = _problems(tmp_path, "\n  extends: scenes/bench.yaml\n  suture: {length: -1 mm}")
    assert [(Path(p.file).name, p.line, p.path) for p in problems] == [
        ("p.yaml", 5, "scene.suture.length")
    ]


@pytest.mark.parametrize(
    "base", ["bench-square", "bench-square-posts", "bench-square-stitch", "bench-bent-tip",
             "bench-bent-tip-posts"],
)  # fmt: skip
def test_each_closed_wound_scene_is_its_base_with_the_edges_apposed(base: str) -> None:
    """``<base>-closed.yaml`` changes only the wound's opening (to 0) and the name."""
    open_ = load_scene(SCENES / f"{base}.yaml")
    closed = load_scene(SCENES / f"{base}-closed.yaml")
    assert open_.tissue.wound.gap is None  # the pad's own 1 mm slit
    assert closed.tissue.wound.gap == 0.0
    assert closed.name == f"{base}-closed"
    for field in type(open_).model_fields:
        if field not in ("name", "tissue"):
            assert getattr(closed, field) == getattr(open_, field), field
    assert closed.tissue.model_dump(exclude={"wound"}) == open_.tissue.model_dump(exclude={"wound"})
    assert closed.tissue.wound.start == open_.tissue.wound.start
    assert closed.tissue.wound.end == open_.tissue.wound.end


@pytest.mark.parametrize("algorithm", [1, 2, 3])
@pytest.mark.parametrize("register", [False, True])
def test_the_square_knot_takes_the_closed_scene_with_wound_closed(
    algorithm: int, register: bool
) -> None:
    from suture_engine.language.loader import load_procedure

    params = {"algorithm": algorithm, "register": register}
    slit = load_procedure(ROOT / "procedures" / "square-knot.yaml", params=params).scene
    closed = load_procedure(
        ROOT / "procedures" / "square-knot.yaml", params={**params, "wound": "closed"}
    ).scene
    assert closed.name == f"{slit.name}-closed"
    assert (slit.tissue.wound.gap, closed.tissue.wound.gap) == (None, 0.0)
