"""The dry-run: every check of a procedure that needs no backend.

:func:`validate_file` loads a procedure (collecting the loader's problems:
YAML, schema, units, bounds, expressions, skills, ``use:`` files) and then
checks the loaded procedure and each sub-procedure it uses:

- the state graph: transitions to undefined states, states unreachable from
  ``initial``, states from which no terminal state can be reached, retry
  policies without a bound and failure transitions that loop back without one;
- references to scene points and roles that do not exist, roles naming robots
  the scene lacks, skills given a robot that carries the wrong tool;
- targets the robot cannot reach (inverse kinematics 3.14-3.17 outside the
  joint limits, or within a margin of the singularities 3.22-3.23);
- tensions above the scene's derived limit; each skill's own checks (the PI
  force gains against the Routh bounds 7.29, 7.33, 7.41, 7.43).
"""

from __future__ import annotations

import difflib
import os
from collections import deque
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any

from suture_engine.errors import SutureError
from suture_engine.language.model import BASE_EVENTS, MAX_RETRY, FailurePolicy
from suture_engine.language.refs import SceneRef
from suture_engine.language.scene import ON_SURFACE_TOLERANCE
from suture_engine.language.units import Unit
from suture_engine.validation.problem import Problem
from suture_engine.validation.reach import DEFAULT_SINGULARITY_MARGIN, check_reach, world_to_base

if TYPE_CHECKING:
    from suture_engine.language.procedure import LoadedState, Procedure
    from suture_engine.language.source import PathKey, SourceMap

__all__ = ["check_procedure", "validate_file"]

PLANNED_EVENTS = frozenset({"done"})
"""Events that advance the procedure as planned; every other event is a failure."""


_BITE_POINTS = frozenset({"entry", "exit"})
"""Skill parameters naming a point where the needle crosses the tissue surface."""


def validate_file(
    path: str | os.PathLike[str],
    *,
    allow_outside: bool = False,
    params: Mapping[str, Any] | None = None,
    backend: str | None = None,
) -> list[Problem]:
    """Every problem of a procedure file: the loader's, then the semantic checks'.

    Args:
        path: the procedure file.
        allow_outside: allow includes outside the procedure's folder tree.
        params: parameter values overriding the defaults (as written in YAML).
        backend: the backend the procedure is to run on: the scene's ``faults:`` it
            cannot simulate are problems (``fault-not-supported``, naming it).
    """
    from suture_engine.language.loader import load

    result = load(path, allow_outside=allow_outside, params=params)
    problems = list(result.problems)
    if result.procedure is not None:
        problems.extend(check_procedure(result.procedure))
        if backend is not None:
            from suture_engine.faults.support import fault_problems

            problems.extend(fault_problems(result.procedure, backend))
    return _sorted_unique(problems)


def _sorted_unique(problems: list[Problem]) -> list[Problem]:
    seen: set[tuple[Any, ...]] = set()
    out = []
    order = {name: i for i, name in enumerate(dict.fromkeys(p.file for p in problems))}
    for p in sorted(problems, key=lambda p: (order[p.file], p.line, p.column)):
        key = (p.file, p.line, p.column, p.code, p.message)
        if key not in seen:
            seen.add(key)
            out.append(p)
    return out


def check_procedure(proc: Procedure) -> list[Problem]:
    """The semantic checks of a loaded procedure and of every sub-procedure it uses."""
    problems: list[Problem] = []
    seen: set[int] = set()
    for p, on in _walk(proc):
        if id(p) in seen:
            continue
        seen.add(id(p))
        problems.extend(_graph(p))
        problems.extend(_roles(p))
        for state in p.states.values():
            problems.extend(_state_checks(p, state, on))
    return problems


def _walk(proc: Procedure, on: bool = True) -> Iterator[tuple[Procedure, bool]]:
    """The procedure and its sub-procedures, each with whether it can run with these
    parameters (a sub-procedure that `when:` turns off cannot)."""
    yield proc, on
    for state in proc.states.values():
        if state.use is not None:
            yield from _walk(state.use, on and state.enabled)


def _source(proc: Procedure) -> SourceMap:
    from suture_engine.language.source import SourceMap

    return proc.source if isinstance(proc.source, SourceMap) else SourceMap(proc.file)


# --------------------------------------------------------------------------- graph


def _edges(state: LoadedState) -> Iterator[tuple[str, str]]:
    for event, target in state.on.items():
        if isinstance(target, str):
            yield event, target


