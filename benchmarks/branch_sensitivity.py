"""How later steps' parameters decide a run's outcome, from one shared start.

Runs a procedure once up to the first tick of a step (``--at``), then branches: the
process forks once per variant, and each child changes some later steps' skill
parameters and runs on to the end. Every branch starts from the same state, bit for
bit (physics, skills, sensor noise), so a difference between branches comes from the
change alone. A run to a late step costs its prefix once instead of once per variant:
on the main job, a mirrored-throw variant from the end of the first throw costs about
a third of a whole run.

The first branch is always the procedure as written (``as-written``): it must end as a
straight ``suture run`` of the same seed does (``tests/test_branch_sensitivity.py``
checks this against ``run_procedure``).

A variant is ``NAME: STEP.FIELD=VALUE; STEP.FIELD+=VALUE; ...``, with STEP a step's
full name in the compiled procedure (``mirrored-knot.over-hook``), FIELD a field of its
skill's parameters, and VALUE a quantity (``28 mm``), a number, a word, ``true`` /
``false``, or a list of them (``[0 mm, 2 mm, 0 mm]``). ``+=`` adds to the value as
compiled (element by element for a list). A step may only be changed if it has not run
before the branch point, nor is the step being entered there.

Printed per branch: outcome, final state, simulated time, the ground-truth knot at the
end and its centre in the world frame [mm] (surgical backends), the largest true
tension, and per step after the branch point its ground-truth knot at the step's end
and the stitcher's and grasper's tool-tip travel (ground truth: evaluation only; skills
never read it). No trace is written; to
look closer, change the procedure and run the variant straight.

POSIX only (``os.fork``); the backend must run in-process (PyBullet ``DIRECT``).

Usage::

    python benchmarks/branch_sensitivity.py procedures/square-knot.yaml --seed 0 \\
        --at mirrored-knot.extend-hook [--set NAME=VALUE] \\
        --variant "h28: mirrored-knot.over-hook.height=28 mm" \\
        [--variant ...] [--backend NAME] [--max-time 230] [--workers 2] [--json FILE]

A run of ``benchmarks/knot_success.py``'s perturbed sweep is branched with
``--sweep-run ALG:RUN`` (its seed and its draw of base error, friction and stiffness;
``--sweep-base-seed`` as that sweep's ``--base-seed``, ``--sweep-only`` as its
``--only``), the sweep's procedure and its ``--set`` values, and ``--backend``::

    python benchmarks/branch_sensitivity.py procedures/square-knot.yaml \\
        --set algorithm=3 --set register=true --backend pybullet-surgical-stitched \\
        --sweep-run 3:3 --at mirrored-knot.clear-jaws --variant "..."
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import suture_engine  # noqa: E402,F401  (first: it pins OpenBLAS' kernel before numpy loads)

# isort: split
import numpy as np  # noqa: E402

from suture_engine.errors import SutureError  # noqa: E402
from suture_engine.runtime.recorder import Recorder  # noqa: E402

AS_WRITTEN = "as-written"


class VariantError(SutureError):
    """A ``--variant`` that cannot be applied: names the variant and what was expected."""

    code = "bad-variant"

    def __init__(self, variant: str, message: str) -> None:
        super().__init__(f"--variant {variant!r}: {message}")
        self.variant = variant


class SweepRunError(SutureError):
    """A ``--sweep-run`` that names no run of the sweep: names it and what was expected."""

    code = "bad-sweep-run"

    def __init__(self, spec: str, message: str) -> None:
        super().__init__(f"--sweep-run {spec!r}: {message}")
        self.spec = spec


@dataclasses.dataclass(frozen=True)
class Change:
    """One change of a variant: ``step``'s skill parameter ``field`` set to (or, with
    ``add``, increased by) ``value`` (SI)."""

    step: str
    field: str
    value: Any
    add: bool = False


@dataclasses.dataclass(frozen=True)
class Variant:
    """A named set of changes."""

    name: str
    changes: tuple[Change, ...]


_ITEM = re.compile(r"^\s*(?P<path>[^=+]+?)\s*(?P<op>\+?=)\s*(?P<value>.+?)\s*$")


def _value(text: str, variant: str) -> Any:
    """A variant's value in SI: a quantity, a number, a bool, a word, or a list."""
    from suture_engine.language.units import UnitError, parse_quantity

    text = text.strip()
    if text.startswith("[") and text.endswith("]"):
        inner = text[1:-1].strip()
        return tuple(_value(part, variant) for part in inner.split(",")) if inner else ()
    if text in ("true", "false"):
        return text == "true"
    try:
        return float(text)
    except ValueError:
        pass
    try:
        return parse_quantity(text).value
    except UnitError:
        if re.fullmatch(r"[A-Za-z_][\w-]*", text):
            return text
        raise VariantError(
            variant,
            f"expected a quantity ('28 mm'), a number, true/false or a list, found {text!r}",
        ) from None


