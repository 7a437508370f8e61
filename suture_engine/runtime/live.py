"""Live supervision for ``suture run --interactive``: a terminal panel and the GUI's keys.

The supervisory automaton lets the surgeon lock, take over, resume or abort at any
moment (thesis 4.6, Figs. 4.22-4.25). This module shows what the surgeon needs to
decide, and takes the keys:

- :class:`LivePanel` is a per-tick hook (``run_procedure(on_tick=...)``) that keeps a
  :class:`PanelSnapshot` (automaton state and step, the mode of each robot, the
  estimated tension against the limit, sim time and real-time factor, the last
  events) and shows it in a ``rich`` live panel with the keys
  (l lock, m manual, r resume, a abort).
- With ``--gui`` the same keys work in the PyBullet window
  (``getKeyboardEvents``, mapped by :func:`gui_key_actions`), and the state and
  mode are drawn as debug text in the 3-D view.

On its first tick the panel wraps the interpreter's operator source
(:class:`TappedOperator`, which adds the GUI keys) and its recorder
(:class:`TappedRecorder`, which lists transitions, events and operator events as the
trace records them).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from suture_engine.runtime.operator import InteractiveOperator, OperatorEvent

__all__ = [
    "KEY_WAS_TRIGGERED",
    "LivePanel",
    "PanelSnapshot",
    "TappedOperator",
    "TappedRecorder",
    "gui_key_actions",
    "render_panel",
    "tension_bar",
]

KEY_WAS_TRIGGERED = 2
"""PyBullet's flag of a key pressed since the last query (``p.KEY_WAS_TRIGGERED``)."""

KEYS_HELP = "l lock   m manual   r resume   a abort"


def gui_key_actions(events: Mapping[int, int]) -> list[str]:
    """Operator actions of a PyBullet ``getKeyboardEvents()`` result.

    Args:
        events: key code -> state flags, as ``p.getKeyboardEvents`` returns them.

    Returns:
        The actions (``lock``, ``manual``, ``resume``, ``abort``) of the keys pressed
        since the last query, in key-code order; held or released keys give nothing.
    """
    out: list[str] = []
    for code in sorted(events):
        if not events[code] & KEY_WAS_TRIGGERED or not 0 <= code < 0x110000:
            continue
        action = InteractiveOperator.KEYS.get(chr(code).lower())
        if action is not None:
            out.append(action)
    return out


def tension_bar(tension_N: float, limit_N: float | None, width: int = 30) -> str:
    """A text bar of the tension against the limit: ``[#####.....] 1.20/3.00 N``.

    Args:
        tension_N: the estimated tension [N].
        limit_N: the tension limit [N] (None: no limit, the bar shows the value only).
        width: characters inside the brackets.
    """
    if limit_N is None or limit_N <= 0.0:
        return f"{tension_N:.2f} N (no limit)"
    frac = min(max(tension_N / limit_N, 0.0), 1.0)
    filled = round(frac * width)
    return f"[{'#' * filled}{'.' * (width - filled)}] {tension_N:.2f}/{limit_N:.2f} N"


@dataclass(frozen=True)
class PanelSnapshot:
    """What the panel shows.

    Attributes:
        procedure: the procedure's name.
        state: the automaton state (a step, its NOT-BE state, or a terminal).
        step: the running or interrupted step (None when none).
        mode: the automaton's high-level mode (lock, manual, autonomous, ...).
        robot_modes: robot -> its mode (the operator may hold one robot alone).
        tension_N: robot -> estimated tension [N].
        tension_limit_N: the scene's tension limit [N] (None: none).
        sim_time_s: simulated time [s].
        real_time_factor: sim time over wall time since the panel started.
        events: the last events, oldest first ("12.300 s  tighten -> NOT-BE(tighten)").
        waiting: the automaton waits for the operator.
    """

    procedure: str = ""
    state: str = ""
    step: str | None = None
    mode: str = ""
    robot_modes: Mapping[str, str] = field(default_factory=dict)
    tension_N: Mapping[str, float] = field(default_factory=dict)
    tension_limit_N: float | None = None
    sim_time_s: float = 0.0
    real_time_factor: float = 0.0
    events: tuple[str, ...] = ()
    waiting: bool = False


