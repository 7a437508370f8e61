"""The catalogue of trace channels, each with its JSON schema.

A trace is one MCAP file per run. Every message is JSON (``message_encoding
"json"``) on a channel whose schema is a JSON Schema (``schema encoding
"jsonschema"``), so Foxglove opens the file as it is. The MCAP log time of
every message is the **simulation** time in nanoseconds; no channel carries
wall-clock data unless the writer is explicitly asked to (see
``wall_clock_fields``), so the same seed gives a byte-identical file.

Channels (``<robot>`` is a robot name such as ``left`` or ``right``):

========================== ============================================================
``/meta``                  once, at t = 0: procedure, seed, params, control rate [Hz],
                           engine version, robot names
``/events``                planned and unpredictable events (name, kind, state, robot)
``/transitions``           state changes of the supervisory automaton (source, dest)
``/operator``              operator actions: lock, manual, resume, abort, force, ...
``/joint_state/<robot>``   joint positions [rad] and estimated velocities [rad/s]
``/command/<robot>``       the command applied: kind (torque, velocity, position), values
``/base_wrench/<robot>``   base force/torque sensor: force [N], torque [N*m]
``/tool_state/<robot>``    measured tool joints when they change: the bent-tip grasper's
                           universal joint angles ``bend`` [rad] (none while straight)
``/hook_load/<robot>``     the flexible hook's actuator load along its stroke [N], when it
                           changes (none while the hook is unloaded)
``/tension/estimated``     suture tension estimated from the measurements [N]: per tick
                           the larger of the robots' estimates, with that robot's name,
                           and every robot's own estimate (``estimates``)
``/qp/<robot>``            move-constrained QP: status, iterations, active constraints
                           (solve time [us] is wall-clock data: dropped by default)
``/ground_truth/suture``   simulator's suture centerline as x, y, z arrays [m], at a lower
                           rate (writers may give ``centerline: [[x, y, z], ...]``)
``/ground_truth/tension``  simulator's true suture tension [N] (the thread's largest
                           joint tension) and the joint it acts at (``joint``, a
                           point of the centerline)
``/ground_truth/knot``     knot classification of the simulated suture
========================== ============================================================

Ground-truth channels are for evaluation only: skills never see them.

Each field of a schema has a single JSON type and arrays hold scalars or objects,
the subset Foxglove's JSON-schema parser accepts; any value may still be ``null``
(a non-finite number, or an optional field left empty), which
:func:`validation_schema` spells out for validators. The run metadata is also
written as an MCAP metadata record named ``suture_engine``.

Example:
    >>> spec_for("/joint_state/left").schema_name
    'suture_engine.JointState'
    >>> joint_state_topic("right")
    '/joint_state/right'
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from suture_engine.trace.errors import UnknownChannelError

__all__ = [
    "CATALOGUE",
    "EVENTS",
    "GROUND_TRUTH_KNOT",
    "GROUND_TRUTH_SUTURE",
    "GROUND_TRUTH_SUTURE_CUT",
    "GROUND_TRUTH_TENSION",
    "META",
    "OPERATOR",
    "ROBOT_NAME_PATTERN",
    "TENSION_ESTIMATED",
    "TRANSITIONS",
    "ChannelSpec",
    "base_wrench_topic",
    "command_topic",
    "hook_load_topic",
    "joint_state_topic",
    "qp_topic",
    "schema_bytes",
    "spec_for",
    "tool_state_topic",
    "validation_schema",
]

ROBOT_NAME_PATTERN = r"[A-Za-z0-9_\-]+"
"""Robot names allowed in a per-robot topic."""

META = "/meta"
EVENTS = "/events"
TRANSITIONS = "/transitions"
OPERATOR = "/operator"
TENSION_ESTIMATED = "/tension/estimated"
GROUND_TRUTH_SUTURE = "/ground_truth/suture"
GROUND_TRUTH_SUTURE_CUT = "/ground_truth/suture_cut"
GROUND_TRUTH_TENSION = "/ground_truth/tension"
GROUND_TRUTH_KNOT = "/ground_truth/knot"

_ROBOT = "<robot>"


@dataclass(frozen=True)
class ChannelSpec:
    """One channel of the catalogue.

    Attributes:
        pattern: the topic, with ``<robot>`` standing for a robot name.
        schema_name: the MCAP schema name (``suture_engine.JointState``).
        schema: the JSON Schema of the messages.
        description: what the channel records, with units.
        ground_truth: True for simulator ground truth (evaluation only).
        wall_clock_fields: top-level fields that hold wall-clock measurements; the
            writer drops them unless asked to keep them, to stay deterministic.
        adapt: converts a message from the form writers give to the stored form.
    """

    pattern: str
    schema_name: str
    schema: Mapping[str, Any]
    description: str
    ground_truth: bool = False
    wall_clock_fields: tuple[str, ...] = ()
    adapt: Callable[[Mapping[str, Any]], Mapping[str, Any]] | None = field(
        default=None, repr=False, compare=False
    )
    _regex: re.Pattern[str] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        parts = [re.escape(p) for p in self.pattern.split(_ROBOT)]
        regex = re.compile("^" + f"({ROBOT_NAME_PATTERN})".join(parts) + "$")
        object.__setattr__(self, "_regex", regex)

    @property
    def per_robot(self) -> bool:
        """True when the topic contains a robot name."""
        return _ROBOT in self.pattern

    def matches(self, topic: str) -> bool:
        """Whether ``topic`` is an instance of this channel."""
        return self._regex.match(topic) is not None

    def topic(self, robot: str | None = None) -> str:
        """The concrete topic, for ``robot`` when the channel is per robot.

        Raises:
            ValueError: a robot name is missing, superfluous or malformed.
        """
        if not self.per_robot:
            if robot is not None:
                raise ValueError(f"{self.pattern} is not a per-robot channel")
            return self.pattern
        if robot is None or re.fullmatch(ROBOT_NAME_PATTERN, robot) is None:
            raise ValueError(f"{self.pattern} needs a robot name matching {ROBOT_NAME_PATTERN}")
        return self.pattern.replace(_ROBOT, robot)


def _vec(description: str, n: int | None = None) -> dict[str, Any]:
    """A JSON Schema array of numbers (a ``null`` item stands for a non-finite value)."""
    schema: dict[str, Any] = {
        "type": "array",
        "items": {"type": "number"},
        "description": description,
    }
    if n is not None:
        schema["minItems"] = n
        schema["maxItems"] = n
    return schema


def _obj(
    title: str, properties: dict[str, Any], required: list[str], extra: bool = False
) -> dict[str, Any]:
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "type": "object",
        "properties": properties,
        "required": required,
        "additionalProperties": extra,
    }


# Every field has one JSON type, so that Foxglove can parse the schemas (it rejects type
# lists, "null" types, arrays of arrays and objects without "properties"). Any field may
# hold null (JSON has no NaN); `validation_schema` derives the schema that says so.
def _centerline_columns(message: Mapping[str, Any]) -> Mapping[str, Any]:
    """``{"centerline": [[x, y, z], ...]}`` -> ``{"x": [...], "y": [...], "z": [...]}``."""
    points = message.get("centerline")
    if points is None:
        return message
    out = {k: v for k, v in message.items() if k != "centerline"}
    rows = points.tolist() if hasattr(points, "tolist") else points
    for axis, name in enumerate(("x", "y", "z")):
        out[name] = [float(p[axis]) for p in rows]
    return out


_STR = {"type": "string"}
_OPT_STR = _STR
_NUM = {"type": "number"}
_FREE = {"type": "object", "properties": {}}

CATALOGUE: tuple[ChannelSpec, ...] = (
    ChannelSpec(
        META,
        "suture_engine.Meta",
        _obj(
            "Run metadata (no wall-clock data)",
            {
                "procedure": {**_STR, "description": "procedure name"},
                "seed": {"type": "integer", "description": "random seed"},
                "params": {**_FREE, "description": "procedure parameters as run"},
                "control_rate_hz": {"type": "number", "description": "control rate [Hz]"},
                "engine_version": {**_STR, "description": "suture-engine version"},
                "robots": {"type": "array", "items": _STR, "description": "robot names"},
                "backend": {**_STR, "description": "backend name"},
            },
            ["procedure", "seed", "params", "control_rate_hz", "engine_version"],
            extra=True,
        ),
        "Run metadata, written once at t = 0.",
    ),
    ChannelSpec(
        EVENTS,
        "suture_engine.Event",
        _obj(
            "Event of the supervisory automaton",
            {
                "name": {**_STR, "description": "event name"},
                "kind": {
                    "type": "string",
                    "enum": ["planned", "unpredictable", "operator", "info"],
                    "description": "planned events advance; unpredictable ones go to NOT-BE",
                },
                "state": {**_OPT_STR, "description": "procedure state when it happened"},
                "robot": {**_OPT_STR, "description": "robot concerned, if any"},
                "detail": {**_OPT_STR, "description": "free text (violated invariant, ...)"},
            },
            ["name", "kind"],
        ),
        "Planned and unpredictable events (thesis 4.6, Fig. 4.25).",
    ),
    ChannelSpec(
        TRANSITIONS,
        "suture_engine.Transition",
        _obj(
            "State transition",
            {
                "source": _STR,
                "dest": _STR,
                "trigger": {**_OPT_STR, "description": "event that fired it"},
                "robot": _OPT_STR,
                "mode": {**_OPT_STR, "description": "Lock, Manual or Autonomous (Fig. 4.23)"},
            },
            ["source", "dest"],
        ),
        "State changes of the supervisory hybrid automaton.",
    ),
    ChannelSpec(
        OPERATOR,
        "suture_engine.OperatorEvent",
        _obj(
            "Operator event",
            {
                "action": {**_STR, "description": "lock, manual, resume, abort, force, ..."},
                "robot": _OPT_STR,
                "target_state": {**_OPT_STR, "description": "state to resume at"},
                "source": {**_OPT_STR, "description": "scripted or interactive"},
                "force": _vec("operator force at the tool tip [N]", 3),
                "detail": _OPT_STR,
            },
            ["action"],
        ),
        "Every operator event, scripted or interactive.",
    ),
    ChannelSpec(
        "/joint_state/<robot>",
        "suture_engine.JointState",
        _obj(
            "Measured joint state",
            {
                "position": _vec("joint positions [rad] (or [m] for prismatic joints)"),
                "velocity": _vec("estimated joint velocities [rad/s], from the observer"),
            },
            ["position", "velocity"],
        ),
        "Joint positions from the encoders and estimated velocities.",
    ),
    ChannelSpec(
        "/command/<robot>",
        "suture_engine.Command",
        _obj(
            "Command applied to the robot",
            {
                "kind": {"type": "string", "enum": ["torque", "velocity", "position"]},
                "values": _vec("joint torques [N*m], velocities [rad/s] or positions [rad]"),
                "tool": {**_NUM, "description": "tool command (gripper opening [rad])"},
                "mode": {**_OPT_STR, "description": "Lock, Manual or Autonomous"},
            },
            ["kind", "values"],
        ),
        "The command sent to the backend this tick.",
    ),
    ChannelSpec(
        "/base_wrench/<robot>",
        "suture_engine.BaseWrench",
        _obj(
            "Base force/torque sensor",
            {
                "force": _vec("force [N] in the base frame", 3),
                "torque": _vec("torque [N*m] in the base frame", 3),
            },
            ["force", "torque"],
        ),
        "The base F/T sensor reading.",
    ),
    ChannelSpec(
        "/tool_state/<robot>",
        "suture_engine.ToolState",
        _obj(
            "Measured tool joints",
            {
                "bend": _vec(
                    "universal joint angles from the encoders, about the shaft's x then "
                    "about the turned y [rad]",
                    2,
                ),
            },
            ["bend"],
        ),
        "The bent-tip grasper's measured universal joint, written when it changes (never "
        "while it stays straight from the start).",
    ),
    ChannelSpec(
        "/hook_load/<robot>",
        "suture_engine.HookLoad",
        _obj(
            "Hook actuator load",
            {
                "load": {
                    **_NUM,
                    "description": "load along the hook's stroke [N], + when something "
                    "pulls the hook out against the drive",
                },
            },
            ["load"],
        ),
        "The flexible hook's measured actuator load, written when it changes (never while "
        "it stays unloaded from the start).",
    ),
    ChannelSpec(
        TENSION_ESTIMATED,
        "suture_engine.Tension",
        _obj(
            "Estimated suture tension",
            {
                "tension_N": {**_NUM, "description": "estimated tension [N]"},
                "robot": {**_OPT_STR, "description": "robot whose sensor it comes from"},
                "estimates": {
                    "type": "array",
                    "items": {
                        "type": "object",
                        "properties": {"robot": _STR, "tension_N": _NUM},
                        "required": ["robot", "tension_N"],
                    },
                    "description": "every robot's own estimate [N], in the scene's order",
                },
            },
            ["tension_N"],
        ),
        "Suture tension estimated from the measurements (thesis ch. 4) [N]: the larger "
        "estimate, and every robot's.",
    ),
    ChannelSpec(
        "/qp/<robot>",
        "suture_engine.QpStatus",
        _obj(
            "move-constrained QP status",
            {
                "status": {**_STR, "description": "solver status (solved, max_iter, ...)"},
                "iterations": {"type": "integer"},
                "active_constraints": {"type": "array", "items": _STR},
                "objective": _NUM,
                "solve_time_us": {**_NUM, "description": "wall-clock solve time [us]"},
            },
            ["status", "iterations", "active_constraints"],
        ),
        "Status of the per-tick QP (wall-clock solve time dropped by default).",
        wall_clock_fields=("solve_time_us",),
    ),
    ChannelSpec(
        GROUND_TRUTH_SUTURE,
        "suture_engine.SutureCenterline",
        _obj(
            "Simulated suture centerline (ground truth)",
            {
                "x": _vec("x of the centerline points [m], world frame"),
                "y": _vec("y of the centerline points [m], world frame"),
                "z": _vec("z of the centerline points [m], world frame"),
            },
            ["x", "y", "z"],
        ),
        "The simulator's suture centerline, at a lower rate. Evaluation only. Writers may "
        "pass ``{'centerline': [[x, y, z], ...]}``: it is stored as coordinate arrays.",
        ground_truth=True,
        adapt=_centerline_columns,
    ),
    ChannelSpec(
        GROUND_TRUTH_SUTURE_CUT,
        "suture_engine.SutureCenterline",
        _obj(
            "A cut suture's last centerline (ground truth)",
            {
                "x": _vec("x of the centerline points [m], world frame"),
                "y": _vec("y of the centerline points [m], world frame"),
                "z": _vec("z of the centerline points [m], world frame"),
            },
            ["x", "y", "z"],
        ),
        "The centerline of a suture when it was cut (an interrupted suture's tied stitch, "
        "``cut-suture``), once per cut. Evaluation only. Written like "
        "``/ground_truth/suture``.",
        ground_truth=True,
        adapt=_centerline_columns,
    ),
    ChannelSpec(
        GROUND_TRUTH_TENSION,
        "suture_engine.Tension",
        _obj(
            "True suture tension (ground truth)",
            {
                "tension_N": {**_NUM, "description": "true tension [N]"},
                "joint": {
                    "type": "integer",
                    "minimum": 0,
                    "description": "where tension_N acts: its joint's index among the "
                    "/ground_truth/suture centerline's points",
                },
                "robot": _OPT_STR,
            },
            ["tension_N"],
        ),
        "The simulator's true suture tension [N], the thread's largest joint tension, and "
        "the joint it acts at. Evaluation only.",
        ground_truth=True,
    ),
    ChannelSpec(
        GROUND_TRUTH_KNOT,
        "suture_engine.Knot",
        _obj(
            "Knot classification (ground truth)",
            {
                "type": {**_STR, "description": "unknot, trefoil, square, granny, surgeons, ..."},
                "crossings": {"type": "integer"},
                "seated": {"type": "boolean"},
                "detail": _FREE,
            },
            ["type"],
        ),
        "Knot classification of the simulated suture. Evaluation only.",
        ground_truth=True,
    ),
)

_EXACT = {spec.pattern: spec for spec in CATALOGUE if not spec.per_robot}
_PER_ROBOT = tuple(spec for spec in CATALOGUE if spec.per_robot)
_BY_PATTERN = {spec.pattern: spec for spec in CATALOGUE}


def spec_for(topic: str) -> ChannelSpec:
    """The catalogue entry of a concrete topic.

    Raises:
        UnknownChannelError: the topic is not in the catalogue.
    """
    spec = _EXACT.get(topic)
    if spec is not None:
        return spec
    for spec in _PER_ROBOT:
        if spec.matches(topic):
            return spec
    raise UnknownChannelError(topic, tuple(_BY_PATTERN))


def validation_schema(spec: ChannelSpec) -> dict[str, Any]:
    """The channel's schema with ``null`` allowed wherever a value is (for validation).

    The stored schemas give each field one type (what Foxglove parses); messages may
    still hold ``null`` for a non-finite number or an absent optional value.
    """

    def nullable(node: Any, top: bool) -> Any:
        if isinstance(node, dict):
            out = {k: nullable(v, False) for k, v in node.items()}
            if "properties" in node:
                out["properties"] = {k: nullable(v, False) for k, v in node["properties"].items()}
            if not top and isinstance(node.get("type"), str):
                out["type"] = [node["type"], "null"]
                if "enum" in node:
                    out["enum"] = [*node["enum"], None]
            return out
        if isinstance(node, list):
            return [nullable(v, False) for v in node]
        return node

    result: dict[str, Any] = nullable(dict(spec.schema), True)
    return result


def schema_bytes(spec: ChannelSpec) -> bytes:
    """The schema as stored in the file: UTF-8 JSON with sorted keys, no spaces."""
    return json.dumps(spec.schema, sort_keys=True, separators=(",", ":")).encode()


def joint_state_topic(robot: str) -> str:
    """``/joint_state/<robot>``."""
    return _BY_PATTERN["/joint_state/<robot>"].topic(robot)


def command_topic(robot: str) -> str:
    """``/command/<robot>``."""
    return _BY_PATTERN["/command/<robot>"].topic(robot)


def base_wrench_topic(robot: str) -> str:
    """``/base_wrench/<robot>``."""
    return _BY_PATTERN["/base_wrench/<robot>"].topic(robot)


def tool_state_topic(robot: str) -> str:
    """``/tool_state/<robot>``."""
    return _BY_PATTERN["/tool_state/<robot>"].topic(robot)


def hook_load_topic(robot: str) -> str:
    """``/hook_load/<robot>``."""
    return _BY_PATTERN["/hook_load/<robot>"].topic(robot)


def qp_topic(robot: str) -> str:
    """``/qp/<robot>``."""
    return _BY_PATTERN["/qp/<robot>"].topic(robot)
