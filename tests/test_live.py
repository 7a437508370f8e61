"""Live supervision: the panel, the GUI key mapping, and ``--interactive`` under a pseudo-terminal.

The PyBullet window cannot be opened on a machine without a display, so the GUI keys are
tested through :func:`gui_key_actions` with PyBullet's own key flags as the oracle.
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

from suture_engine.runtime.live import (
    KEY_WAS_TRIGGERED,
    LivePanel,
    PanelSnapshot,
    TappedOperator,
    gui_key_actions,
    render_panel,
    tension_bar,
)
from suture_engine.runtime.operator import OperatorEvent
from suture_engine.runtime.run import run_procedure
from suture_engine.trace.reader import TraceReader

ROOT = Path(__file__).resolve().parent.parent
PROCS = ROOT / "tests" / "procedures"

LONG_HOLD = """\
procedure: long-hold
version: "1"
description: One long hold, for supervising by hand.
scene: scene.yaml
roles: {stitcher: endobot_1, grasper: endobot_2}
initial: hold
states:
  hold:
    skill: hold
    with: {robot: stitcher, duration: 600 s}
    "on": {done: finished}
  finished:
    outcome: succeeded
"""


def test_gui_keys_map_like_the_terminal_keys() -> None:
    import pybullet as p

    assert KEY_WAS_TRIGGERED == p.KEY_WAS_TRIGGERED
    events = {
        ord("l"): p.KEY_WAS_TRIGGERED,
        ord("m"): p.KEY_IS_DOWN,  # held since an earlier query: not a new press
        ord("A"): p.KEY_WAS_TRIGGERED | p.KEY_IS_DOWN,
        ord("r"): p.KEY_WAS_RELEASED,
        ord("x"): p.KEY_WAS_TRIGGERED,  # not an operator key
        p.B3G_F1: p.KEY_WAS_TRIGGERED,
    }
    assert gui_key_actions(events) == ["abort", "lock"]
    assert gui_key_actions({ord(c): p.KEY_WAS_TRIGGERED for c in "mr"}) == ["manual", "resume"]
    assert gui_key_actions({}) == []


def test_tension_bar() -> None:
    assert tension_bar(1.5, 3.0, width=10) == "[#####.....] 1.50/3.00 N"
    assert tension_bar(9.0, 3.0, width=4) == "[####] 9.00/3.00 N"
    assert tension_bar(-0.2, 3.0, width=4) == "[....] -0.20/3.00 N"
    assert tension_bar(0.7, None) == "0.70 N (no limit)"


def test_render_panel_shows_what_the_surgeon_needs() -> None:
    from rich.console import Console

    snap = PanelSnapshot(
        procedure="steps",
        state="NOT-BE(tighten)",
        step="tighten",
        mode="lock",
        robot_modes={"endobot_1": "lock", "endobot_2": "lock"},
        tension_N={"endobot_1": 2.5},
        tension_limit_N=3.0,
        sim_time_s=12.345,
        real_time_factor=0.8,
        events=("   1.000 s  operator lock (interactive)",),
        waiting=True,
    )
    console = Console(record=True, width=100, force_terminal=False)
    console.print(render_panel(snap))
    text = console.export_text()
    for expected in (
        "suture run: steps",
        "NOT-BE(tighten)  (waiting for the operator)",
        "endobot_1",
        "mode lock",
        "2.50/3.00 N",
        "12.35 s",
        "0.80",
        "operator lock (interactive)",
        "l lock   m manual   r resume   a abort",
    ):
        assert expected in text, expected


def test_tapped_operator_passes_events_through_and_adds_gui_keys() -> None:
    class Keys:
        def __init__(self) -> None:
            self.queue = [OperatorEvent("lock", source="interactive")]

        def poll(self, t: float, state: str, step: str | None, mode: str) -> list[OperatorEvent]:
            out, self.queue = self.queue, []
            return out

    tap = TappedOperator(Keys())
    tap.push_gui(["resume"])
    got = tap.poll(0.5, "s", "s", "autonomous")
    assert [(e.action, e.source) for e in got] == [("lock", "interactive"), ("resume", "gui")]
    assert tap.poll(0.6, "s", "s", "autonomous") == []
    assert [t for t, _ in tap.handed] == [0.5, 0.5]
    assert tap.exhausted is None  # a keyboard can always send more: never "stuck"


def test_panel_follows_a_scripted_run(tmp_path: Path) -> None:
    panel = LivePanel("steps", every=10, max_events=100)
    result = run_procedure(
        PROCS / "steps.yaml",
        backend="ideal",
        out=tmp_path / "run",
        operator_file=PROCS / "ops-abort.yaml",
        on_tick=panel,
    )
    assert result.summary.outcome == "aborted"
    snap = panel.snapshot
    assert snap.mode == "terminal"
    assert snap.state == "ABORTED" and not snap.waiting
    assert snap.sim_time_s == pytest.approx(result.summary.sim_time_s, abs=2e-3)
    text = "\n".join(snap.events)
    assert "operator force (scripted) accepted" in text
    assert "operator abort (scripted) accepted" in text
    # every transition after the start appears in the panel, in the trace's order
    recorded = [
        f"{m.data['source']} -> {m.data['dest']}"
        for m in TraceReader(result.trace).messages(["/transitions"])
    ]
    shown = [line.split(" s  ")[1].split(":")[0] for line in snap.events if " -> " in line]
    assert len(shown) >= 5
    assert shown == recorded[1:]


def test_interactive_keys_under_a_pseudo_terminal(tmp_path: Path) -> None:
    pexpect = pytest.importorskip("pexpect")
    shutil.copy(PROCS / "scene.yaml", tmp_path / "scene.yaml")
    (tmp_path / "long.yaml").write_text(LONG_HOLD)
    out = tmp_path / "out"
    child = pexpect.spawn(
        sys.executable,
        [
            "-c",
            "from suture_engine.cli import main; main()",
            "run",
            "long.yaml",
            "--backend",
            "ideal",
            "--interactive",
            "--max-time",
            "300",
            "--out",
            str(out),
        ],
        cwd=str(tmp_path),
        dimensions=(50, 120),
        encoding="utf-8",
        timeout=90,
    )
    try:
        child.expect("mode +autonomous")
        child.send("l")
        child.expect(r"operator lock \(interactive\) accepted")
        child.expect("waiting for the operator")
        child.send("r")
        child.expect(r"operator resume \(interactive\) accepted")
        child.send("a")
        child.expect(r"operator abort \(interactive\)")
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    assert child.exitstatus == 1  # the run did not succeed: the operator aborted it
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "aborted"
    ops = [m.data for m in TraceReader(out / "trace.mcap").messages(["/operator"])]
    assert [(o["action"], o["source"]) for o in ops] == [
        ("lock", "interactive"),
        ("resume", "interactive"),
        ("abort", "interactive"),
    ]
    assert all(o["detail"].startswith("accepted") for o in ops)


def test_gui_keys_reach_the_automaton(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The window's keys, end to end, on a headless PyBullet client.

    Without a display no window opens, so PyBullet's keyboard query is replaced by a
    script of presses; everything after it (mapping, operator channel, automaton,
    trace) is the real path.
    """
    import pybullet as p

    presses = {2: "l", 4: "r", 6: "a"}  # query number -> key pressed since the last one
    calls = {"n": 0}

    def keyboard(physicsClientId: int = 0) -> dict[int, int]:
        calls["n"] += 1
        key = presses.get(calls["n"])
        return {ord(key): p.KEY_WAS_TRIGGERED} if key else {}

    monkeypatch.setattr(p, "getKeyboardEvents", keyboard)
    panel = LivePanel("steps", every=50, gui=True)
    result = run_procedure(
        PROCS / "steps.yaml", backend="pybullet", out=tmp_path / "run", on_tick=panel
    )
    assert result.summary.outcome == "aborted"
    ops = [m.data for m in TraceReader(result.trace).messages(["/operator"])]
    assert [(o["action"], o["source"]) for o in ops] == [
        ("lock", "gui"),
        ("resume", "gui"),
        ("abort", "gui"),
    ]
    assert calls["n"] >= 6