def parse_variant(spec: str) -> Variant:
    """Parse ``NAME: STEP.FIELD=VALUE; ...``.

    Raises:
        VariantError: no name, no change, or a change that is not ``STEP.FIELD=VALUE``.
    """
    name, sep, body = spec.partition(":")
    name = name.strip()
    if not sep or not name:
        raise VariantError(spec, "expected 'NAME: STEP.FIELD=VALUE; ...'")
    if name == AS_WRITTEN:
        raise VariantError(spec, f"{AS_WRITTEN!r} is the branch that changes nothing")
    changes = []
    for item in filter(str.strip, body.split(";")):
        m = _ITEM.match(item)
        if m is None or "." not in m["path"]:
            raise VariantError(
                spec, f"expected STEP.FIELD=VALUE or STEP.FIELD+=VALUE, found {item.strip()!r}"
            )
        step, _, field = m["path"].rpartition(".")
        changes.append(Change(step, field, _value(m["value"], name), m["op"] == "+="))
    if not changes:
        raise VariantError(spec, "no change given")
    return Variant(name, tuple(changes))


def _changed_params(params: Any, changes: Sequence[Change], variant: str) -> Any:
    """``params`` (a frozen skill-parameter model) with ``changes`` applied, validated."""
    from pydantic import ValidationError

    data = params.model_dump()
    for ch in changes:
        if ch.field not in type(params).model_fields:
            fields = ", ".join(sorted(type(params).model_fields))
            raise VariantError(variant, f"{ch.step}: no field {ch.field!r} (fields: {fields})")
        if ch.add:
            old = data[ch.field]
            if (
                isinstance(old, (tuple, list))
                and isinstance(ch.value, tuple)
                and len(old) == len(ch.value)
            ):
                data[ch.field] = tuple(a + b for a, b in zip(old, ch.value, strict=True))
            elif isinstance(old, (int, float)) and isinstance(ch.value, float):
                data[ch.field] = old + ch.value
            else:
                raise VariantError(
                    variant, f"{ch.step}.{ch.field}: cannot add {ch.value!r} to {old!r}"
                )
        else:
            data[ch.field] = ch.value
    try:
        return type(params).model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        raise VariantError(variant, f"{ch.step}: {first['loc']}: {first['msg']}") from None


def apply_variant(steps: dict[str, Any], variant: Variant, entered: set[str]) -> None:
    """Replace the changed steps' skill factories in the compiled plan's ``steps``.

    Raises:
        VariantError: an unknown step, a step that already ran (or is running), an unknown
            field or a value its parameters refuse.
    """
    by_step: dict[str, list[Change]] = {}
    for ch in variant.changes:
        by_step.setdefault(ch.step, []).append(ch)
    for step, changes in by_step.items():
        if step not in steps:
            raise VariantError(variant.name, f"no step {step!r} in the compiled procedure")
        if step in entered:
            raise VariantError(
                variant.name, f"step {step!r} ran before the branch point (or starts there)"
            )
        spec = steps[step]
        skill = spec.make_skill()
        cls, params = type(skill), _changed_params(skill.params, changes, variant.name)
        steps[step] = dataclasses.replace(spec, make_skill=lambda c=cls, p=params: c(p))