def _events(state: LoadedState) -> set[str]:
    """The events ``state`` can raise: :data:`BASE_EVENTS`, ``timeout`` when it has one,
    and for a skill state the skill's named failure events
    (:attr:`skills.base.Skill.events`)."""
    from skills.registry import get_skill

    out = set(BASE_EVENTS)
    if state.timeout is not None:
        out.add("timeout")
    if state.skill is not None:
        try:
            out |= set(get_skill(state.skill).events)
        except SutureError:  # an unknown skill: reported by the state's own checks
            out |= {e for e in state.on if e not in BASE_EVENTS}
    return out


def _graph(proc: Procedure) -> list[Problem]:
    src = _source(proc)
    out: list[Problem] = []
    names = list(proc.states)
    if not proc.initial or proc.initial not in proc.states:
        close = difflib.get_close_matches(proc.initial, names, n=1, cutoff=0.6)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        out.append(
            src.problem(
                "undefined-state",
                f"initial state {proc.initial!r} is not defined{hint}",
                ("initial",),
            )
        )
    terminals = {n for n, s in proc.states.items() if s.terminal}
    if proc.states and not terminals:
        out.append(
            src.problem(
                "no-terminal", "no state has an `outcome`: the run can never end", ("states",)
            )
        )
    succ: dict[str, set[str]] = {n: set() for n in names}
    for name, state in proc.states.items():
        allowed = _events(state)
        for event, target in state.on.items():
            where: PathKey = ("states", name, "on", event)
            if event not in allowed:
                close = difflib.get_close_matches(event, sorted(allowed), n=1, cutoff=0.6)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                out.append(
                    src.problem(
                        "unknown-event",
                        f"state {name!r} never raises event {event!r}: expected one of "
                        f"{', '.join(sorted(allowed))}{hint}",
                        where,
                    )
                )
                continue
            if event not in BASE_EVENTS and isinstance(target, FailurePolicy):
                out.append(
                    src.problem(
                        "bad-event-target",
                        f"the named failure event {event!r} leads to a state (its name), "
                        "not a retry policy: a policy belongs to `failed`",
                        where,
                    )
                )
                continue
            if isinstance(target, FailurePolicy):
                out.extend(_policy(src, target, where))
                continue
            if target not in proc.states:
                close = difflib.get_close_matches(target, names, n=1, cutoff=0.6)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                out.append(
                    src.problem(
                        "undefined-state",
                        f"event {event!r} goes to undefined state {target!r}{hint}",
                        where,
                    )
                )
                continue
            succ[name].add(target)
    # reachable from initial; a state skipped by `when:` (false) may be cut off by an
    # `on:` expression resolved for the same parameters, so it and what it leads to
    # count as reachable
    if proc.initial in proc.states:
        skipped = [n for n, s in proc.states.items() if not s.enabled]
        seen = _closure([proc.initial, *skipped], succ)
        for name in names:
            if name not in seen:
                out.append(
                    src.problem(
                        "unreachable-state",
                        f"state {name!r} cannot be reached from initial state {proc.initial!r}",
                        ("states", name),
                    )
                )
    # can end: a terminal, or a policy that aborts / locks for the operator
    ends = set(terminals) | {
        n
        for n, s in proc.states.items()
        if any(isinstance(t, FailurePolicy) for t in s.on.values())
    }
    pred: dict[str, set[str]] = {n: set() for n in names}
    for a, targets in succ.items():
        for b in targets:
            pred[b].add(a)
    can_end: set[str] = set()
    for end in ends:
        can_end |= _closure([end], pred)
    if terminals:
        for name in names:
            if name not in can_end:
                out.append(
                    src.problem(
                        "no-terminal",
                        f"no terminal state can be reached from state {name!r}",
                        ("states", name),
                    )
                )
    # failure transitions that loop back without a retry bound
    for name, state in proc.states.items():
        for event, target in _edges(state):
            if event in PLANNED_EVENTS or target not in proc.states:
                continue
            if name in _closure([target], succ):
                out.append(
                    src.problem(
                        "unbounded-retry",
                        f"failure event {event!r} loops back from {name!r} to {target!r} "
                        "with no bound; use a policy such as {retry: 2, then: lock}",
                        ("states", name, "on", event),
                    )
                )
    return out


def _closure(starts: list[str], succ: dict[str, set[str]]) -> set[str]:
    seen = set(starts)
    queue = deque(starts)
    while queue:
        for nxt in succ.get(queue.popleft(), ()):
            if nxt not in seen:
                seen.add(nxt)
                queue.append(nxt)
    return seen


def _policy(src: SourceMap, policy: FailurePolicy, where: PathKey) -> list[Problem]:
    retry = policy.retry
    if isinstance(retry, str) or retry < 0:
        return [
            src.problem(
                "unbounded-retry",
                f"retry must be a count from 0 to {MAX_RETRY}, found {retry!r}: "
                "an unbounded retry loop never hands over to the operator",
                (*where, "retry"),
            )
        ]
    if retry > MAX_RETRY:
        return [
            src.problem(
                "out-of-bounds", f"retry {retry} is above the limit {MAX_RETRY}", (*where, "retry")
            )
        ]
    return []


