"""Thesis-style figures of one run, drawn from its trace.

Every figure is built from the channel catalogue
(:mod:`suture_engine.trace.channels`); a channel that holds no message in the
trace gives an explicit "no data on <channel>" panel instead of an error, so the
figures work on any trace, whatever the skills of the run recorded.

Figures (PNG, matplotlib's Agg canvas, no pyplot state):

* ``force_tracking``: base force sensor [N] per robot, desired against measured
  (Figs. 7.21-7.29). No catalogue channel carries a desired force yet; the panel
  says so.
* ``joint_positions``: measured joint positions [rad, m] against the position
  commands (Fig. 6.11); torque-commanded runs have no desired positions.
* ``task_path``: the tool-tip path [mm] from the forward kinematics (3.12) of the
  measured joints, against the line constraints of the procedure's
  ``move-constrained`` states (Figs. 6.7, 6.13, 6.18).
* ``tension``: estimated and true suture tension [N] against the tension limit.
* ``timeline``: Gantt of the automaton's states with NOT-BE episodes, retries,
  unpredictable events and operator events.
* ``qp``: active constraints, iterations and solve time [us] of the per-tick QP.
* ``thread_states``: the simulator's thread (ground truth, backends with a thread) as
  each state left it, from above and from the side [mm], one pair of panels per state
  whose thread moved. For evaluation: what each step did to the thread.

Example:
    >>> data = load_trace("runs/demo/trace.mcap")
    >>> figures = render_figures(data)
    >>> write_figures(figures, "runs/demo/figures")
"""

from __future__ import annotations

import io
import json
import os
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from suture_engine.trace import channels

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from suture_engine.trace.reader import TraceStatus

__all__ = [
    "FIGURE_NAMES",
    "RenderedFigure",
    "TraceData",
    "load_trace",
    "render_figures",
    "write_figures",
]

FIGURE_NAMES: tuple[str, ...] = (
    "force_tracking",
    "joint_positions",
    "task_path",
    "tension",
    "timeline",
    "qp",
    "thread_states",
)
"""The figures :func:`render_figures` draws, in order."""

THREAD_STATES_MAX = 64
"""The most states ``thread_states`` draws (the first ones; the figure says how many it
left out)."""

_NOTBE = "~notbe"
_DPI = 100
_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#17becf")
_ROBOT_COLOURS = ("#2ca02c", "#9467bd", "#8c564b", "#17becf")
"""Each robot's own tension estimate (none red: red is the tension limit's line)."""


@dataclass(frozen=True)
class TraceData:
    """The messages of one trace, grouped by topic.

    Attributes:
        path: the trace file.
        meta: the ``/meta`` message (empty when absent).
        status: how far the trace could be read.
        series: per topic, the ``(t [s], message)`` pairs in time order (of
            ``/ground_truth/suture`` only the last, to bound memory).
        summary: the run's ``summary.json`` beside the trace, if any.
        thread_exits: ``(t [s], state, centerline)`` for each state left: the last
            ``/ground_truth/suture`` message before the transition (``t`` is that
            message's time), and the last one of the trace under the final state.
    """

    path: Path
    meta: Mapping[str, Any]
    status: TraceStatus
    series: Mapping[str, Sequence[tuple[float, Any]]]
    summary: Mapping[str, Any] | None
    thread_exits: Sequence[tuple[float, str, Any]] = ()

    @property
    def robots(self) -> list[str]:
        """Robot names: from ``/meta``, else from the per-robot topics."""
        names = self.meta.get("robots")
        if isinstance(names, list) and names:
            return [str(n) for n in names]
        found: list[str] = []
        for topic in self.series:
            parts = topic.split("/")
            if len(parts) == 3 and parts[1] in ("joint_state", "command", "base_wrench", "qp"):
                if parts[2] not in found:
                    found.append(parts[2])
        return found

    @property
    def duration_s(self) -> float:
        """The last readable simulation time [s] (0 for an empty trace)."""
        last = self.status.last_time_ns
        return last / 1e9 if last is not None else 0.0

    def get(self, topic: str) -> Sequence[tuple[float, Any]]:
        """The ``(t [s], message)`` pairs of ``topic`` (empty when it has none)."""
        return self.series.get(topic, ())


