"""Text drawings of a procedure's state machine: Mermaid and Graphviz dot.

Each state is labelled with its name, its skill (or the sub-procedure it uses)
and its invariant; planned transitions are drawn by event, failure policies as
edges to the Lock (wait for the operator) or Abort pseudo-states of the
supervisory automaton (thesis 4.6). No graphviz installation is needed: the
output is text. :func:`to_mermaid_transitions` draws the same machine through
``transitions``' own ``GraphMachine`` (its Mermaid engine, no graphviz needed).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from suture_engine.language.model import FailurePolicy

if TYPE_CHECKING:
    from suture_engine.language.procedure import LoadedState, Procedure

__all__ = ["state_label", "to_dot", "to_mermaid", "to_mermaid_transitions"]


def _invariant_text(state: LoadedState) -> str:
    inv = state.invariant
    if inv is None:
        return ""
    parts = []
    if inv.max_tension is not None:
        parts.append(f"tension <= {inv.max_tension:g} N")
    if inv.max_force is not None:
        parts.append(f"|F| <= {inv.max_force:g} N")
    if inv.singularity_margin is not None:
        parts.append(f"singularity margin {inv.singularity_margin * 57.29577951308232:g} deg")
    if inv.workspace is not None:
        parts.append("workspace box")
    return ", ".join(parts)


def state_label(state: LoadedState) -> list[str]:
    """The lines of a state's label: name, activity, invariant."""
    lines = [state.name]
    if state.skill is not None:
        lines.append(f"skill {state.skill}")
    elif state.use is not None:
        lines.append(f"use {state.use.name}")
        args = ", ".join(
            f"{k}={v}" for k, v in state.use.params.items() if isinstance(v, (bool, int, str))
        )
        if args:
            lines.append(f"({args})")
    elif state.outcome is not None:
        lines.append(f"outcome {state.outcome}")
    inv = _invariant_text(state)
    if inv:
        lines.append(f"invariant {inv}")
    if not state.enabled:
        lines.append("(skipped)")
    return lines


def _clean(text: str) -> str:
    return text.replace('"', "'").replace(":", " -").replace(";", ",")


def _policy_text(event: str, policy: FailurePolicy) -> str:
    return f"{event} (retry {policy.retry}, then {policy.then})"


def to_mermaid(proc: Procedure) -> str:
    """A Mermaid ``stateDiagram-v2`` of the procedure."""
    ids = {name: f"s{i}" for i, name in enumerate(proc.states)}
    lines = ["stateDiagram-v2", f"    %% {proc.name} ({proc.file})"]
    for name, state in proc.states.items():
        label = "<br/>".join(_clean(line) for line in state_label(state))
        lines.append(f'    state "{label}" as {ids[name]}')
    if proc.initial in ids:
        lines.append(f"    [*] --> {ids[proc.initial]}")
    needs_lock = needs_abort = False
    for name, state in proc.states.items():
        for event, target in state.on.items():
            if isinstance(target, FailurePolicy):
                dest = "Lock" if target.then == "lock" else "Abort"
                needs_lock = needs_lock or dest == "Lock"
                needs_abort = needs_abort or dest == "Abort"
                lines.append(f"    {ids[name]} --> {dest}: {_clean(_policy_text(event, target))}")
            elif target in ids:
                lines.append(f"    {ids[name]} --> {ids[target]}: {_clean(event)}")
        if state.terminal:
            lines.append(f"    {ids[name]} --> [*]")
    if needs_lock:
        lines.append('    state "Lock - hold, wait for the operator" as Lock')
    if needs_abort:
        lines.append('    state "Abort" as Abort')
        lines.append("    Abort --> [*]")
    return "\n".join(lines) + "\n"


