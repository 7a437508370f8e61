"""Loading a procedure file into a :class:`~suture_engine.language.procedure.Procedure`.

Loading collects every problem it finds instead of stopping at the first:
YAML errors, schema errors (unknown keys, wrong types, missing keys), unit
mismatches, out-of-bounds parameters, bad expressions, unknown skills, bad
skill parameters, and missing, cyclic or out-of-tree ``use:`` files. Each
problem is located at file, line and column. Semantic checks that need the
whole procedure (the state graph, scene references, reachability, limits) are
in :mod:`suture_engine.validation.checks`.

Quantities are converted to SI here, once. ``${...}`` expressions are
evaluated here over the procedure's parameters and the scene.
"""

from __future__ import annotations

import difflib
import os
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

from pydantic import ValidationError

from suture_engine.language.errors import InvalidValue, problems_from_validation
from suture_engine.language.expressions import (
    ExpressionError,
    Namespace,
    evaluate,
    find_expression,
)
from suture_engine.language.model import FailurePolicy, ParamSpec, ProcedureDocument, StateDocument
from suture_engine.language.procedure import LoadedState, Procedure, SourceLocation
from suture_engine.language.scene import Scene
from suture_engine.language.scene_file import resolve_extends, unwrap
from suture_engine.language.source import (
    PathKey,
    SourceMap,
    YamlDocument,
    load_yaml_file,
    load_yaml_text,
)
from suture_engine.language.units import (
    Quantity,
    UnitError,
    dimension_name,
    parse_quantity,
    parse_unit,
)
from suture_engine.validation.problem import Problem, ProblemError

__all__ = ["MAX_INCLUDE_DEPTH", "LoadResult", "load", "load_procedure", "load_text"]

MAX_INCLUDE_DEPTH = 8
"""Deepest chain of ``use:`` sub-procedures."""

_INVALID = InvalidValue()
_INTERP = "${"


class LoadResult(NamedTuple):
    """What loading found.

    Attributes:
        procedure: the loaded procedure, as complete as the problems allow
            (``None`` when the file could not be read or is not a procedure at all).
        problems: every problem found while loading, located.
    """

    procedure: Procedure | None
    problems: list[Problem]


class _Head(ProcedureDocument):
    states: dict[str, Any]  # type: ignore[assignment]  # validated state by state


Locator = Callable[[str, str, str], Problem]
"""(code, message, key) -> a problem located at the caller's ``with.<key>``."""


@dataclass
class _Binding:
    values: dict[str, Any]
    locate: Locator


@dataclass
class _Context:
    root: Path
    allow_outside: bool
    problems: list[Problem] = field(default_factory=list)
    scenes: dict[Path, Scene | None] = field(default_factory=dict)


def load(
    path: str | os.PathLike[str],
    *,
    allow_outside: bool = False,
    params: Mapping[str, Any] | None = None,
) -> LoadResult:
    """Load a procedure file, collecting every problem.

    Args:
        path: the procedure file.
        allow_outside: allow ``use:`` and scene paths outside the procedure's folder tree
            (a file may also allow it with ``includes_outside: true``).
        params: values overriding the procedure's parameter defaults, written as in
            YAML (``{"algorithm": 3, "tail": "20 mm"}``); checked like a ``use:``'s ``with``.

    Returns:
        The procedure (possibly incomplete) and the problems found.
    """
    display = os.fspath(path)
    file = Path(display)
    ctx = _Context(root=file.resolve().parent, allow_outside=allow_outside)
    try:
        doc = load_yaml_file(file, display)
    except ProblemError as exc:
        return LoadResult(None, exc.problems)
    binding = None
    if params is not None:
        source = doc.source

        def locate(code: str, message: str, key: str) -> Problem:
            return source.problem(code, f"(override) {message}", ("params", key))

        binding = _Binding(dict(params), locate)
    proc = _load_document(ctx, doc.data, doc.source, file.resolve(), binding, None, None, [])
    return LoadResult(proc, _dedupe(ctx.problems))


def load_text(text: str, file: str = "<text>", *, base: Path | None = None) -> LoadResult:
    """Load a procedure from text (``use:`` and scene paths relative to ``base``)."""
    base_dir = (base or Path.cwd()).resolve()
    ctx = _Context(root=base_dir, allow_outside=False)
    try:
        doc = load_yaml_text(text, file)
    except ProblemError as exc:
        return LoadResult(None, exc.problems)
    proc = _load_document(ctx, doc.data, doc.source, base_dir / file, None, None, None, [])
    return LoadResult(proc, _dedupe(ctx.problems))