def _step_name(state: str) -> str:
    return state.rsplit("/", 1)[-1].split("~", 1)[0]


class BranchRecorder(Recorder):
    """Keeps what a branch reports: per step after the branch point, the ground-truth
    knot at its end, the tools' true tip travel and the step's largest true tension;
    the largest true tension over the branch."""

    def __init__(self, backend: Any) -> None:
        self.backend = backend
        self.entered: set[str] = set()
        self.steps: list[dict[str, Any]] = []
        self.recording = False
        self.peak_true_N = 0.0
        self._step_peak_N = 0.0
        self._current: tuple[str, float, dict[str, Any]] | None = None

    def tick(
        self,
        time_ns: int,
        obs: Any,
        torques: Any,
        modes: Any,
        tension: Any,
        ground_truth: Mapping[str, Any],
    ) -> None:
        value = ground_truth.get("tension_N")
        if self.recording and value is not None:
            self.peak_true_N = max(self.peak_true_N, float(value))
            self._step_peak_N = max(self._step_peak_N, float(value))

    def start(self, state: str, t: float) -> None:
        """Begin recording at the branch point: the step being entered, at ``t`` [s]."""
        self.recording = True
        self._current = (state.rsplit("/", 1)[-1], t, self._tips(self.backend.ground_truth()))

    def _tips(self, truth: Mapping[str, Any]) -> dict[str, Any]:
        return {k.split("/")[0]: np.asarray(truth[k]) for k in truth if k.endswith("/tool_tip")}

    def transition(self, time_ns: int, record: Any) -> None:
        t = time_ns / 1e9
        self.entered.add(_step_name(record.dest))
        if not self.recording:
            return
        truth = self.backend.ground_truth()
        tips = self._tips(truth)
        if self._current is not None:
            name, t0, tips0 = self._current
            travel = {
                r: round(1e3 * float(np.linalg.norm(tips[r] - tips0[r])), 2)
                for r in tips
                if r in tips0
            }
            self.steps.append({"step": name, "start_s": round(t0, 3), "end_s": round(t, 3),
                               "knot": _knot(truth), "travel_mm": travel,
                               "peak_true_N": round(self._step_peak_N, 3)})  # fmt: skip
        self._current = (record.dest.rsplit("/", 1)[-1], t, tips)
        self._step_peak_N = 0.0


def _centre_mm(knot: Any) -> list[float] | None:
    """The summary's knot centre in the world frame [mm], or None (no knot)."""
    centre = knot.get("centre") if isinstance(knot, dict) else None
    return None if centre is None else [round(1e3 * float(c), 1) for c in centre]


def _knot(truth: Mapping[str, Any]) -> str | None:
    """The ground-truth thread's knot type (None: no thread, or a degenerate one)."""
    from suture_engine.suture.topology import InvalidCenterline, classify_knot

    try:
        return str(classify_knot(np.asarray(truth["centerline"])).type)
    except (KeyError, InvalidCenterline):
        return None