def _escape(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"')


def to_dot(proc: Procedure) -> str:
    """A Graphviz ``dot`` digraph of the procedure."""
    ids = {name: f"s{i}" for i, name in enumerate(proc.states)}

    def q(text: str) -> str:
        return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'

    lines = [f"digraph {q(proc.name)} {{", "  rankdir=LR;", "  node [shape=box, style=rounded];"]
    lines.append('  __start [shape=point, label=""];')
    for name, state in proc.states.items():
        shape = ", peripheries=2" if state.terminal else ""
        label = "\\n".join(
            line.replace("\\", "\\\\").replace('"', '\\"') for line in state_label(state)
        )
        lines.append(f'  {ids[name]} [label="{label}"{shape}];')
    if proc.initial in ids:
        lines.append(f"  __start -> {ids[proc.initial]};")
    extra: set[str] = set()
    for name, state in proc.states.items():
        for event, target in state.on.items():
            if isinstance(target, FailurePolicy):
                dest = "Lock" if target.then == "lock" else "Abort"
                extra.add(dest)
                text = q(_policy_text(event, target))
                lines.append(f"  {ids[name]} -> {dest} [label={text}, style=dashed];")
            elif target in ids:
                lines.append(f"  {ids[name]} -> {ids[target]} [label={q(event)}];")
    if "Lock" in extra:
        lines.append('  Lock [label="Lock\\nhold, wait for the operator", shape=octagon];')
    if "Abort" in extra:
        lines.append('  Abort [label="Abort", shape=octagon, peripheries=2];')
    lines.append("}")
    return "\n".join(lines) + "\n"


def _machine_spec(proc: Procedure) -> tuple[list[dict[str, object]], list[dict[str, str]]]:
    ids = {name: f"s{i}" for i, name in enumerate(proc.states)}
    states: list[dict[str, object]] = [
        {"name": ids[name], "label": "<br/>".join(_clean(x) for x in state_label(state))}
        for name, state in proc.states.items()
    ]
    transitions: list[dict[str, str]] = []
    extra: set[str] = set()
    for name, state in proc.states.items():
        for event, target in state.on.items():
            if isinstance(target, FailurePolicy):
                dest = "Lock" if target.then == "lock" else "Abort"
                extra.add(dest)
                label = _clean(_policy_text(event, target))
                transitions.append(
                    {
                        "trigger": f"t{len(transitions)}",
                        "source": ids[name],
                        "dest": dest,
                        "label": label,
                    }
                )
            elif target in ids:
                transitions.append(
                    {
                        "trigger": f"t{len(transitions)}",
                        "source": ids[name],
                        "dest": ids[target],
                        "label": _clean(event),
                    }
                )
    for dest in sorted(extra):
        text = "Lock - hold, wait for the operator" if dest == "Lock" else "Abort"
        states.append({"name": dest, "label": text})
    return states, transitions


def to_mermaid_transitions(proc: Procedure) -> str:
    """A Mermaid ``stateDiagram-v2`` drawn by ``transitions``' ``GraphMachine``."""
    from transitions.extensions import GraphMachine

    base: Any = GraphMachine.state_cls

    class _LabelledState(base):  # type: ignore[misc, valid-type]
        def __init__(self, *args: object, label: str | None = None, **kwargs: object) -> None:
            super().__init__(*args, **kwargs)
            if label:
                self.label = label

    class _Machine(GraphMachine):  # type: ignore[misc]
        state_cls = _LabelledState

    class _Model:
        pass

    states, transitions = _machine_spec(proc)
    if not states:
        return "stateDiagram-v2\n"
    model = _Model()
    initial = f"s{list(proc.states).index(proc.initial)}" if proc.initial in proc.states else None
    _Machine(
        model=model,
        states=states,
        transitions=transitions,
        initial=initial or str(states[0]["name"]),
        graph_engine="mermaid",
        auto_transitions=False,
        title=proc.name,
    )
    text: str = model.get_graph().draw(None)  # type: ignore[attr-defined]
    return text if text.endswith("\n") else text + "\n"