def load_procedure(
    path: str | os.PathLike[str],
    *,
    allow_outside: bool = False,
    params: Mapping[str, Any] | None = None,
) -> Procedure:
    """Load a procedure file that must be free of loading problems (see :func:`load`).

    Raises:
        ProblemError: carrying every problem found.
    """
    result = load(path, allow_outside=allow_outside, params=params)
    if result.problems or result.procedure is None:
        raise ProblemError(result.problems or [Problem("invalid", "not a procedure", str(path))])
    return result.procedure


def _dedupe(problems: list[Problem]) -> list[Problem]:
    seen: set[tuple[str, int, int, str, str]] = set()
    out = []
    for p in problems:
        key = (p.file, p.line, p.column, p.code, p.message)
        if key not in seen:
            seen.add(key)
            out.append(p)
    return out


# --------------------------------------------------------------------------- documents


def _load_document(
    ctx: _Context,
    data: Any,
    source: SourceMap,
    file: Path,
    binding: _Binding | None,
    caller_scene: Scene | None,
    caller_roles: Mapping[str, str] | None,
    stack: list[Path],
) -> Procedure | None:
    add = ctx.problems.append
    if not isinstance(data, dict):
        found = "an empty file" if data is None else type(data).__name__
        add(source.problem("schema", f"a procedure is a mapping of keys, found {found}", ()))
        return None
    head = _validate_head(ctx, data, source)
    if head is None:
        return None

    # parameters: defaults, or values bound by the caller's `with`
    values = _resolve_params(ctx, head, source, binding)
    names: dict[str, Any] = dict(values)
    names["params"] = Namespace("params", values)
    # parameters already reported as bad: expressions using them are skipped silently
    raw_params = data.get("params")
    for key in [*head.params, *(raw_params if isinstance(raw_params, dict) else ())]:
        if isinstance(key, str) and key not in values:
            names[key] = _INVALID

    # scene: the caller's, else this file's own
    scene = caller_scene
    if scene is None and head.scene is not None:
        scene = _load_scene(ctx, head, source, file, names)
    elif scene is None and not stack:
        add(source.problem("missing-scene", "the procedure names no scene", ()))
    if scene is not None:
        names.update(_scene_namespaces(scene))

    roles: Mapping[str, str] = head.roles or (caller_roles or {})
    initial = _resolve(ctx, head.initial, source, ("initial",), names)
    states: dict[str, LoadedState] = {}
    raw_states = head.states if isinstance(head.states, dict) else {}
    allow = ctx.allow_outside or head.includes_outside
    for name, raw in raw_states.items():
        states[name] = _load_state(ctx, name, raw, source, file, names, scene, roles, stack, allow)
    return Procedure(
        name=head.procedure,
        version=str(head.version),
        description=head.description,
        file=source.file,
        scene=scene,
        params={k: (v.value if isinstance(v, Quantity) else v) for k, v in values.items()},
        roles=dict(roles),
        initial=initial if isinstance(initial, str) else "",
        states=states,
        source=source,
        backend=_backend(ctx, head, source, names) if not stack else None,
    )


def _backend(ctx: _Context, head: _Head, source: SourceMap, names: Mapping[str, Any]) -> str | None:
    """The file's ``backend:`` (``${...}`` evaluated with the parameters), checked
    against the registered backends."""
    if head.backend is None:
        return None
    from backends.registry import available, is_known

    name = _resolve(ctx, head.backend, source, ("backend",), names)
    if name is _INVALID:  # a bad expression, already reported
        return None
    if not isinstance(name, str) or not is_known(name):
        registered = available()
        ctx.problems.append(
            source.problem(
                "unknown-backend",
                f"no backend named {name!r}; registered: {', '.join(registered)}",
                ("backend",),
            )
        )
        return None
    return name


