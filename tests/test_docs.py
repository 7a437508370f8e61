"""The docs pages: the generated language reference and the plugin example."""

from __future__ import annotations

import importlib.util
import re
import shutil
import sys
import types
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"


def _generator() -> types.ModuleType:
    spec = importlib.util.spec_from_file_location(
        "gen_language_reference", DOCS / "gen_language_reference.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_language_reference_covers_the_whole_schema() -> None:
    gen = _generator()
    schema = gen.schema()
    text = gen.render(schema)
    for name, definition in schema["$defs"].items():
        assert f'<a id="{name.lower()}"></a>' in text, name
        for field in definition.get("properties", {}):
            assert f"| `{field}` |" in text, (name, field)
    from skills.registry import available_skills

    for skill in available_skills():
        assert f"`{skill}` skill parameters" in text, skill
    # meanings come from the models' attribute docstrings, with units
    assert "How long to hold [s]" in text
    # and the committed page is the one the schema gives (a new field is not left out)
    assert (DOCS / "language.md").read_text() == text, "run python docs/gen_language_reference.py"


def test_plugin_page_skill_runs(tmp_path: Path) -> None:
    from skills.registry import register_skill
    from suture_engine.runtime.run import run_procedure
    from suture_engine.trace.reader import TraceReader

    page = (DOCS / "plugins.md").read_text(encoding="utf-8")
    code = re.findall(r"```python\n(.*?)```", page, re.S)[0]
    module = types.ModuleType("docs_nudge_plugin")
    sys.modules[module.__name__] = module
    exec(compile(code, str(DOCS / "plugins.md"), "exec"), module.__dict__)
    register_skill(module.Nudge)
    shutil.copy(ROOT / "tests" / "procedures" / "scene.yaml", tmp_path / "scene.yaml")
    (tmp_path / "nudge.yaml").write_text(
        "procedure: nudge-demo\n"
        'version: "1"\n'
        "scene: scene.yaml\n"
        "roles: {stitcher: endobot_1, grasper: endobot_2}\n"
        "initial: push\n"
        "states:\n"
        "  push:\n"
        "    skill: nudge\n"
        "    with: {robot: stitcher, distance: 3 mm}\n"
        "    timeout: 2 s\n"
        '    "on": {done: finished}\n'
        "  finished:\n"
        "    outcome: succeeded\n",
        encoding="utf-8",
    )
    result = run_procedure(tmp_path / "nudge.yaml", out=tmp_path / "out", max_time_s=5.0)
    assert result.summary.outcome == "succeeded"
    q4 = [
        m.data["position"][3]
        for m in TraceReader(result.trace).messages(["/joint_state/endobot_1"])
    ]
    assert abs((q4[-1] - q4[0]) - 0.003) < 5e-4  # pushed 3 mm [m]