# --------------------------------------------------------------------------- roles and states


def _roles(proc: Procedure) -> list[Problem]:
    if proc.scene is None:
        return []
    src = _source(proc)
    out = []
    robots = sorted(proc.scene.robots)
    for role, robot in proc.roles.items():
        if robot not in proc.scene.robots:
            out.append(
                src.problem(
                    "unknown-robot",
                    f"role {role!r} names robot {robot!r}, which the scene lacks "
                    f"(robots: {', '.join(robots)})",
                    ("roles", role),
                )
            )
    return out


_FIELD_MARKERS: dict[int, tuple[Any, tuple[frozenset[str], bool, str | None]]] = {}
""":func:`_field_markers` by the field's ``id`` (with the field, so the id stays its own)."""


def _field_markers(info: Any) -> tuple[frozenset[str], bool, str | None]:
    """SceneRef kinds, whether a position, and the unit of a pydantic field.

    A field's markers belong to its class, so they are worked out once per field and
    process (a procedure's states share a few skills' fields).
    """
    cached = _FIELD_MARKERS.get(id(info))
    if cached is not None and cached[0] is info:
        return cached[1]
    found = _read_field_markers(info)
    _FIELD_MARKERS[id(info)] = (info, found)
    return found


def _read_field_markers(info: Any) -> tuple[frozenset[str], bool, str | None]:
    """:func:`_field_markers` without the cache.

    Pydantic moves a top-level ``Annotated`` marker into ``info.metadata``; markers
    inside unions stay in the annotation.
    """
    kinds, position = _markers(info.annotation)
    unit = _unit(info.annotation)
    for meta in info.metadata:
        if isinstance(meta, SceneRef):
            kinds.add(meta.kind)
        if isinstance(meta, Unit):
            unit = meta.unit
            position = position or (meta.unit == "m" and info.annotation is not float)
    return frozenset(kinds), position, unit


def _unit(annotation: Any) -> str | None:
    for meta in getattr(annotation, "__metadata__", ()) or ():
        if isinstance(meta, Unit):
            return meta.unit
    for arg in getattr(annotation, "__args__", ()) or ():
        found = _unit(arg)
        if found is not None:
            return found
    return None


def _markers(annotation: Any) -> tuple[set[str], bool]:
    """SceneRef kinds and whether a Unit("m") position is among the annotation's branches."""
    kinds: set[str] = set()
    position = False
    for meta in getattr(annotation, "__metadata__", ()) or ():
        if isinstance(meta, SceneRef):
            kinds.add(meta.kind)
        if isinstance(meta, Unit) and meta.unit == "m":
            position = True
    for arg in getattr(annotation, "__args__", ()) or ():
        k, p = _markers(arg)
        kinds |= k
        position = position or p
    return kinds, position