def _validate_head(ctx: _Context, data: dict[str, Any], source: SourceMap) -> _Head | None:
    try:
        return _Head.model_validate(data)
    except ValidationError as exc:
        ctx.problems.extend(problems_from_validation(exc, source, (), ProcedureDocument))
        bad = {err["loc"][0] for err in exc.errors() if err.get("loc")}
    lenient = {k: v for k, v in data.items() if k not in bad}
    if not isinstance(lenient.get("procedure"), str):
        lenient["procedure"] = "<unnamed>"
    lenient.setdefault("initial", "")
    if not isinstance(lenient.get("states"), dict):
        lenient["states"] = {}
    params = lenient.get("params")
    if isinstance(params, dict):
        lenient["params"] = {k: v for k, v in params.items() if _is_valid_spec(v)}
    try:
        return _Head.model_validate(lenient)
    except ValidationError:
        return None


def _is_valid_spec(value: Any) -> bool:
    try:
        ParamSpec.model_validate(value)
    except ValidationError:
        return False
    return True


# --------------------------------------------------------------------------- parameters


def _convert(spec: ParamSpec, value: Any) -> Any:
    """Convert a written parameter value to its typed form; raise ValueError with a reason."""
    kind = spec.type
    if kind == "bool":
        if isinstance(value, bool):
            return value
        raise ValueError(f"expected true or false, found {value!r}")
    if kind == "int":
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise ValueError(f"expected an integer, found {value!r}")
    if kind == "float":
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        raise ValueError(f"expected a number, found {value!r}")
    if kind == "str":
        if isinstance(value, str):
            return value
        raise ValueError(f"expected a string, found {value!r}")
    if spec.unit is None:
        raise ValueError("a quantity parameter needs a `unit`")
    factor, dim = parse_unit(spec.unit)
    if isinstance(value, str) and parse_quantity(value).dim == (0, 0, 0, 0):
        q = Quantity(parse_quantity(value).value * factor, dim)  # "1e5": a bare number
    elif isinstance(value, str):
        q = parse_quantity(value)
    elif isinstance(value, Quantity):
        q = value
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        q = Quantity(float(value) * factor, dim)  # a bare number is in the declared unit
    else:
        raise ValueError(f"expected a quantity in {spec.unit}, found {value!r}")
    if q.dim != dim:
        raise UnitError(
            f"expected {dimension_name(dim)} (unit {spec.unit}), found {dimension_name(q.dim)}"
        )
    return q


def _magnitude(v: Any) -> Any:
    return v.value if isinstance(v, Quantity) else v


def _check_spec(spec: ParamSpec, value: Any) -> str | None:
    """Bounds and choices; returns the reason a converted value is out of them."""
    x = _magnitude(value)
    for bound, name in ((spec.min, "min"), (spec.max, "max")):
        if bound is None:
            continue
        b = _magnitude(_convert(spec, bound))
        if (name == "min" and x < b) or (name == "max" and x > b):
            return f"{_show(value)} is {'below' if name == 'min' else 'above'} {name} {bound!r}"
    if spec.choices is not None:
        allowed = [_magnitude(_convert(spec, c)) for c in spec.choices]
        if not any(
            x == a or (isinstance(x, float) and isinstance(a, float) and abs(x - a) < 1e-12)
            for a in allowed
        ):
            return f"{_show(value)} is not one of {spec.choices!r}"
    return None


def _show(value: Any) -> str:
    return str(value) if isinstance(value, Quantity) else repr(value)


def _is_default_expression(raw: Any) -> bool:
    return isinstance(raw, str) and _INTERP in raw


def _mentions(text: str, name: str) -> bool:
    """Whether ``text`` uses ``name`` as a top-level name (not as ``x.name`` or a part of one)."""
    return re.search(rf"(?<![\w.]){re.escape(name)}(?!\w)", text) is not None


def _usable_names(
    ctx: _Context,
    source: SourceMap,
    where: PathKey,
    head: _Head,
    name: str,
    raw: str,
    values: Mapping[str, Any],
    *,
    own: bool,
) -> dict[str, Any] | None:
    """What an expression of parameter ``name`` may use, or None (reported) if it names
    a parameter declared after it.

    The parameters resolve in the order they are written: a default (``own`` false) sees
    those declared before ``name``, a ``requires`` (``own`` true) ``name`` too; one whose
    value was refused is seen as invalid.
    """
    order = list(head.params)
    cut = order.index(name) + (1 if own else 0)
    later = next((k for k in order[cut:] if _mentions(raw, k)), None)
    if later is not None:
        what, which = (
            ("condition", "its parameter and those") if own else ("default", "the parameters")
        )
        reason = (
            f"the {what} {raw!r} uses {later!r}, which is not declared before it; "
            f"a {what} may use only {which} declared before it"
        )
        ctx.problems.append(source.problem("bad-expression", reason, where))
        return None
    return {k: values.get(k, _INVALID) for k in order[:cut]}