def render_panel(snap: PanelSnapshot) -> Any:
    """The ``rich`` renderable of a snapshot (a bordered panel with a table)."""
    from rich.panel import Panel
    from rich.table import Table
    from rich.text import Text

    table = Table.grid(padding=(0, 2))
    table.add_column(style="bold")
    table.add_column()
    state = snap.state + ("  (waiting for the operator)" if snap.waiting else "")
    table.add_row("state", state)
    table.add_row("step", snap.step or "-")
    table.add_row("mode", snap.mode)
    for robot, mode in snap.robot_modes.items():
        table.add_row(f"  {robot}", f"mode {mode}")
    for robot, value in snap.tension_N.items():
        colour = "green"
        if snap.tension_limit_N and value > 0.8 * snap.tension_limit_N:
            colour = "red" if value > snap.tension_limit_N else "yellow"
        table.add_row(
            f"tension {robot}", Text(tension_bar(value, snap.tension_limit_N), style=colour)
        )
    table.add_row("sim time", f"{snap.sim_time_s:.2f} s")
    table.add_row("real-time factor", f"{snap.real_time_factor:.2f}")
    table.add_row("events", Text("\n".join(snap.events) or "-"))
    table.add_row("keys", KEYS_HELP)
    return Panel(table, title=f"suture run: {snap.procedure}", expand=False)


class TappedOperator:
    """An operator source that also hands over GUI keys and remembers what it gave.

    Args:
        inner: the wrapped source (the terminal's :class:`InteractiveOperator`), or None.
        gui: the simulator's window takes keys (so more events may always come).
    """

    def __init__(self, inner: Any, gui: bool = False) -> None:
        self.inner = inner
        self.gui = gui
        self.pending: list[OperatorEvent] = []
        self.handed: list[tuple[float, OperatorEvent]] = []
        """(sim time [s], event) of every event handed to the interpreter."""

    def push_gui(self, actions: list[str]) -> None:
        """Queue actions read from the PyBullet window."""
        self.pending.extend(OperatorEvent(a, source="gui") for a in actions)

    def poll(self, t: float, state: str, step: str | None, mode: str) -> list[OperatorEvent]:
        """The inner source's events of this tick, then the queued GUI keys."""
        out = list(self.inner.poll(t, state, step, mode)) if self.inner is not None else []
        out.extend(self.pending)
        self.pending = []
        self.handed.extend((t, ev) for ev in out)
        return out

    @property
    def exhausted(self) -> bool | None:
        """Whether no more events can come (None: a keyboard, it can always send more)."""
        if self.gui:
            return None
        if self.inner is None:
            return not self.pending
        return getattr(self.inner, "exhausted", None)


class TappedRecorder:
    """A recorder proxy: everything goes to the wrapped recorder; transitions, events and
    operator events are also listed, one line each, for the panel.

    Args:
        inner: the run's recorder.
        lines: where the lines go (``(time [s], text)``).
    """

    def __init__(self, inner: Any, lines: deque[str]) -> None:
        self.inner = inner
        self.lines = lines

    def transition(self, time_ns: int, record: Any) -> None:
        """Forward, and list ``source -> dest (event)``."""
        self.inner.transition(time_ns, record)
        why = f": {record.reason}" if record.reason else ""
        self.lines.append(f"{time_ns * 1e-9:8.3f} s  {record.source} -> {record.dest}{why}")

    def event(
        self,
        time_ns: int,
        name: str,
        kind: str,
        state: str,
        detail: str,
        robot: str | None = None,
    ) -> None:
        """Forward, and list the event."""
        self.inner.event(time_ns, name, kind, state, detail, robot)
        self.lines.append(f"{time_ns * 1e-9:8.3f} s  {kind} {name} in {state}: {detail}")

    def operator(self, time_ns: int, event: OperatorEvent, accepted: bool, detail: str) -> None:
        """Forward, and list the operator event and whether it was accepted."""
        self.inner.operator(time_ns, event, accepted, detail)
        verdict = "accepted" if accepted else f"refused: {detail}"
        self.lines.append(
            f"{time_ns * 1e-9:8.3f} s  operator {event.action} ({event.source}) {verdict}"
        )

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