def run_branches(
    procedure: str | Path,
    *,
    at: str,
    variants: Sequence[Variant],
    seed: int = 0,
    sets: Sequence[str] = (),
    backend: str | None = None,
    max_time_s: float = 300.0,
    workers: int = 1,
    backend_options: Mapping[str, Any] | None = None,
    calibration_error: Mapping[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Run ``procedure`` to the first tick of step ``at``; branch into the procedure as
    written and each variant; return one result per branch (as-written first).
    ``backend_options`` go to the backend's constructor (e.g. a sweep run's perturbation:
    :func:`sweep_run`); ``calibration_error`` to the interpreter (robot -> believed base
    minus actual [m]: :func:`sweep_calibration`).

    Raises:
        VariantError: a variant that cannot be applied (checked before the run starts,
            the branch step itself included, except for steps that run before the branch
            point, found there).
        RuntimeError: the run ended before reaching ``at``, or a branch died.
    """
    from backends import registry
    from suture_engine.runtime.interpreter import Interpreter
    from suture_engine.runtime.run import load_plan

    proc, plan = load_plan(procedure, sets)
    if at not in plan.steps:
        raise VariantError(at, f"--at: no step {at!r} in the compiled procedure")
    for v in variants:  # unknown steps, fields and values, before the long prefix;
        # the step entered at the branch point has started there: it cannot change
        apply_variant(dict(plan.steps), v, {at})
    be = registry.create(backend or proc.backend or "pybullet", **dict(backend_options or {}))
    scene = proc.scene
    recorder = BranchRecorder(be)
    out_dir = Path(tempfile.mkdtemp(prefix="branches-"))
    branches = [Variant(AS_WRITTEN, ()), *variants]
    state: dict[str, Any] = {"branch": None}

    def on_tick(interp: Any) -> None:
        if state["branch"] is not None or _step_name(interp.automaton.state) != at:
            return
        state["t_branch"] = interp.tick_index * interp.dt
        running: list[int] = []
        for i, variant in enumerate(branches):
            if len(running) >= workers:
                os.waitpid(running.pop(0), 0)
            pid = os.fork()
            if pid == 0:  # the branch: change the later steps and run on
                state["branch"] = (i, variant)
                try:
                    apply_variant(interp.automaton.plan.steps, variant, recorder.entered)
                except VariantError as exc:
                    (out_dir / f"{i}.json").write_text(
                        json.dumps({"variant": variant.name, "error": str(exc)})
                    )
                    os._exit(0)
                recorder.start(interp.automaton.state, state["t_branch"])
                state["wall0"] = time.perf_counter()
                return
            running.append(pid)
        for pid in running:
            os.waitpid(pid, 0)
        state["branch"] = "parent"
        interp.max_time_s = 0.0  # the prefix ends here

    try:
        first = be.reset(scene, seed)
        interp = Interpreter(
            plan, be, first, roles=proc.roles, params=proc.params, scene=scene, seed=seed,
            control_rate_hz=1.0 / float(scene.physics.timestep) if scene is not None else 1000.0,
            recorder=recorder, max_time_s=max_time_s,
            tension_limit_N=float(scene.tension_limit) if scene is not None else None,
            on_tick=on_tick, calibration_error=calibration_error,
        )  # fmt: skip
        summary = interp.run(proc.name, backend or proc.backend or "pybullet")
    finally:
        if not isinstance(state["branch"], tuple):
            be.close()
    if isinstance(state["branch"], tuple):  # a branch's end: report and leave at once
        i, variant = state["branch"]
        knot = summary.knot
        first_knot = knot[0] if isinstance(knot, list) and knot else knot
        result = {
            "variant": variant.name,
            "changes": [dataclasses.asdict(c) for c in variant.changes],
            "outcome": summary.outcome, "final_state": summary.final_state,
            "sim_time_s": round(summary.sim_time_s, 3), "ticks": summary.ticks,
            "knot": first_knot.get("type") if isinstance(first_knot, dict) else None,
            "knot_centre_mm": _centre_mm(first_knot),
            "knot_lay": first_knot.get("lay") if isinstance(first_knot, dict) else None,
            "max_tension_N": summary.max_tension_N,
            "last_fault": summary.last_fault,
            "peak_true_tension_N": round(recorder.peak_true_N, 3),
            "branch_s": round(state["t_branch"], 3),
            "wall_s": round(time.perf_counter() - state["wall0"], 1),
            "steps": recorder.steps,
        }  # fmt: skip
        (out_dir / f"{i}.json").write_text(json.dumps(result))
        os._exit(0)
    if state["branch"] is None:
        raise RuntimeError(f"the run ended ({summary.final_state}) before step {at!r}")
    results = []
    for i, variant in enumerate(branches):
        path = out_dir / f"{i}.json"
        if not path.exists():
            raise RuntimeError(f"branch {variant.name!r} died without a result")
        results.append(json.loads(path.read_text()))
        path.unlink()
    out_dir.rmdir()
    return results


def sweep_run(
    spec: str,
    backend: str,
    base_seed: int = 0,
    only: str | None = None,
    base_error_as: str = "placement",
) -> tuple[int, dict[str, Any]]:
    """The seed and backend options of run ``RUN`` of algorithm ``ALG`` (``spec`` is
    ``"ALG:RUN"``) in ``benchmarks/knot_success.py``'s perturbed sweep with ``base_seed``
    on ``backend``: branching from it starts where that sweep's run does, bit for bit.
    Give the sweep's procedure and ``--set`` values as well (``--set algorithm=ALG``).
    ``only`` is that sweep's ``--only`` text (``"friction"``, ``"base,friction"``: an
    ablation), None for the whole perturbation. ``base_error_as`` is that sweep's
    ``--base-error-as``: with ``calibration`` the options carry no base error, and
    :func:`sweep_calibration` gives the interpreter's.

    Raises:
        SweepRunError: ``spec`` is not ``ALG:RUN`` with two non-negative integers, or
            ``only`` names an unknown perturbation.
    """
    job = _sweep_job(spec, backend, base_seed, only, base_error_as)
    return job.seed, dict(job.options)


def sweep_calibration(
    spec: str,
    backend: str,
    base_seed: int = 0,
    only: str | None = None,
    base_error_as: str = "placement",
) -> dict[str, Any] | None:
    """The calibration error [m] of the sweep run that :func:`sweep_run` starts (None
    unless ``base_error_as`` is ``calibration``); same arguments and errors."""
    return _sweep_job(spec, backend, base_seed, only, base_error_as).calibration


def _sweep_job(
    spec: str, backend: str, base_seed: int, only: str | None, base_error_as: str
) -> Any:
    """knot_success's job for ``spec`` (``"ALG:RUN"``), as :func:`sweep_run` reads it."""
    m = re.fullmatch(r"\s*(\d+)\s*:\s*(\d+)\s*", spec)
    if m is None:
        raise SweepRunError(spec, "expected ALG:RUN, e.g. 3:6")
    alg, run = int(m.group(1)), int(m.group(2))
    ks = _knot_success()
    try:
        kinds = None if only is None else ks.parse_only(only)
    except ValueError as exc:
        raise SweepRunError(spec, f"--sweep-only: {exc}") from None
    jobs = ks.make_jobs(
        [alg], run + 1, base_seed=base_seed, backend=backend, out=Path("unused"),
        max_time_s=0.0, perturb=True, accepted=ks.accepted_options(backend), only=kinds,
    )  # fmt: skip
    if base_error_as not in ks.BASE_ERROR_AS:
        raise SweepRunError(spec, f"--sweep-base-error-as: one of {', '.join(ks.BASE_ERROR_AS)}")
    job = jobs[run]
    return ks.as_calibration(job) if base_error_as == "calibration" else job