def _default_from_expression(
    ctx: _Context,
    source: SourceMap,
    name: str,
    raw: str,
    values: Mapping[str, Any],
    head: _Head,
) -> Any:
    """A default written with ``${...}``: evaluated over the parameters declared before it.

    A name declared later makes a problem at the default: the parameters resolve in the
    order they are written. One declared before whose value was refused (and reported)
    leaves the default invalid, silently.
    """
    where: PathKey = ("params", name, "default")
    names = _usable_names(ctx, source, where, head, name, raw, values, own=False)
    if names is None:
        return _INVALID
    names["params"] = Namespace("params", dict(values))
    return _resolve(ctx, raw, source, where, names)


def _check_requires(
    ctx: _Context,
    head: _Head,
    source: SourceMap,
    binding: _Binding | None,
    name: str,
    values: Mapping[str, Any],
) -> bool:
    """A parameter's ``requires``: evaluated over it and the parameters declared before it.

    Broken, it is reported where the caller set this parameter, else where the caller set
    one the condition names, else at this parameter's ``requires``. Returns whether the
    value stands (a condition that cannot be evaluated is reported and fails it too).
    """
    raw = head.params[name].requires
    where: PathKey = ("params", name, "requires")
    if not isinstance(raw, str) or find_expression(raw) is None:
        reason = f"`requires` must be one `${{...}}` condition, got {raw!r}"
        ctx.problems.append(source.problem("bad-expression", reason, where))
        return False
    names = _usable_names(ctx, source, where, head, name, raw, values, own=True)
    if names is None:
        return False
    met = _resolve(ctx, raw, source, where, names)
    if met is True:
        return True
    if isinstance(met, InvalidValue):
        return False
    if met is not False:
        reason = f"{name!r} requires {raw!r}, which gives {met!r}, not true or false"
        ctx.problems.append(source.problem("bad-expression", reason, where))
        return False
    used = [k for k in names if _mentions(raw, k)]
    shown = ", ".join(f"{k}={_show_yaml(values[k])}" for k in used if k in values)
    reason = f"parameter {name!r} requires {raw} (here {shown})"
    description = head.params[name].description
    if description:
        reason += f": {description}"
    bound = binding.values if binding is not None else {}
    setter = next((k for k in (name, *used) if k in bound), None)
    if binding is not None and setter is not None:
        ctx.problems.append(binding.locate("unmet-requirement", reason, setter))
    else:
        ctx.problems.append(source.problem("unmet-requirement", reason, where))
    return False