class LivePanel:
    """The per-tick hook behind ``--interactive``: snapshot, panel, GUI keys.

    Args:
        procedure: the procedure's name (the panel's title).
        console: the ``rich`` console to draw on (None: standard output).
        every: ticks between snapshots (the tick loop stays cheap).
        max_events: events listed.
        gui: poll the PyBullet window's keys and draw debug text.
    """

    def __init__(
        self,
        procedure: str,
        *,
        console: Any = None,
        every: int = 50,
        max_events: int = 6,
        gui: bool = False,
    ) -> None:
        self.procedure = procedure
        self.console = console
        self.every = max(1, int(every))
        self.gui = gui
        self.snapshot = PanelSnapshot(procedure=procedure)
        self.events: deque[str] = deque(maxlen=max_events)
        self.tap: TappedOperator | None = None
        self._wall0: float | None = None
        self._live: Any = None
        self._text_id = -1

    # ------------------------------------------------------------- the hook
    def __call__(self, interp: Any) -> None:
        """Called after every tick with the interpreter."""
        t = interp.tick_index * interp.dt
        a = interp.automaton
        if self.tap is None:  # first tick: tap the operator source and the recorder
            self.tap = TappedOperator(interp.operator_source, gui=self.gui)
            interp.operator_source = self.tap
            interp.recorder = TappedRecorder(interp.recorder, self.events)
            self.events.append(f"{t:8.3f} s  started in {a.state}")
            self._wall0 = time.perf_counter()
        if interp.tick_index % self.every and not a.finished:
            return
        self.snapshot = self._snap(interp, t)
        if self.gui:
            self._gui(interp)

    def _snap(self, interp: Any, t: float) -> PanelSnapshot:
        a = interp.automaton
        held = getattr(interp, "robot_modes", {})
        modes = {r: held.get(r, a.mode_of(r)).value for r in interp.robots}
        wall = time.perf_counter() - (self._wall0 or time.perf_counter())
        tension = getattr(interp, "_tension", {}) or {}
        return PanelSnapshot(
            procedure=self.procedure,
            state=a.state,
            step=a.step_name,
            mode=a.mode.value,
            robot_modes=modes,
            tension_N={k: float(v) for k, v in tension.items()},
            tension_limit_N=interp.tension_limit_N,
            sim_time_s=t,
            real_time_factor=t / wall if wall > 0 else 0.0,
            events=tuple(self.events),
            waiting=bool(a.waiting_for_operator) and not a.finished,
        )

    def _gui(self, interp: Any) -> None:
        """Read the PyBullet window's keys; show state and mode as debug text."""
        client = getattr(interp.backend, "client", None)
        if not isinstance(client, int) or self.tap is None:
            return
        import pybullet as p

        self.tap.push_gui(gui_key_actions(p.getKeyboardEvents(physicsClientId=client)))
        snap = self.snapshot
        text = f"{snap.state}  [{snap.mode}]  t={snap.sim_time_s:.1f} s   {KEYS_HELP}"
        kwargs: dict[str, Any] = {"physicsClientId": client}
        if self._text_id >= 0:
            kwargs["replaceItemUniqueId"] = self._text_id
        self._text_id = p.addUserDebugText(
            text, [0.0, -0.06, 0.08], textColorRGB=[1, 1, 0], textSize=1.2, **kwargs
        )

    # ------------------------------------------------------------- the panel
    def __rich__(self) -> Any:
        return render_panel(self.snapshot)

    def start(self) -> None:
        """Start drawing (4 refreshes a second, in a thread of ``rich``)."""
        from rich.console import Console
        from rich.live import Live

        self._live = Live(
            self,
            console=self.console or Console(),
            refresh_per_second=4,
            auto_refresh=True,
            transient=False,
        )
        self._live.start()

    def stop(self) -> None:
        """Draw the last snapshot and stop."""
        if self._live is not None:
            self._live.refresh()
            self._live.stop()
            self._live = None