class RenderedFigure(NamedTuple):
    """One drawn figure.

    Attributes:
        name: file stem (``tension``).
        title: human title.
        png: the PNG image.
        missing: channels the figure wanted but found empty.
    """

    name: str
    title: str
    png: bytes
    missing: tuple[str, ...]


def load_trace(path: str | os.PathLike[str]) -> TraceData:
    """Read a trace (complete or truncated) and the ``summary.json`` beside it.

    Args:
        path: the trace file.

    Raises:
        TraceIOError, TraceForeignError, TraceCorruptError: see
            :class:`~suture_engine.trace.reader.TraceReader`.
    """
    from suture_engine.trace.reader import TraceReader

    reader = TraceReader(path)
    series: dict[str, list[tuple[float, Any]]] = {}
    meta: dict[str, Any] = {}
    exits: list[tuple[float, str, Any]] = []
    state = ""
    for msg in reader.messages():
        if msg.topic == channels.META and not meta and isinstance(msg.data, dict):
            meta = dict(msg.data)
        rows = series.setdefault(msg.topic, [])
        if msg.topic == channels.TRANSITIONS and isinstance(msg.data, dict):
            state = str(msg.data.get("dest", ""))
            centerline = series.get(channels.GROUND_TRUTH_SUTURE)
            if centerline:
                exits.append(
                    (centerline[-1][0], str(msg.data.get("source", "")), centerline[-1][1])
                )
        if msg.topic == channels.GROUND_TRUTH_SUTURE and rows:
            rows[-1] = (msg.log_time_ns / 1e9, msg.data)  # the latest centerline only
        else:
            rows.append((msg.log_time_ns / 1e9, msg.data))
    last = series.get(channels.GROUND_TRUTH_SUTURE)
    if last:
        exits.append((last[-1][0], state or "end", last[-1][1]))
    summary: dict[str, Any] | None = None
    summary_path = Path(path).with_name("summary.json")
    if summary_path.is_file():
        try:
            loaded = json.loads(summary_path.read_text(encoding="utf-8"))
            summary = loaded if isinstance(loaded, dict) else None
        except (OSError, ValueError):
            summary = None
    return TraceData(Path(path), meta, reader.status, series, summary, tuple(exits))


# -- helpers --------------------------------------------------------------------------------


def _new_figure(width: float, height: float) -> Figure:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _png(fig: Figure) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_DPI)
    return buf.getvalue()


def _no_data(ax: Axes, what: str) -> None:
    """An explicit empty panel."""
    ax.text(
        0.5,
        0.5,
        f"no data on {what}",
        ha="center",
        va="center",
        transform=ax.transAxes,
        fontsize=11,
        color="#777777",
    )
    ax.set_xticks([])
    ax.set_yticks([])


def _floats(values: Any) -> list[float]:
    """A JSON array as floats (``null`` -> NaN)."""
    if not isinstance(values, list):
        return []
    return [float("nan") if v is None else float(v) for v in values]


def _matrix(rows: Sequence[tuple[float, Any]], key: str) -> tuple[Any, Any]:
    """Times [s] and an (N, k) array of the array field ``key`` (rows of other widths dropped)."""
    import numpy as np

    pairs = [(t, _floats(m.get(key))) for t, m in rows if isinstance(m, dict)]
    pairs = [(t, v) for t, v in pairs if v]
    if not pairs:
        return np.zeros(0), np.zeros((0, 0))
    width = max(len(v) for _, v in pairs)
    pairs = [(t, v) for t, v in pairs if len(v) == width]
    return np.array([t for t, _ in pairs]), np.array([v for _, v in pairs], dtype=float)


def _scalar(rows: Sequence[tuple[float, Any]], key: str) -> tuple[Any, Any]:
    import numpy as np

    t = [tt for tt, m in rows if isinstance(m, dict) and isinstance(m.get(key), int | float)]
    v = [m[key] for _, m in rows if isinstance(m, dict) and isinstance(m.get(key), int | float)]
    return np.array(t, dtype=float), np.array(v, dtype=float)