def _state_checks(proc: Procedure, state: LoadedState, on: bool = True) -> list[Problem]:
    from skills.registry import get_skill

    src = _source(proc)
    scene = proc.scene
    base: PathKey = ("states", state.name)
    out: list[Problem] = []
    limit = scene.tension_limit if scene is not None else None
    inv = state.invariant
    if inv is not None and inv.max_tension is not None and limit is not None:
        if inv.max_tension > limit + 1e-12:
            out.append(
                src.problem(
                    "tension-limit",
                    f"invariant max_tension {inv.max_tension:g} N is above the scene's limit "
                    f"{limit:.4g} N (min of suture strength and tissue pull-out, times "
                    f"{scene.safety_factor if scene else 0:g})",
                    (*base, "invariant", "max_tension"),
                )
            )
    params = state.params if state.params is not None else state.partial_params
    if state.skill is None or params is None:
        return out
    cls = get_skill(state.skill)
    where: PathKey = (*base, "with")
    fields = type(params).model_fields
    for name, info in fields.items():
        value = getattr(params, name)
        kinds, _, _ = _field_markers(info)
        if not isinstance(value, str):
            continue
        if "role" in kinds and value not in proc.roles:
            close = difflib.get_close_matches(value, list(proc.roles), n=1, cutoff=0.6)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            out.append(
                src.problem(
                    "unknown-role",
                    f"role {value!r} is not declared under `roles`{hint}",
                    (*where, name),
                )
            )
        if "point" in kinds and scene is not None and value not in scene.tissue.points:
            points = sorted(scene.tissue.points)
            close = difflib.get_close_matches(value, points, n=1, cutoff=0.6)
            hint = f"; did you mean {close[0]!r}?" if close else f" (points: {', '.join(points)})"
            out.append(
                src.problem(
                    "unknown-point", f"the scene has no point {value!r}{hint}", (*where, name)
                )
            )
        elif "point" in kinds and scene is not None and name in _BITE_POINTS:
            height = scene.tissue.height(scene.tissue.points[value])
            if abs(height) > ON_SURFACE_TOLERANCE:
                out.append(
                    src.problem(
                        "off-tissue",
                        f"{name} point {value!r} is {height * 1e3:.3g} mm off the tissue "
                        "surface; a bite enters and leaves on the surface",
                        (*where, name),
                    )
                )
    for name, info in fields.items():
        value = getattr(params, name)
        if limit is None or "tension" not in name or not isinstance(value, float):
            continue
        if _field_markers(info)[2] == "N" and value > limit + 1e-12:
            assert scene is not None
            out.append(
                src.problem(
                    "tension-limit",
                    f"{name} {value:g} N is above the scene's tension limit {limit:.4g} N = "
                    f"min(knot-pull strength {scene.suture.knot_pull_strength:.4g} N, "
                    f"{scene.tissue.type} pull-out {scene.tissue.pullout_tension:.4g} N) x "
                    f"safety factor {scene.safety_factor:g}",
                    (*where, name),
                )
            )
    # a state that `when:` turns off for these parameters (or in a sub-procedure it turns
    # off) is not checked against the scene, which the same parameters may choose (its
    # tools, its reach, the skill's own checks): validate with --set to check it on
    if scene is not None and on and state.enabled:
        out.extend(_tool_check(proc, params, cls, src, where))
        out.extend(_reach_checks(proc, state, params, src, where))
    found: list[Problem] = []
    try:
        if on and state.enabled:
            found = cls.check(params, scene)
    except Exception as exc:  # a third-party check that breaks must not crash validation
        found = [Problem("skill-check", f"skill {cls.name!r} check failed: {exc}")]
    for p in found:
        path = (*where, *[part for part in p.path.split(".") if part]) if p.path else where
        out.append(src.problem(p.code, p.message, path))
    return out


def _robot_of(proc: Procedure, role: Any) -> Any:
    if proc.scene is None or not isinstance(role, str):
        return None
    robot = proc.roles.get(role)
    return proc.scene.robots.get(robot) if robot is not None else None


def _tool_check(
    proc: Procedure, params: Any, cls: Any, src: SourceMap, where: PathKey
) -> list[Problem]:
    tools = getattr(cls, "tools", None)
    role = getattr(params, "robot", None)
    robot = _robot_of(proc, role)
    if not tools or robot is None or robot.tool in tools:
        return []
    return [
        src.problem(
            "tool-mismatch",
            f"skill {cls.name!r} needs a robot with a {' or '.join(tools)}; role {role!r} "
            f"({proc.roles.get(str(role))}) carries a {robot.tool}",
            (*where, "robot"),
        )
    ]


def _reach_checks(
    proc: Procedure, state: LoadedState, params: Any, src: SourceMap, where: PathKey
) -> list[Problem]:
    scene = proc.scene
    if params is None or scene is None or getattr(params, "relative_to", None) is not None:
        return []
    roles = [getattr(params, "robot", None)]
    if roles[0] is None:
        roles = [getattr(params, "post", None), getattr(params, "loop", None)]
    offset = getattr(params, "offset", (0.0, 0.0, 0.0))
    margin = DEFAULT_SINGULARITY_MARGIN
    if state.invariant is not None and state.invariant.singularity_margin is not None:
        margin = state.invariant.singularity_margin
    out: list[Problem] = []
    for name, info in type(params).model_fields.items():
        if name in ("offset", "point") and state.skill in ("move-constrained", "rotate-about"):
            continue
        kinds, position, _ = _field_markers(info)
        value = getattr(params, name)
        if isinstance(value, str) and "point" in kinds:
            world = scene.tissue.points.get(value)
        elif position and name != "offset" and isinstance(value, tuple) and len(value) == 3:
            world = value
        else:
            continue
        if world is None:
            continue
        target = tuple(world[i] + offset[i] for i in range(3))
        for role in roles:
            robot = _robot_of(proc, role)
            if robot is None:
                continue
            local = world_to_base(target, robot.base.position, robot.base.rpy)
            lim = robot.joint_limits
            reach = check_reach(
                local,
                (lim.yaw, lim.pitch, lim.roll, lim.insertion),
                margin,
                getattr(params, "roll", None),
            )
            if reach.problem:
                out.append(
                    src.problem(
                        reach.problem,
                        f"{role} ({proc.roles.get(str(role))}) cannot reach {name} "
                        f"{value if isinstance(value, str) else list(value)}: {reach.reason}",
                        (*where, name),
                    )
                )
    return out