def _show_yaml(value: Any) -> str:
    """A value as it would be written in YAML (``true``, ``3``, ``2 mm``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value) if isinstance(value, (Quantity, int, float, str)) else repr(value)


def _resolve_params(
    ctx: _Context, head: _Head, source: SourceMap, binding: _Binding | None
) -> dict[str, Any]:
    add = ctx.problems.append
    values: dict[str, Any] = {}
    bound = binding.values if binding is not None else {}
    if binding is not None:
        for key in bound:
            if key not in head.params:
                close = difflib.get_close_matches(key, list(head.params), n=1, cutoff=0.6)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                known = ", ".join(head.params) or "none"
                add(
                    binding.locate(
                        "unknown-param",
                        f"{head.procedure!r} has no parameter {key!r}{hint} (parameters: {known})",
                        key,
                    )
                )
    for name, spec in head.params.items():
        where: PathKey = ("params", name)
        if spec.type == "quantity" and spec.unit is None:
            add(
                source.problem(
                    "missing-field", f"quantity parameter {name!r} needs a `unit`", where
                )
            )
            continue
        # the declaration itself: default, bounds and choices must convert (a default
        # written as an expression is converted once evaluated, below)
        for key in ("default", "min", "max"):
            raw = getattr(spec, key)
            if raw is None or (key == "default" and _is_default_expression(raw)):
                continue
            try:
                _convert(spec, raw)
            except UnitError as exc:
                add(source.problem("unit-mismatch", exc.message, (*where, key)))
            except ValueError as exc:
                add(source.problem("bad-param", str(exc), (*where, key)))
        if spec.type == "quantity" and spec.unit is not None:
            try:
                parse_unit(spec.unit)
            except UnitError as exc:
                add(source.problem("unit-mismatch", exc.message, (*where, "unit")))
        if name in bound:
            raw, from_caller = bound[name], True
        else:
            raw, from_caller = spec.default, False
            if _is_default_expression(raw):
                raw = _default_from_expression(ctx, source, name, raw, values, head)
        if isinstance(raw, InvalidValue):
            continue
        if raw is None:
            if binding is not None:
                add(binding.locate("missing-param", f"parameter {name!r} needs a value", name))
            else:
                add(
                    source.problem("missing-param", f"parameter {name!r} has no default", (*where,))
                )
            continue

        code, reason = "", ""
        try:
            value = _convert(spec, raw)
            reason = _check_spec(spec, value) or ""
            code = "out-of-bounds" if reason else ""
        except UnitError as exc:
            code, reason = "unit-mismatch", exc.message
        except ValueError as exc:
            code, reason = "bad-param", str(exc)
        if not code:
            values[name] = value
            if spec.requires is not None and not _check_requires(
                ctx, head, source, binding, name, values
            ):
                del values[name]  # reported: what depends on it is not checked again
        elif from_caller and binding is not None:
            add(binding.locate(code, f"parameter {name!r}: {reason}", name))
        else:
            add(source.problem(code, reason, (*where, "default")))
    return values


# --------------------------------------------------------------------------- scene


def _inside(ctx: _Context, head: _Head, path: Path) -> bool:
    if ctx.allow_outside or head.includes_outside:
        return True
    try:
        path.resolve().relative_to(ctx.root)
    except ValueError:
        return False
    return True


def _load_scene(
    ctx: _Context, head: _Head, source: SourceMap, file: Path, names: dict[str, Any]
) -> Scene | None:
    add = ctx.problems.append
    hint = "; allow it with `includes_outside: true` or --allow-outside"
    if isinstance(head.scene, dict):
        inline = unwrap(YamlDocument({"scene": head.scene}, source), ("scene",))
        try:
            merged = resolve_extends(
                inline,
                file.parent,
                _cached_yaml,
                allowed=lambda p: _inside(ctx, head, p),
                outside_hint=hint,
            )
            return Scene.model_validate(merged.data)
        except ProblemError as exc:
            ctx.problems.extend(exc.problems)
        except ValidationError as exc:
            ctx.problems.extend(problems_from_validation(exc, merged.source, merged.prefix, Scene))
        return None
    ref = _resolve(ctx, head.scene, source, ("scene",), names)
    if not isinstance(ref, str):
        return None
    target = file.parent / ref
    display = os.path.normpath(os.path.join(os.path.dirname(source.file), ref))
    if not _inside(ctx, head, target):
        add(
            source.problem(
                "include-outside",
                f"scene {ref!r} is outside the procedure's folder tree" + hint,
                ("scene",),
            )
        )
        return None
    key = target.resolve()
    if key in ctx.scenes:
        return ctx.scenes[key]
    if not target.is_file():
        add(source.problem("missing-scene", f"scene file {ref!r} not found", ("scene",)))
        ctx.scenes[key] = None
        return None
    scene: Scene | None = None
    try:
        doc = _cached_yaml(target, display)
    except ProblemError as exc:
        ctx.problems.extend(exc.problems)
    else:
        try:
            merged = resolve_extends(
                unwrap(doc),
                target.parent,
                _cached_yaml,
                allowed=lambda p: _inside(ctx, head, p),
                outside_hint=hint,
                seen=(key,),
            )
            scene = Scene.model_validate(merged.data)
        except ProblemError as exc:
            ctx.problems.extend(exc.problems)
        except ValidationError as exc:
            ctx.problems.extend(problems_from_validation(exc, merged.source, merged.prefix, Scene))
    ctx.scenes[key] = scene
    return scene


def _scene_namespaces(scene: Scene) -> dict[str, Namespace]:
    newton, metre = (1, 1, -2, 0), (1, 0, 0, 0)
    suture = {
        "knot_pull_strength": Quantity(scene.suture.knot_pull_strength, newton),
        "diameter": Quantity(scene.suture.diameter, metre),
        "length": Quantity(scene.suture.length, metre),
        "usp": scene.suture.usp,
    }
    tissue = {
        "pullout_tension": Quantity(scene.tissue.pullout_tension, newton),
        "stiffness": Quantity(scene.tissue.stiffness, (0, 1, -2, 0)),
        "type": scene.tissue.type,
    }
    scene_ns = {
        "tension_limit": Quantity(scene.tension_limit, newton),
        "safety_factor": scene.safety_factor,
        "measurement_delay": Quantity(scene.physics.measurement_delay, (0, 0, 1, 0)),
        "timestep": Quantity(scene.physics.timestep, (0, 0, 1, 0)),
        # how many calibration posts stand in the scene (``Scene.posts``): a step whose
        # path they would block can be left out without them
        "posts": len(scene.posts),
    }
    return {
        "scene": Namespace("scene", scene_ns),
        "suture": Namespace("suture", suture),
        "tissue": Namespace("tissue", tissue),
    }


# --------------------------------------------------------------------------- expressions


def _resolve(
    ctx: _Context, value: Any, source: SourceMap, path: PathKey, names: Mapping[str, Any]
) -> Any:
    """Evaluate every ``${...}`` in ``value`` (recursively); bad ones become problems."""
    if isinstance(value, dict):
        return {k: _resolve(ctx, v, source, (*path, k), names) for k, v in value.items()}
    if isinstance(value, list):
        return [_resolve(ctx, v, source, (*path, i), names) for i, v in enumerate(value)]
    if not isinstance(value, str) or _INTERP not in value:
        return value
    invalid = [k for k, v in names.items() if isinstance(v, InvalidValue)]
    if invalid and any(_mentions(value, k) for k in invalid):
        return _INVALID
    try:
        inner = find_expression(value)
        if inner is not None and inner.count(_INTERP) == 0 and "}" not in inner:
            return evaluate(inner, names)
        return _interpolate(value, names)
    except ExpressionError as exc:
        ctx.problems.append(source.problem("bad-expression", exc.message, path))
        return _INVALID


def _interpolate(text: str, names: Mapping[str, Any]) -> str:
    out, pos = [], 0
    while True:
        start = text.find(_INTERP, pos)
        if start < 0:
            out.append(text[pos:])
            return "".join(out)
        end = text.find("}", start)
        if end < 0:
            raise ExpressionError("unclosed ${", text)
        out.append(text[pos:start])
        value = evaluate(text[start + 2 : end], names)
        if isinstance(value, bool):
            out.append("true" if value else "false")
        elif isinstance(value, (str, int)):
            out.append(str(value))
        elif isinstance(value, float) and value.is_integer():
            out.append(str(int(value)))
        else:
            raise ExpressionError(f"cannot insert {value} into text", text[start + 2 : end])
        pos = end + 1


# --------------------------------------------------------------------------- states


def _load_state(
    ctx: _Context,
    name: str,
    raw: Any,
    source: SourceMap,
    file: Path,
    names: Mapping[str, Any],
    scene: Scene | None,
    roles: Mapping[str, str],
    stack: list[Path],
    allow_outside: bool,
) -> LoadedState:
    add = ctx.problems.append
    where: PathKey = ("states", name)
    line, column = source.locate(where)
    location = SourceLocation(source.file, line, column)
    if not isinstance(raw, dict):
        add(source.problem("schema", f"state {name!r} must be a mapping", where))
        return LoadedState(name=name, location=location)
    resolved = _resolve(ctx, raw, source, where, names)
    try:
        doc = StateDocument.model_validate(resolved)
    except ValidationError as exc:
        ctx.problems.extend(problems_from_validation(exc, source, where, StateDocument))
        return LoadedState(name=name, location=location, on=_lenient_on(resolved.get("on")))
    state = LoadedState(
        name=name,
        location=location,
        skill=doc.skill,
        invariant=doc.invariant,
        timeout=doc.timeout,
        on=dict(doc.on),
        outcome=doc.outcome,
        description=doc.description,
        enabled=doc.when,
    )
    if doc.skill is not None:
        params, partial = _skill_params(ctx, doc.skill, doc.with_, source, where)
        return _replace(state, params=params, partial_params=partial)
    if doc.use is not None:
        sub = _load_use(ctx, doc, source, file, where, scene, roles, stack, allow_outside)
        return _replace(state, use=sub)
    return state


def _replace(state: LoadedState, **changes: Any) -> LoadedState:
    import dataclasses

    return dataclasses.replace(state, **changes)


def _lenient_on(raw: Any) -> dict[str, str | FailurePolicy]:
    out: dict[str, str | FailurePolicy] = {}
    if not isinstance(raw, dict):
        return out
    for event, target in raw.items():
        if isinstance(target, str):
            out[str(event)] = target
        elif isinstance(target, dict):
            try:
                out[str(event)] = FailurePolicy.model_validate(target)
            except ValidationError:
                continue
    return out


def _skill_params(
    ctx: _Context, skill: str, with_: dict[str, Any], source: SourceMap, where: PathKey
) -> tuple[Any, Any]:
    """(validated parameters or None, parameters with the invalid fields dropped or None)."""
    from skills.registry import UnknownSkill, get_skill

    try:
        cls = get_skill(skill)
    except UnknownSkill as exc:
        ctx.problems.append(source.problem(exc.code, exc.message, (*where, "skill")))
        return None, None
    except Exception as exc:  # a third-party skill that fails to import
        ctx.problems.append(
            source.problem("skill-import", f"skill {skill!r} failed to load: {exc}", where)
        )
        return None, None
    try:
        return cls.Params.model_validate(with_), None
    except ValidationError as exc:
        ctx.problems.extend(problems_from_validation(exc, source, (*where, "with"), cls.Params))
        bad = {err["loc"][0] for err in exc.errors() if err.get("loc")}
    try:
        partial = cls.Params.model_validate({k: v for k, v in with_.items() if k not in bad})
    except ValidationError:
        partial = None
    return None, partial


def _load_use(
    ctx: _Context,
    doc: StateDocument,
    source: SourceMap,
    file: Path,
    where: PathKey,
    scene: Scene | None,
    roles: Mapping[str, str],
    stack: list[Path],
    allow_outside: bool,
) -> Procedure | None:
    add = ctx.problems.append
    ref = doc.use or ""
    target = (file.parent / ref).resolve()
    display = os.path.normpath(os.path.join(os.path.dirname(source.file), ref))
    here = (*where, "use")
    if not (allow_outside or _tree_ok(ctx, target)):
        add(
            source.problem(
                "include-outside",
                f"{ref!r} is outside the procedure's folder tree; "
                "allow it with `includes_outside: true` or --allow-outside",
                here,
            )
        )
        return None
    chain = [*stack, file.resolve()]
    if target in chain:
        cycle = " -> ".join(p.name for p in chain[chain.index(target) :]) + f" -> {target.name}"
        add(source.problem("cyclic-use", f"sub-procedures use each other: {cycle}", here))
        return None
    if len(chain) > MAX_INCLUDE_DEPTH:
        add(source.problem("include-too-deep", f"more than {MAX_INCLUDE_DEPTH} nested uses", here))
        return None
    if not target.is_file():
        add(source.problem("missing-use", f"sub-procedure file {ref!r} not found", here))
        return None
    try:
        sub = _cached_yaml(target, display)
    except ProblemError as exc:
        ctx.problems.extend(exc.problems)
        return None

    def locate(code: str, message: str, key: str) -> Problem:
        return source.problem(code, message, (*where, "with", key), at_key=code == "unknown-param")

    binding = _Binding(dict(doc.with_), locate)
    return _load_document(ctx, sub.data, sub.source, target, binding, scene, roles, chain)


_YAML_CACHE: dict[tuple[Path, str, int, int], YamlDocument] = {}


def _cached_yaml(path: Path, display: str) -> YamlDocument:
    """Sub-procedures and scenes are read once per process while unchanged.

    The cached data is never mutated: resolving expressions builds new containers.
    """
    try:
        stat = path.stat()
    except OSError:
        return load_yaml_file(path, display)
    key = (path.resolve(), display, stat.st_mtime_ns, stat.st_size)
    doc = _YAML_CACHE.get(key)
    if doc is None:
        doc = load_yaml_file(path, display)
        if len(_YAML_CACHE) > 256:
            _YAML_CACHE.clear()
        _YAML_CACHE[key] = doc
    return doc


def _tree_ok(ctx: _Context, target: Path) -> bool:
    try:
        target.relative_to(ctx.root)
    except ValueError:
        return False
    return True