def _robot_axes(fig: Figure, robots: Sequence[str], cols: int = 1) -> list[Any]:
    n = max(1, len(robots))
    axes = fig.subplots(n, cols, squeeze=False)
    return [list(row) for row in axes]


# -- figures --------------------------------------------------------------------------------


def _force_tracking(data: TraceData) -> RenderedFigure:
    import numpy as np

    robots = data.robots or ["(no robot)"]
    fig = _new_figure(9, 2.6 * len(robots))
    missing: list[str] = []
    for (ax,), robot in zip(_robot_axes(fig, robots), robots, strict=True):
        topic = channels.base_wrench_topic(robot) if data.robots else "/base_wrench/<robot>"
        t, f = _matrix(data.get(topic), "force")
        if t.size == 0 or f.shape[1] != 3:
            missing.append(topic)
            _no_data(ax, topic)
            ax.set_title(f"{robot}: force tracking")
            continue
        for k, axis in enumerate("xyz"):
            ax.plot(t, f[:, k], lw=1.0, color=_COLOURS[k], label=f"measured $F_{axis}$")
        ax.plot(t, np.linalg.norm(f, axis=1), lw=1.4, color="black", label="measured $|F|$")
        ax.text(
            0.99,
            0.97,
            "desired force: not recorded in this trace",
            ha="right",
            va="top",
            transform=ax.transAxes,
            fontsize=8,
            color="#777777",
        )
        ax.set_title(f"{robot}: base force sensor, desired vs measured")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("force [N]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=8, ncol=4)
    return RenderedFigure(
        "force_tracking", "Force tracking (Figs. 7.21-7.29)", _png(fig), tuple(missing)
    )


def _joint_positions(data: TraceData) -> RenderedFigure:
    robots = data.robots or ["(no robot)"]
    fig = _new_figure(9, 2.8 * len(robots))
    missing: list[str] = []
    for (ax,), robot in zip(_robot_axes(fig, robots), robots, strict=True):
        topic = channels.joint_state_topic(robot) if data.robots else "/joint_state/<robot>"
        t, q = _matrix(data.get(topic), "position")
        ax.set_title(f"{robot}: joint positions, desired vs measured")
        if t.size == 0:
            missing.append(topic)
            _no_data(ax, topic)
            continue
        cmd_topic = channels.command_topic(robot)
        desired = [(tt, m) for tt, m in data.get(cmd_topic) if m.get("kind") == "position"]
        td, qd = _matrix(desired, "values")
        for j in range(q.shape[1]):
            colour = _COLOURS[j % len(_COLOURS)]
            ax.plot(t, q[:, j], lw=1.2, color=colour, label=f"$q_{j + 1}$ measured")
            if td.size and qd.shape[1] == q.shape[1]:
                ax.plot(td, qd[:, j], lw=1.0, ls="--", color=colour, label=f"$q_{j + 1}$ desired")
        if not td.size:
            ax.text(
                0.99,
                0.97,
                f"no position commands on {cmd_topic}: desired not recorded",
                ha="right",
                va="top",
                transform=ax.transAxes,
                fontsize=8,
                color="#777777",
            )
        ax.set_xlabel("t [s]")
        ax.set_ylabel("q [rad] (insertion [m])")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=7, ncol=4)
    return RenderedFigure(
        "joint_positions", "Joint positions (Fig. 6.11)", _png(fig), tuple(missing)
    )


def _line_constraints(data: TraceData) -> list[tuple[str, Any, Any]]:
    """``(robot, point [m], unit direction)`` of the procedure's line fixtures.

    Read from the procedure file named in ``/meta``; an unreadable or changed file
    gives no constraint (the figure then says so).
    """
    import numpy as np

    name = data.meta.get("procedure_file")
    if not isinstance(name, str) or not Path(name).is_file():
        return []
    try:
        import yaml

        from suture_engine.language.units import parse_quantity

        doc = yaml.safe_load(Path(name).read_text(encoding="utf-8"))
        found = []
        for state in (doc.get("states") or {}).values():
            if not isinstance(state, dict) or state.get("skill") != "move-constrained":
                continue
            args = state.get("with") or {}
            if args.get("fixture") != "line":
                continue
            point = np.array(
                [
                    float(v) if isinstance(v, int | float) else parse_quantity(str(v)).value
                    for v in args["point"]
                ]
            )
            direction = np.array([float(v) for v in args["direction"]])
            direction = direction / np.linalg.norm(direction)
            role = str(args.get("robot", ""))
            found.append((str((doc.get("roles") or {}).get(role, role)), point, direction))
        return found
    except Exception:  # a procedure this figure cannot read: draw no constraint
        return []