def _knot_success() -> Any:
    """``benchmarks/knot_success.py`` (the sweep's draws are defined there), imported from
    this script's own folder."""
    here = str(Path(__file__).resolve().parent)
    if here not in sys.path:
        sys.path.append(here)
    import knot_success

    return knot_success


def format_results(results: Sequence[Mapping[str, Any]]) -> str:
    """The printed table: one line per branch, then its steps after the branch point."""
    lines = []
    for r in results:
        if "error" in r:
            lines.append(f"{r['variant']}: {r['error']}")
            continue
        lines.append(
            f"{r['variant']}: {r['outcome']} ({r['final_state']}), "
            f"{r['sim_time_s']:.1f} s simulated, knot {r['knot']}"
            + (f" lying as {r['knot_lay']}" if r.get("knot_lay") else "")
            + (f" at {tuple(r['knot_centre_mm'])} mm" if r.get("knot_centre_mm") else "")
            + ", "
            f"true peak {r['peak_true_tension_N']:.2f} N, branched at {r['branch_s']:.2f} s"
        )
        fault = r.get("last_fault")
        if fault:
            where = f"{fault['step']} at {fault['t_s']:.2f} s"
            lines.append(f"    last fault: {where}: {fault['reason']}")
        for s in r["steps"]:
            travel = ", ".join(f"{k} {v:.1f} mm" for k, v in s["travel_mm"].items())
            span = f"{s['start_s']:8.2f}-{s['end_s']:8.2f} s"
            peak = s.get("peak_true_N")
            shown = "" if peak is None else f"  true peak {peak:.2f} N"
            lines.append(f"    {s['step']:<42} {span}  knot {s['knot']}  travel {travel}{shown}")
    return "\n".join(lines)