def _task_path(data: TraceData) -> RenderedFigure:
    import numpy as np

    from suture_engine.robot.kinematics import forward_kinematics

    robots = data.robots or ["(no robot)"]
    fig = _new_figure(9, 3.6 * len(robots))
    missing: list[str] = []
    all_lines = _line_constraints(data)
    for row, robot in zip(_robot_axes(fig, robots, cols=2), robots, strict=True):
        topic = channels.joint_state_topic(robot) if data.robots else "/joint_state/<robot>"
        _, q = _matrix(data.get(topic), "position")
        if q.shape[0] == 0 or q.shape[1] != 4:
            if q.shape[0] == 0:
                missing.append(topic)
            what = topic if q.shape[0] == 0 else f"{topic} as the EndoBot's 4 joints"
            for ax in row:
                _no_data(ax, what)
                ax.set_title(f"{robot}: tool-tip path")
            continue
        p = np.array([forward_kinematics(qq).position for qq in q]) * 1e3
        lines = [line for line in all_lines if line[0] == robot]
        span = float(np.max(np.ptp(p, axis=0))) if p.shape[0] > 1 else 0.0
        half = max(span, 10.0)
        for ax, (i, j, label) in zip(row, ((0, 2, "x-z"), (1, 2, "y-z")), strict=True):
            ax.plot(p[:, i], p[:, j], lw=1.4, color=_COLOURS[0], label="tool tip")
            ax.plot(p[0, i], p[0, j], "o", color=_COLOURS[2], label="start")
            ax.plot(p[-1, i], p[-1, j], "s", color=_COLOURS[3], label="end")
            for _robot, point, direction in lines:
                a = point * 1e3 - direction * half
                b = point * 1e3 + direction * half * 10
                ax.plot([a[i], b[i]], [a[j], b[j]], "k--", lw=1.0, label="line constraint")
            if not lines:
                ax.text(
                    0.01,
                    0.01,
                    f"no line constraint on {robot} in the procedure",
                    transform=ax.transAxes,
                    fontsize=8,
                    color="#777777",
                )
            ax.set_title(f"{robot}: tool-tip path ({label}, base frame)")
            ax.set_xlabel(f"{'xyz'[i]} [mm]")
            ax.set_ylabel(f"{'xyz'[j]} [mm]")
            ax.set_xlim(p[:, i].min() - half * 0.2, p[:, i].max() + half * 0.2)
            ax.set_ylim(p[:, j].min() - half * 0.2, p[:, j].max() + half * 0.2)
            ax.grid(True, alpha=0.3)
            ax.legend(loc="upper right", fontsize=7)
    return RenderedFigure(
        "task_path", "Task-space path (Figs. 6.7, 6.13, 6.18)", _png(fig), tuple(missing)
    )


def _per_robot_estimates(rows: Sequence[tuple[float, Any]]) -> dict[str, tuple[Any, Any]]:
    """Each robot's own estimate over time, from the ``estimates`` of ``/tension/estimated``
    (empty for traces written before the field)."""
    import numpy as np

    series: dict[str, tuple[list[float], list[float]]] = {}
    for t, m in rows:
        each = m.get("estimates") if isinstance(m, dict) else None
        for e in each if isinstance(each, list) else ():
            if isinstance(e, dict) and isinstance(e.get("tension_N"), int | float):
                ts, vs = series.setdefault(str(e.get("robot")), ([], []))
                ts.append(t)
                vs.append(e["tension_N"])
    return {
        r: (np.array(ts, dtype=float), np.array(vs, dtype=float)) for r, (ts, vs) in series.items()
    }


def _tension(data: TraceData) -> RenderedFigure:
    fig = _new_figure(9, 3.2)
    ax = fig.subplots()
    missing: list[str] = []
    drawn = False
    rows = data.get(channels.TENSION_ESTIMATED)
    each = _per_robot_estimates(rows)
    for i, (robot, (t, v)) in enumerate(sorted(each.items())):
        colour = _ROBOT_COLOURS[i % len(_ROBOT_COLOURS)]
        ax.plot(t, v, lw=0.9, color=colour, label=f"estimated, {robot}")
        drawn = True
    for topic, label, colour in (
        (channels.TENSION_ESTIMATED, "estimated", _COLOURS[0]),
        (channels.GROUND_TRUTH_TENSION, "true (simulator)", _COLOURS[1]),
    ):
        if topic == channels.TENSION_ESTIMATED and each:
            continue  # drawn per robot (the larger of them is this series)
        t, v = _scalar(data.get(topic), "tension_N")
        if t.size == 0:
            missing.append(topic)
            continue
        ax.plot(t, v, lw=1.2, color=colour, label=label)
        drawn = True
    limit = (data.summary or {}).get("tension_limit_N")
    ax.set_title("Suture tension against the tension limit")
    if not drawn:
        _no_data(ax, " and ".join(missing))
    else:
        if isinstance(limit, int | float):
            ax.axhline(float(limit), color="red", ls="--", lw=1.2, label=f"limit {limit:.3g} N")
        else:
            ax.text(
                0.99,
                0.97,
                "no tension limit (no summary.json or none set)",
                ha="right",
                va="top",
                transform=ax.transAxes,
                fontsize=8,
                color="#777777",
            )
        ax.set_xlabel("t [s]")
        ax.set_ylabel("tension [N]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    return RenderedFigure("tension", "Tension", _png(fig), tuple(missing))


def _state_colour(state: str) -> str:
    if state.endswith(_NOTBE):
        return "#d62728"
    if state in ("lock", "manual"):
        return "#ff7f0e"
    if state in ("aborted", "failed"):
        return "#7f7f7f"
    return "#1f77b4"


def _timeline(data: TraceData) -> RenderedFigure:
    transitions = [(t, m) for t, m in data.get(channels.TRANSITIONS) if isinstance(m, dict)]
    events = [(t, m) for t, m in data.get(channels.EVENTS) if isinstance(m, dict)]
    operator = [(t, m) for t, m in data.get(channels.OPERATOR) if isinstance(m, dict)]
    missing = [
        topic
        for topic, rows in (
            (channels.TRANSITIONS, transitions),
            (channels.EVENTS, events),
            (channels.OPERATOR, operator),
        )
        if not rows
    ]
    states: list[str] = []
    for _, m in transitions:
        for s in (str(m.get("source")), str(m.get("dest"))):
            if s not in states:
                states.append(s)
    lanes = [*states, "events", "operator"]
    fig = _new_figure(9, 1.2 + 0.32 * len(lanes))
    ax = fig.subplots()
    ax.set_title("State timeline: states, NOT-BE episodes, retries, events, operator")
    if not transitions:
        _no_data(ax, channels.TRANSITIONS)
        return RenderedFigure("timeline", "State timeline", _png(fig), tuple(missing))
    end = max(data.duration_s, transitions[-1][0])
    y = {name: i for i, name in enumerate(lanes)}
    spans = [(transitions[0][0], str(transitions[0][1].get("source")))]
    spans += [(t, str(m.get("dest"))) for t, m in transitions]
    for k, (t0, state) in enumerate(spans):
        t1 = spans[k + 1][0] if k + 1 < len(spans) else end
        width = max(t1 - t0, end * 2e-3)
        ax.broken_barh([(t0, width)], (y[state] - 0.35, 0.7), color=_state_colour(state))
    retries = [t for t, m in transitions if m.get("trigger") == "retry"]
    for t in retries:
        ax.axvline(t, color="#9467bd", ls=":", lw=1.0)
    if retries:
        ax.plot([], [], color="#9467bd", ls=":", label=f"retry ({len(retries)})")
    for kind, marker, colour in (
        ("planned", "|", "#2ca02c"),
        ("unpredictable", "x", "#d62728"),
        ("info", ".", "#7f7f7f"),
        ("operator", "^", "#9467bd"),
    ):
        ts = [t for t, m in events if m.get("kind") == kind]
        if ts:
            ax.plot(ts, [y["events"]] * len(ts), marker, color=colour, ms=8, ls="", label=kind)
    if operator:
        ts = [t for t, _ in operator]
        ax.plot(ts, [y["operator"]] * len(ts), "v", color="black", ms=8, ls="", label="operator")
        for t, m in operator:
            ax.annotate(
                str(m.get("action", "")),
                (t, y["operator"]),
                fontsize=7,
                xytext=(3, 4),
                textcoords="offset points",
            )
    else:
        ax.text(
            0.0, y["operator"], "  no data on /operator", va="center", fontsize=8, color="#777777"
        )
    if not events:
        ax.text(0.0, y["events"], "  no data on /events", va="center", fontsize=8, color="#777777")
    ax.set_yticks(range(len(lanes)), lanes, fontsize=8)
    ax.set_ylim(-0.6, len(lanes) - 0.4)
    ax.invert_yaxis()
    ax.set_xlim(0.0, end * 1.02 if end > 0 else 1.0)
    ax.set_xlabel("t [s]")
    ax.grid(True, axis="x", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="lower right", fontsize=7, ncol=5)
    return RenderedFigure("timeline", "State timeline", _png(fig), tuple(missing))


def _qp(data: TraceData) -> RenderedFigure:
    import numpy as np

    robots = data.robots or ["(no robot)"]
    fig = _new_figure(9, 2.6 * len(robots))
    missing: list[str] = []
    for (ax, ax_time), robot in zip(_robot_axes(fig, robots, cols=2), robots, strict=True):
        topic = channels.qp_topic(robot) if data.robots else "/qp/<robot>"
        rows = [(t, m) for t, m in data.get(topic) if isinstance(m, dict)]
        ax.set_title(f"{robot}: QP active constraints")
        ax_time.set_title(f"{robot}: QP solve time")
        if not rows:
            missing.append(topic)
            _no_data(ax, topic)
            _no_data(ax_time, topic)
            continue
        t = np.array([tt for tt, _ in rows])
        active = np.array([len(m.get("active_constraints") or []) for _, m in rows])
        ax.step(t, active, where="post", color=_COLOURS[0], label="active constraints")
        _, iters = _scalar(rows, "iterations")
        if iters.size == t.size:
            ax.plot(t, iters, lw=0.8, color=_COLOURS[1], alpha=0.7, label="iterations")
        unsolved = [tt for tt, m in rows if m.get("status") not in ("solved", None)]
        if unsolved:
            ax.plot(unsolved, [0] * len(unsolved), "x", color="red", label="not solved")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("count")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=7)
        ts, us = _scalar(rows, "solve_time_us")
        if ts.size == 0:
            _no_data(ax_time, f"{topic} solve_time_us (wall clock, dropped by default)")
        else:
            ax_time.plot(ts, us, lw=0.8, color=_COLOURS[2])
            ax_time.set_xlabel("t [s]")
            ax_time.set_ylabel("solve time [us]")
            ax_time.grid(True, alpha=0.3)
    return RenderedFigure("qp", "QP active constraints and solve time", _png(fig), tuple(missing))