def main(argv: Sequence[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("procedure")
    ap.add_argument("--at", required=True, help="the step whose first tick is the branch point")
    ap.add_argument("--variant", action="append", default=[], help="NAME: STEP.FIELD=VALUE; ...")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="NAME=VALUE")
    ap.add_argument("--backend", default=None)
    ap.add_argument("--max-time", type=float, default=300.0)
    ap.add_argument("--workers", type=int, default=1, help="branches run at once")
    ap.add_argument("--json", type=Path, default=None, help="also write the results here")
    ap.add_argument(
        "--sweep-run", default=None, metavar="ALG:RUN",
        help="start as run RUN of algorithm ALG of knot_success.py's perturbed sweep does "
        "(its seed and perturbation; --seed is then ignored; needs --backend)",
    )  # fmt: skip
    ap.add_argument("--sweep-base-seed", type=int, default=0, help="that sweep's --base-seed")
    ap.add_argument(
        "--sweep-only", default=None, metavar="KINDS",
        help="that sweep's --only (comma-separated from base,friction,stiffness)",
    )  # fmt: skip
    ap.add_argument(
        "--sweep-base-error-as", default="placement", metavar="KIND",
        help="that sweep's --base-error-as (placement or calibration)",
    )  # fmt: skip
    ap.add_argument(
        "--thread-damping", type=float, default=None, metavar="PER_S",
        help="the backend's thread_damping: how fast the thread's free motion dies away [1/s]",
    )  # fmt: skip
    ap.add_argument(
        "--thread-weight", type=float, default=None, metavar="G_PER_M",
        help="the backend's thread_weight: the mass per length whose weight the thread keeps [g/m]",
    )  # fmt: skip
    args = ap.parse_args(argv)
    thread = (("--thread-damping", "thread_damping", args.thread_damping),
              ("--thread-weight", "thread_weight", args.thread_weight))  # fmt: skip
    for flag, option, given in thread:  # the bounds knot_success.py checks
        if given is not None and (problem := _knot_success().thread_flag_problem(option, given)):
            ap.error(f"{flag}: {problem}")
    try:
        variants = [parse_variant(v) for v in args.variant]
        seed, options, calibration = args.seed, {}, None
        if args.sweep_run is not None:
            if args.backend is None:
                raise SweepRunError(args.sweep_run, "needs --backend (the sweep's)")
            job = _sweep_job(args.sweep_run, args.backend, args.sweep_base_seed,
                             args.sweep_only, args.sweep_base_error_as)  # fmt: skip
            seed, options, calibration = job.seed, dict(job.options), job.calibration
        if args.thread_damping is not None:
            options["thread_damping"] = args.thread_damping
        if args.thread_weight is not None:
            options["thread_weight"] = args.thread_weight * 1e-3
        results = run_branches(
            args.procedure, at=args.at, variants=variants, seed=seed, sets=args.sets,
            backend=args.backend, max_time_s=args.max_time, workers=max(1, args.workers),
            backend_options=options, calibration_error=calibration,
        )  # fmt: skip
    except (SutureError, RuntimeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(format_results(results))
    if args.json is not None:
        tmp = args.json.with_suffix(args.json.suffix + ".tmp")
        tmp.write_text(json.dumps(results, indent=1))
        tmp.replace(args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