def _centerline_mm(message: Any) -> Any:
    """A ``/ground_truth/suture`` message as an (N, 3) array [mm] (None when malformed)."""
    import numpy as np

    if not isinstance(message, dict):
        return None
    xyz = [_floats(message.get(k)) for k in ("x", "y", "z")]
    if not xyz[0] or any(len(c) != len(xyz[0]) for c in xyz):
        return None
    return np.array(xyz, dtype=float).T * 1e3


def _thread_states(data: TraceData) -> RenderedFigure:
    import numpy as np

    title = "Thread as each state left it (ground truth)"
    shots: list[tuple[float, str, Any]] = []
    for t, state, message in data.thread_exits:
        points = _centerline_mm(message)
        if points is None:
            continue
        if shots and shots[-1][0] == t:  # the same centerline: the state took no time
            shots[-1] = (t, f"{shots[-1][1]}, {state.split('/')[-1]}", points)
            continue
        shots.append((t, state.split("/")[-1], points))
    if not shots:
        fig = _new_figure(9, 3)
        _no_data(fig.subplots(), channels.GROUND_TRUTH_SUTURE)
        return RenderedFigure("thread_states", title, _png(fig), (channels.GROUND_TRUTH_SUTURE,))
    left_out = max(0, len(shots) - THREAD_STATES_MAX)
    shots = shots[:THREAD_STATES_MAX]
    every = np.vstack([p for _, _, p in shots])
    lo, hi = np.nanmin(every, axis=0), np.nanmax(every, axis=0)
    pad = 0.05 * float(np.nanmax(hi - lo)) + 1.0
    per_row = 4
    rows = -(-len(shots) // per_row)
    fig = _new_figure(2.6 * per_row * 2 / 1.6, 0.6 + 2.3 * rows)
    axes = fig.subplots(rows, 2 * per_row, squeeze=False)
    suffix = f" (the first {THREAD_STATES_MAX}; {left_out} more not drawn)" if left_out else ""
    fig.suptitle(
        f"{title}{suffix}: from above (x-y) and from the side (x-z) [mm]; "
        "square: the tail end, triangle: the needle end, dashed: the tissue surface",
        fontsize=9,
    )
    for k, ax in enumerate(axes.flat):
        if k // 2 >= len(shots):
            ax.set_axis_off()
            continue
        t, label, points = shots[k // 2]
        a, b = (0, 1) if k % 2 == 0 else (0, 2)
        ax.plot(points[:, a], points[:, b], "-", color=_COLOURS[0], lw=1.0)
        ax.plot(points[0, a], points[0, b], "s", color=_COLOURS[2], ms=4)
        ax.plot(points[-1, a], points[-1, b], "^", color=_COLOURS[3], ms=4)
        if b == 2:
            ax.axhline(0.0, color="#777777", ls="--", lw=0.8)
        ax.set_xlim(lo[a] - pad, hi[a] + pad)
        ax.set_ylim(lo[b] - pad, hi[b] + pad)
        ax.set_aspect("equal", adjustable="box")
        ax.tick_params(labelsize=6)
        view = "x-y" if b == 1 else "x-z"
        ax.set_title(f"{label[:32]}\n{t:.1f} s, {view}", fontsize=7)
    return RenderedFigure("thread_states", title, _png(fig), ())


_DRAW = {
    "force_tracking": _force_tracking,
    "joint_positions": _joint_positions,
    "task_path": _task_path,
    "tension": _tension,
    "timeline": _timeline,
    "qp": _qp,
    "thread_states": _thread_states,
}


def render_figures(data: TraceData, names: Sequence[str] = FIGURE_NAMES) -> list[RenderedFigure]:
    """Draw the figures of a run in memory.

    Args:
        data: the trace, from :func:`load_trace`.
        names: which figures (default all of :data:`FIGURE_NAMES`).

    Raises:
        ValueError: an unknown figure name.
    """
    unknown = [n for n in names if n not in _DRAW]
    if unknown:
        raise ValueError(f"unknown figure(s) {unknown}; known: {', '.join(FIGURE_NAMES)}")
    return [_DRAW[name](data) for name in names]


def write_figures(figures: Sequence[RenderedFigure], out_dir: str | os.PathLike[str]) -> list[Path]:
    """Write ``<name>.png`` files into ``out_dir``, each atomically (temp file + rename).

    Returns:
        The paths written.
    """
    target = Path(out_dir)
    target.mkdir(parents=True, exist_ok=True)
    written = []
    for fig in figures:
        path = target / f"{fig.name}.png"
        fd, tmp = tempfile.mkstemp(prefix=f".{fig.name}-", suffix=".png", dir=target)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(fig.png)
            os.chmod(tmp, 0o644)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        written.append(path)
    return written
