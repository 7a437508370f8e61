"""Square-knot success rate per ligation algorithm under perturbations (issue #6).

Runs ``procedures/square-knot.yaml --set algorithm=N`` on the surgical PyBullet backend,
``--seeds`` runs per algorithm, each with its own perturbation drawn from
``numpy.random.SeedSequence([base_seed, algorithm, run])`` (so a run's inputs do not
depend on the number of workers or on the other algorithms):

- base calibration error: a vector e per robot with independent N(0, sigma^2)
  components, sigma = 1 mm, between where the robot's base stands and where the skills
  believe it stands. ``--base-error-as`` says which of the two is off the scene's layout:
  ``placement`` (the default so far): the robot is built at the declared base + e and the
  skills plan from the declared one; ``calibration``: the robot is built at the declared
  base and the skills plan from the declared base - e
  (:mod:`suture_engine.runtime.calibration`). Either way the tool tips land about e off
  their goals; they differ once a ``register`` step has measured the base: a placement
  error then leaves the ports where they were moved to, a calibration error leaves
  nothing;
- joint friction: every joint's friction scaled by one factor ~ U(0.7, 1.3);
- suture stiffness: the thread's stiffness scaled by one factor ~ U(0.8, 1.2). On the
  surgical backend this scales the thread's bending stiffness EI, whose default is 0 (the
  limp thread the knot physics is tuned with): the factor then changes nothing unless a
  nominal EI is given with ``--bending-stiffness`` (the table says so).

A perturbation is passed to the backend only if its constructor takes the option (see
``OPTION_NAMES``); the table says which ones were applied, so an unperturbed run is never
reported as perturbed.

Success = the run's outcome is ``succeeded`` AND the ground-truth classifier (the
``knot`` entry of ``summary.json``, from the simulated thread, never the procedure's
belief) says ``square`` AND the knot binds the stitch (``through_tissue``).

``--single`` measures one throw instead: ``knot-algorithm-N.yaml --set stitch=false`` on
the stitched start (``pybullet-surgical-stitched`` unless ``--backend`` says otherwise);
success is then ``succeeded``, a ``trefoil`` and ``through_tissue``. The rate is printed
with its 95 % Wilson score interval (``suture_engine.report.sweep.wilson_interval``),
which counts every run as independent; ``paths`` beside it counts the distinct runs
(runs whose states changed on the same ticks made the same motion: with
``--no-perturb`` several seeds can be one run, see :func:`path_digest`). Every run's row
goes to ``OUT/results.csv``. A square knot on a ``*-stitched`` backend
(``--backend pybullet-surgical-stitched``) starts from the stitched start as well
(``--set stitch=false``).

Usage::

    python benchmarks/knot_success.py [--seeds 20] [--algorithms 1,2,3] [--max-time 600]
        [--workers 2] [--out runs/knot-success] [--backend pybullet-surgical]
        [--base-seed 0] [--no-perturb] [--bending-stiffness EI] [--wound-gap MM]
        [--wound-depth MM] [--pad-clear-depth MM]
        [--thread-contact-stiffness N_PER_M] [--smooth-joints] [--thread-damping PER_S]
        [--thread-weight G_PER_M] [--single] [--resume]
        [--only base,friction,stiffness] [--base-part all|common|relative]
        [--set NAME=VALUE ...] [--runs 1,2,5-9]

``--only`` applies only the named perturbations (an ablation): run ``i`` keeps the
values run ``i`` draws, the others stay nominal. ``--base-part`` splits each run's base
error into the part both robots share (their mean: the tools' relative poses stay exact,
only their poses to the tissue and thread are off) and the rest (the relative error that
tool-to-tool moves suffer), and applies one of them. ``--set`` passes a procedure
parameter to every run (``--set register=true``: the throw first registers both robots'
bases on the scene's posts). ``--runs`` runs only the named runs of the ``--seeds`` draws,
each with the seed and perturbation it draws in the whole sweep: to re-measure the runs a
change can reach (a change to a second throw cannot alter a run whose first throw failed).

The table is rewritten after every run, so a stopped sweep keeps its rows; ``--resume``
keeps them and runs only the runs still missing (same algorithm, run, seed and
perturbation).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import inspect
import io
import math
import sys
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from multiprocessing import get_context
from pathlib import Path
from typing import Any, NamedTuple

import suture_engine  # noqa: F401 (first: it pins OpenBLAS' kernel before numpy loads)

# isort: split
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
PROCEDURE = ROOT / "procedures" / "square-knot.yaml"
SINGLE = str(ROOT / "procedures" / "knot-algorithm-%d.yaml")
"""One throw of algorithm N (``--single``)."""
ROBOTS = ("endobot_1", "endobot_2")

BASE_SIGMA = 1e-3
"""Standard deviation of each component of a base calibration error [m]."""
FRICTION_RANGE = (0.7, 1.3)
"""Range of the joint friction scale [-] (+-30 %)."""
STIFFNESS_RANGE = (0.8, 1.2)
"""Range of the suture stiffness scale [-] (+-20 %)."""

OPTION_NAMES: dict[str, tuple[str, ...]] = {
    "base_error": ("base_error", "base_offsets", "base_offset"),
    "friction_scale": ("friction_scale", "joint_friction_scale"),
    "stiffness_scale": ("suture_stiffness_scale", "stiffness_scale"),
}
"""Backend constructor options that may carry each perturbation, first match used."""


@dataclass(frozen=True)
class Perturbation:
    """One run's perturbation.

    Attributes:
        base_error: per robot, the actual base's displacement from the declared one [m].
        friction_scale: joint friction factor [-].
        stiffness_scale: suture stiffness factor [-].
    """

    base_error: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)
    friction_scale: float = 1.0
    stiffness_scale: float = 1.0


KINDS = {"base": "base_error", "friction": "friction_scale", "stiffness": "stiffness_scale"}
"""``--only`` names -> the :class:`Perturbation` field each one sets."""


def keep_only(perturbation: Perturbation, kinds: Sequence[str]) -> Perturbation:
    """The perturbation with only ``kinds`` (keys of :data:`KINDS`) kept, the others at
    their nominal values (the values kept are the ones drawn, so an ablation's run ``i``
    has run ``i``'s draw)."""
    nominal = Perturbation()
    keep = {KINDS[k] for k in kinds}
    return Perturbation(
        **{f: getattr(perturbation if f in keep else nominal, f) for f in KINDS.values()}
    )


BASE_PARTS = ("all", "common", "relative")
"""``--base-part`` choices: the whole base error, its common part (every robot displaced by
the robots' mean error: the tools keep their true relative poses), or its relative part
(each robot's error minus the mean: the same relative error, none shared)."""


def split_base(perturbation: Perturbation, part: str) -> Perturbation:
    """The perturbation with only ``part`` (one of :data:`BASE_PARTS`) of its base error.

    The two parts add up to the whole: ``common + relative == all`` robot by robot.

    Raises:
        ValueError: an unknown part.
    """
    if part not in BASE_PARTS:
        raise ValueError(f"base part must be one of {BASE_PARTS}, got {part!r}")
    errors = perturbation.base_error
    if part == "all" or not errors:
        return perturbation
    mean = np.mean(np.array([errors[r] for r in sorted(errors)], dtype=float), axis=0)
    split = {
        r: tuple(float(v) for v in (mean if part == "common" else np.asarray(e, float) - mean))
        for r, e in errors.items()
    }
    return replace(perturbation, base_error=split)  # type: ignore[arg-type]


def draw_perturbation(rng: np.random.Generator, robots: Sequence[str] = ROBOTS) -> Perturbation:
    """Draw one perturbation (module doc) from ``rng``."""
    base = {r: tuple(float(v) for v in rng.normal(0.0, BASE_SIGMA, 3)) for r in robots}
    return Perturbation(
        base_error=base,  # type: ignore[arg-type]
        friction_scale=float(rng.uniform(*FRICTION_RANGE)),
        stiffness_scale=float(rng.uniform(*STIFFNESS_RANGE)),
    )


def accepted_options(backend: str) -> set[str]:
    """Keyword options the constructors of a built-in backend's class chain take."""
    import importlib
    from importlib.metadata import entry_points

    from backends import registry

    target = getattr(registry, "_BUILTIN", {}).get(backend)
    if target is None:  # an entry-point backend (pybullet-surgical-stitched is one)
        eps = {ep.name: ep.value for ep in entry_points(group=registry.ENTRY_POINT_GROUP)}
        target = eps.get(backend)
    if target is None:
        return set()
    module, _, attr = target.partition(":")
    cls = getattr(importlib.import_module(module), attr)
    names: set[str] = set()
    for klass in inspect.getmro(cls):
        init = klass.__dict__.get("__init__")
        if init is None:
            continue
        for name, prm in inspect.signature(init).parameters.items():
            if name != "self" and prm.kind not in (prm.VAR_POSITIONAL, prm.VAR_KEYWORD):
                names.add(name)
    return names


def backend_options(
    perturbation: Perturbation, accepted: set[str]
) -> tuple[dict[str, Any], tuple[str, ...], tuple[str, ...]]:
    """The backend options carrying a perturbation.

    Returns:
        ``(options, applied, missing)``: the keyword options, and which perturbations
        they carry and which the backend cannot take.
    """
    values: dict[str, Any] = {
        "base_error": {r: list(v) for r, v in perturbation.base_error.items()},
        "friction_scale": perturbation.friction_scale,
        "stiffness_scale": perturbation.stiffness_scale,
    }
    options: dict[str, Any] = {}
    applied: list[str] = []
    missing: list[str] = []
    for what, names in OPTION_NAMES.items():
        name = next((n for n in names if n in accepted), None)
        if name is None:
            missing.append(what)
        else:
            options[name] = values[what]
            applied.append(what)
    return options, tuple(applied), tuple(missing)


class Job(NamedTuple):
    """One run (picklable)."""

    algorithm: int
    run: int
    seed: int
    perturbation: Perturbation
    options: dict[str, Any]
    backend: str
    out_dir: str
    max_time_s: float
    single: bool = False
    sets: tuple[str, ...] = ()
    calibration: dict[str, tuple[float, float, float]] | None = None
    """Robot -> believed base minus actual [m] (``--base-error-as calibration``), or None."""


BASE_ERROR_AS = ("placement", "calibration")
"""``--base-error-as`` choices: where a draw's base error goes (module doc)."""


def as_calibration(job: Job) -> Job:
    """The job with its base error as a calibration error: the backend gets none (the
    robots stand where the scene declares them) and the skills' believed bases are the
    declared ones minus the draw's error, so that the tool tips land where a placement
    error of the same draw puts them."""
    errors = job.perturbation.base_error
    options = {k: v for k, v in job.options.items() if k not in OPTION_NAMES["base_error"]}
    if not errors:
        return job._replace(options=options)
    calibration = {r: (-float(e[0]), -float(e[1]), -float(e[2])) for r, e in errors.items()}
    return job._replace(options=options, calibration=calibration)


class Row(NamedTuple):
    """One run's result (a row of ``results.csv``)."""

    algorithm: int
    run: int
    seed: int
    outcome: str
    knot_type: str
    success: bool
    max_tension_N: float
    sim_time_s: float
    wall_time_s: float
    friction_scale: float
    stiffness_scale: float
    base_error_mm: float
    error: str
    last_fault: str = ""
    """The run's last fault (``step: reason``, from the summary's ``last_fault``): on a
    failed run, where and why it stopped."""
    path: str = ""
    """A digest of the run's transitions (each state entered and its tick; see
    :func:`path_digest`): two runs with the same one changed state on the same ticks."""
    peak_true_tension_N: float = math.nan
    """The thread's true peak tension [N] (ground truth, the summary's
    ``peak_true_tension_N``; NaN when the run has none). ``max_tension_N`` is the base
    sensors' estimate, which the tools meeting can raise and a pinch between them can
    hide: the tension limit is checked against this one."""
    knot_lay: str = ""
    """How the knot lies (the summary's ``lay``: ``square`` when its post strand is
    straight, ``half-hitches`` when not, Fig. 7.4; '' when none): a square that lies as
    half hitches still counts as a square."""
    peak_true_at: str = ""
    """Where the true peak was reached (the summary's ``peak_true_tension_at``): the step
    and the thread's joint, e.g. ``mirrored-knot.tighten at joint 16`` (the joint is a
    point of the ground-truth centerline); '' when not known."""


def make_jobs(
    algorithms: Sequence[int],
    seeds: int,
    *,
    base_seed: int,
    backend: str,
    out: Path,
    max_time_s: float,
    perturb: bool,
    accepted: set[str],
    only: Sequence[str] | None = None,
    base_part: str = "all",
) -> list[Job]:
    """Every run's seed, perturbation and backend options (module doc); ``base_part``
    keeps that part of each base error (:func:`split_base`)."""
    jobs = []
    for alg in algorithms:
        for i in range(seeds):
            ss = np.random.SeedSequence([base_seed, alg, i])
            seed = int(ss.generate_state(1, dtype=np.uint32)[0] & 0x7FFFFFFF)
            rng = np.random.default_rng(ss.spawn(1)[0])
            pert = draw_perturbation(rng) if perturb else Perturbation()
            if perturb and only is not None:
                pert = keep_only(pert, only)
            if perturb:
                pert = split_base(pert, base_part)
            opts = backend_options(pert, accepted)[0] if perturb else {}
            out_dir = str(out / "runs" / f"alg{alg}-{i:03d}")
            jobs.append(Job(alg, i, seed, pert, opts, backend, out_dir, max_time_s))
    return jobs


def parse_only(text: str) -> list[str]:
    """The perturbation kinds in ``text`` (``"base,friction"``), each a key of :data:`KINDS`.

    Raises ``ValueError`` when none is given or one is unknown."""
    kinds = [k.strip() for k in text.split(",") if k.strip()]
    if not kinds or any(k not in KINDS for k in kinds):
        raise ValueError(f"comma-separated from {','.join(KINDS)}; got {text!r}")
    return kinds


def parse_runs(text: str, seeds: int) -> set[int]:
    """The run numbers in ``text`` (``"1,2,5-9"``), each in ``range(seeds)``.

    Raises ``ValueError`` naming the item that is not a run number or a range of them."""
    chosen: set[int] = set()
    for item in (part.strip() for part in text.split(",")):
        lo, sep, hi = item.partition("-")
        try:
            first, last = int(lo), int(hi if sep else lo)
        except ValueError:
            raise ValueError(f"{item!r} is not a run number or a range N-M") from None
        if not 0 <= first <= last < seeds:
            raise ValueError(f"{item!r}: runs go from 0 to {seeds - 1} (--seeds {seeds})")
        chosen.update(range(first, last + 1))
    return chosen


def _agreed(knot: Any, key: str) -> str:
    """Field ``key`` of a summary's ``knot`` entry ('' when none). A list (one entry per
    knot) gives it only when every knot has the same; 'mixed' when not."""
    if isinstance(knot, Mapping):
        return str(knot.get(key) or "")
    if isinstance(knot, list) and knot:
        values = {_agreed(k, key) for k in knot}
        return values.pop() if len(values) == 1 else "mixed"
    return ""


def knot_type(knot: Any) -> str:
    """The ground-truth knot type of a summary's ``knot`` entry ('' when none; a list
    counts only when every knot has the same type)."""
    return _agreed(knot, "type")


def knot_lay(knot: Any) -> str:
    """How a summary's ``knot`` entry lies (its ``lay``; '' when none; a list counts only
    when every knot lies the same way, 'mixed' when not)."""
    return _agreed(knot, "lay")


def binds_stitch(knot: Any) -> bool:
    """Whether every knot entry's thread still runs through the tissue (``through_tissue``)."""
    if isinstance(knot, Mapping):
        return knot.get("through_tissue") is True
    if isinstance(knot, list) and knot:
        return all(binds_stitch(k) for k in knot)
    return False


def is_success(outcome: str, knot: str, bound: bool = True, *, single: bool = False) -> bool:
    """Success = outcome ``succeeded``, the ground-truth knot ``square`` (``trefoil`` for a
    single throw) and the knot binding the stitch (``bound``)."""
    return outcome == "succeeded" and knot == ("trefoil" if single else "square") and bound


def job_sets(job: Job) -> list[str]:
    """The run's ``--set`` values: a single throw or a square knot on the stitched start
    (a ``*-stitched`` backend) skips the stitch, elsewhere makes it; a square knot picks
    its algorithm; then the ``--set`` values given on the command line."""
    stitched = job.single or job.backend.endswith("-stitched")
    return (
        ([] if job.single else [f"algorithm={job.algorithm}"])
        + (["stitch=false"] if stitched else ["stitch=true"])
        + list(job.sets)
    )


def path_digest(trace: Path) -> str:
    """A short digest of a trace's ``/transitions``: each destination state with its log
    time [ns], in order ("" when the trace cannot be read).

    In the knot procedures (position control, no force loop) the sensor noise reaches
    the motion only through the steps that decide on a measurement: a guarded move's
    stop, an invariant's lock. Unperturbed runs of different seeds whose states changed
    on the same ticks then share their motion: seeds 1, 7 and 10 of the main job send
    the same commands, to the bit, at 110 s (docs/status.md). The number of distinct
    digests is how many runs the seeds made. (A procedure with a force loop, such as
    ``tension-regulate``, feeds the noise to every tick: there the count is a lower
    bound.)
    """
    import hashlib

    from suture_engine.trace.channels import TRANSITIONS
    from suture_engine.trace.errors import TraceError
    from suture_engine.trace.reader import TraceReader

    h = hashlib.sha256()
    try:
        for m in TraceReader(trace).messages([TRANSITIONS]):
            h.update(f"{m.data['dest']}@{m.log_time_ns};".encode())
    except TraceError:  # a missing or unreadable trace: no digest, the run counts alone
        return ""
    return h.hexdigest()[:12]


def run_one(job: Job) -> Row:
    """Run one job in a worker; any exception becomes an ``error`` row (a failure)."""
    from suture_engine.runtime.run import run_procedure

    base_mm = _base_error_mm(job.perturbation)
    start = time.perf_counter()
    common = (job.perturbation.friction_scale, job.perturbation.stiffness_scale, base_mm)
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            result = run_procedure(
                str(SINGLE % job.algorithm if job.single else PROCEDURE),
                backend=job.backend,
                seed=job.seed,
                sets=job_sets(job),
                out=job.out_dir,
                max_time_s=job.max_time_s,
                backend_options=job.options or None,
                calibration_error=job.calibration,
            )
    except Exception as exc:  # a physics blow-up counts as a failed run, with its reason
        wall = time.perf_counter() - start
        msg = f"{type(exc).__name__}: {exc}".replace("\n", " ")[:300]
        return Row(job.algorithm, job.run, job.seed, "error", "", False, math.nan, 0.0, wall,
                   *common, msg)  # fmt: skip
    s = result.summary
    kt = knot_type(s.knot)
    fault = f"{s.last_fault['step']}: {s.last_fault['reason']}"[:200] if s.last_fault else ""
    ok = is_success(s.outcome, kt, binds_stitch(s.knot), single=job.single)
    return Row(
        job.algorithm, job.run, job.seed, s.outcome, kt, ok,
        float(s.max_tension_N), float(s.sim_time_s), time.perf_counter() - start, *common, "",
        fault, path_digest(Path(job.out_dir) / "trace.mcap"),
        float(s.metrics.get("peak_true_tension_N", math.nan)), knot_lay(s.knot),
        peak_at_text(s.metrics.get("peak_true_tension_at")),
    )  # fmt: skip


def peak_at_text(at: Any) -> str:
    """The summary's ``peak_true_tension_at`` as ``step at joint N`` ('' when None)."""
    if not isinstance(at, dict):
        return ""
    step = str(at.get("state") or "?").rsplit("/", 1)[-1]
    joint = at.get("joint")
    return step if joint is None else f"{step} at joint {joint}"


def square_lays(rows: Sequence[Row]) -> dict[int, dict[str, int]]:
    """How the successful runs' knots lie, per algorithm (``lay``: ``square``,
    ``half-hitches``, ``-`` when the row has none, e.g. one read from an older table);
    algorithms without a success are absent."""
    out: dict[int, dict[str, int]] = {}
    for alg in sorted({r.algorithm for r in rows}):
        lays = Counter(r.knot_lay or "-" for r in rows if r.algorithm == alg and r.success)
        if lays:
            out[alg] = dict(lays.most_common())
    return out


def true_peaks(rows: Sequence[Row]) -> dict[int, tuple[float, int, float]]:
    """Per algorithm: the largest true peak tension [N], its run, and the largest
    estimated peak [N] (for comparison). Rows without a true peak (NaN) are left out;
    an algorithm with none is absent."""
    out: dict[int, tuple[float, int, float]] = {}
    for alg in sorted({r.algorithm for r in rows}):
        mine = [r for r in rows if r.algorithm == alg]
        known = [r for r in mine if math.isfinite(r.peak_true_tension_N)]
        if not known:
            continue
        top = max(known, key=lambda r: r.peak_true_tension_N)
        est = max(
            (r.max_tension_N for r in mine if math.isfinite(r.max_tension_N)), default=math.nan
        )
        out[alg] = (top.peak_true_tension_N, top.run, est)
    return out


class Tally(NamedTuple):
    """Per-algorithm result."""

    algorithm: int
    runs: int
    successes: int
    rate: float
    low: float
    high: float
    outcomes: dict[str, int]
    knots: dict[str, int]
    paths: int
    """Distinct runs among them: rows with the same non-empty ``path`` count once (the
    Wilson interval counts every row as independent)."""


def tally(rows: Sequence[Row]) -> list[Tally]:
    """Success rate with its 95 % Wilson interval, per algorithm."""
    from suture_engine.report.sweep import wilson_interval

    out = []
    for alg in sorted({r.algorithm for r in rows}):
        mine = [r for r in rows if r.algorithm == alg]
        k = sum(r.success for r in mine)
        lo, hi = wilson_interval(k, len(mine))
        out.append(
            Tally(
                alg, len(mine), k, k / len(mine), lo, hi,
                dict(Counter(r.outcome for r in mine)),
                dict(Counter(r.knot_type or "none" for r in mine)),
                len({r.path or f"row {i}" for i, r in enumerate(mine)}),
            )
        )  # fmt: skip
    return out


def stops(rows: Sequence[Row]) -> dict[int, dict[str, int]]:
    """Where the failed runs stopped, per algorithm: the step of each one's last fault
    (``-`` when it had none: it ended without one, e.g. ``succeeded`` with the wrong knot),
    most frequent first."""
    out: dict[int, dict[str, int]] = {}
    for alg in sorted({r.algorithm for r in rows}):
        steps = Counter(
            r.last_fault.split(":", 1)[0] if r.last_fault else ("error" if r.error else "-")
            for r in rows
            if r.algorithm == alg and not r.success
        )
        if steps:
            out[alg] = dict(steps.most_common())
    return out


def write_csv(rows: Sequence[Row], path: Path) -> None:
    """All rows, one per run, sorted by algorithm and run; written to a temporary file
    and renamed over ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(Row._fields)
        for r in sorted(rows, key=lambda r: (r.algorithm, r.run)):
            w.writerow(r)
    tmp.replace(path)


def _bool(text: str) -> bool:
    return text == "True"


_TYPES: dict[str, Callable[[str], Any]] = {
    "algorithm": int, "run": int, "seed": int, "success": _bool, "max_tension_N": float,
    "sim_time_s": float, "wall_time_s": float, "friction_scale": float,
    "stiffness_scale": float, "base_error_mm": float, "peak_true_tension_N": float,
}  # fmt: skip
"""How each column of ``results.csv`` reads back (the others are text)."""


def read_csv(path: Path) -> list[Row]:
    """The rows of a ``results.csv`` written by :func:`write_csv` ([] when there is none).

    Raises:
        ValueError: the file is not such a table (its header or a value is wrong).
    """
    if not path.exists():
        return []
    with path.open(newline="", encoding="utf-8") as fh:
        table = list(csv.reader(fh))
    # a table written before the last_fault, path, peak_true_tension_N, knot_lay or
    # peak_true_at column reads with them empty (NaN)
    if not table or tuple(table[0]) not in (Row._fields[: len(Row._fields) - k] for k in range(6)):
        raise ValueError(f"{path}: not a results table (header {table[:1]})")
    fields = tuple(table[0])
    rows = []
    for line, values in enumerate(table[1:], start=2):
        try:
            rows.append(Row(*(_TYPES.get(k, str)(v) for k, v in zip(fields, values, strict=True))))
        except ValueError as exc:
            raise ValueError(f"{path}, line {line}: {exc}") from None
    return rows


def _base_error_mm(perturbation: Perturbation) -> float:
    """The largest of the robots' base errors [mm] (the table's ``base_error_mm``)."""
    return max(
        (float(np.linalg.norm(v)) * 1e3 for v in perturbation.base_error.values()), default=0.0
    )


def _job_key(job: Job) -> tuple[Any, ...]:
    pert = job.perturbation
    return (job.algorithm, job.run, job.seed, pert.friction_scale, pert.stiffness_scale,
            _base_error_mm(pert))  # fmt: skip


def _row_key(row: Row) -> tuple[Any, ...]:
    return (row.algorithm, row.run, row.seed, row.friction_scale, row.stiffness_scale,
            row.base_error_mm)  # fmt: skip


def pending(jobs: Sequence[Job], done: Sequence[Row]) -> list[Job]:
    """The jobs with no row in ``done`` for the same algorithm, run, seed and perturbation
    (so a row of another base seed or of another ``--only`` never stands in for a run)."""
    have = {_row_key(r) for r in done}
    return [j for j in jobs if _job_key(j) not in have]


THREAD_FLAG_BOUNDS: dict[str, tuple[Callable[[float], bool], str]] = {
    "thread_contact_stiffness": (lambda v: v > 0, "a stiffness > 0 [N/m]"),
    "thread_damping": (lambda v: v >= 0, "a rate >= 0 [1/s]"),
    "thread_weight": (lambda v: v > 0, "a mass per length > 0 [g/m]"),
}
"""The thread flags' bounds, by backend option, in the flags' own units (the backend's:
the weight in g/m); ``benchmarks/branch_sensitivity.py`` reads them too."""


def thread_flag_problem(option: str, given: float) -> str | None:
    """Why a thread flag's value ``given`` is out of its bounds, or None (in bounds, or a
    flag with no bounds)."""
    if option not in THREAD_FLAG_BOUNDS:
        return None
    valid, bound = THREAD_FLAG_BOUNDS[option]
    return None if valid(given) else f"{bound}, got {given}"


def main(argv: Sequence[str]) -> int:
    """Run the benchmark and print the table; 0."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--algorithms", default="1,2,3")
    ap.add_argument("--max-time", type=float, default=600.0, help="simulated s per run")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "knot-success")
    ap.add_argument("--backend", default=None, help="default pybullet-surgical(-stitched)")
    ap.add_argument("--single", action="store_true", help="one throw, stitched start")
    ap.add_argument("--base-seed", type=int, default=0)
    ap.add_argument("--no-perturb", action="store_true")
    ap.add_argument(
        "--only",
        default=None,
        help="apply only these perturbations, comma-separated from base,friction,stiffness "
        "(each run keeps its own draw of them; the others stay nominal)",
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a procedure parameter for every run (repeatable), e.g. register=true; "
        "give --resume only with the same values",
    )
    ap.add_argument(
        "--base-part",
        choices=BASE_PARTS,
        default="all",
        help="of each base error apply all, its common part (the robots' mean: relative "
        "poses exact) or its relative part (each minus the mean)",
    )
    ap.add_argument(
        "--base-error-as",
        choices=BASE_ERROR_AS,
        default="placement",
        help="each base error as a placement (the robot built off its declared base) or a "
        "calibration error (the robot where declared, the skills' belief off); give "
        "--resume only with the same choice",
    )
    ap.add_argument(
        "--bending-stiffness", type=float, default=None, help="nominal thread EI [N*m^2]"
    )
    ap.add_argument(
        "--wound-gap",
        type=float,
        default=None,
        help="the tissue pad's wound width as the thread's contacts meet it [mm] (default: "
        "the backend's, 1 mm, which pinches the 1.8 mm model thread; 0: the wound closed); "
        "give --resume only with the same value",
    )
    ap.add_argument(
        "--wound-depth",
        type=float,
        default=None,
        help="how deep the pad's wound stays open [mm], a floor below (default: through "
        "the pad); give --resume only with the same value",
    )
    ap.add_argument(
        "--pad-clear-depth",
        type=float,
        default=None,
        help="a thread capsule leaving the stitch channel inside the pad gets its contacts "
        "with the pad back only once it lies no deeper than this in it [mm] (default: at "
        "once; 0.1 turns the wait on); give --resume only with the same value",
    )
    ap.add_argument(
        "--thread-contact-stiffness",
        type=float,
        default=None,
        help="every contact of the thread's capsules a spring of this stiffness [N/m] "
        "(damping 5 N*s/m; default: rigid contacts); give --resume only with the same value",
    )
    ap.add_argument(
        "--smooth-joints",
        action="store_true",
        help="the thread's capsules reach over its joints (a round tube through each, no "
        "groove; default: tip to tip); give --resume only with the same choice",
    )
    ap.add_argument(
        "--thread-damping",
        type=float,
        default=None,
        help="how fast the thread's free motion dies away [1/s] (default: the scene's, "
        "else 0.5); give --resume only with the same value",
    )
    ap.add_argument(
        "--thread-weight",
        type=float,
        default=None,
        help="the mass per length whose weight the thread keeps [g/m] (default: the "
        "scene's, else 0.1); give --resume only with the same value",
    )
    ap.add_argument(
        "--runs",
        default=None,
        help="run only these runs of the --seeds draws, e.g. 1,2,5-9 (each keeps its own "
        "seed and perturbation)",
    )
    ap.add_argument(
        "--resume",
        action="store_true",
        help="keep the rows already in OUT/results.csv and run only the missing runs",
    )
    args = ap.parse_args(list(argv))
    if args.backend is None:
        args.backend = "pybullet-surgical-stitched" if args.single else "pybullet-surgical"
    try:
        algorithms = [int(a) for a in args.algorithms.split(",") if a.strip()]
    except ValueError:
        ap.error(f"--algorithms: comma-separated integers, got {args.algorithms!r}")
    if not algorithms or any(a not in (1, 2, 3) for a in algorithms) or args.seeds < 1:
        ap.error("--algorithms from 1,2,3 and --seeds >= 1")
    accepted = accepted_options(args.backend)
    _, applied, missing = backend_options(draw_perturbation(np.random.default_rng(0)), accepted)
    perturb = not args.no_perturb
    only = None
    if args.only is not None:
        try:
            only = parse_only(args.only)
        except ValueError as exc:
            ap.error(f"--only: {exc}")
        if args.no_perturb:
            ap.error(f"--only {args.only!r}: not with --no-perturb")
        applied = tuple(a for a in applied if a in {KINDS[k] for k in only})
        missing = tuple(m for m in missing if m in {KINDS[k] for k in only})
    if args.base_part != "all" and not perturb:
        ap.error("--base-part splits the perturbations' base error: not with --no-perturb")
    jobs = make_jobs(
        algorithms, args.seeds, base_seed=args.base_seed, backend=args.backend, out=args.out,
        max_time_s=args.max_time, perturb=perturb, accepted=accepted, only=only,
        base_part=args.base_part,
    )  # fmt: skip
    if any("=" not in v for v in args.set):
        ap.error(f"--set: NAME=VALUE, got {args.set!r}")
    jobs = [j._replace(single=args.single, sets=tuple(args.set)) for j in jobs]
    calibrated = args.base_error_as == "calibration"
    if calibrated:
        if not perturb:
            ap.error("--base-error-as calibration: not with --no-perturb")
        jobs = [as_calibration(j) for j in jobs]
    if args.runs is not None:
        try:
            chosen = parse_runs(args.runs, args.seeds)
        except ValueError as exc:
            ap.error(f"--runs: {exc}")
        jobs = [j for j in jobs if j.run in chosen]
    nominal_ei = args.bending_stiffness
    if nominal_ei is not None:
        if "suture_bending_stiffness" not in accepted:
            ap.error(
                f"--bending-stiffness: backend {args.backend} takes no suture_bending_stiffness"
            )
        jobs = [
            j._replace(options={**j.options, "suture_bending_stiffness": nominal_ei}) for j in jobs
        ]
    lengths = (
        ("--wound-gap", "wound_gap"),
        ("--wound-depth", "wound_depth"),
        ("--pad-clear-depth", "pad_clear_depth"),
    )
    for flag, key in lengths:
        mm = getattr(args, key)
        if mm is None:
            continue
        if key not in accepted:
            ap.error(f"{flag}: backend {args.backend} takes no {key}")
        if not (mm > 0 if key == "wound_depth" else mm >= 0):
            bound = "> 0" if key == "wound_depth" else ">= 0"
            ap.error(f"{flag}: a length {bound} [mm], got {mm}")
        jobs = [j._replace(options={**j.options, key: mm * 1e-3}) for j in jobs]
    stiffness, damping, weight = (
        args.thread_contact_stiffness,
        args.thread_damping,
        args.thread_weight,
    )
    thread = [  # flag, backend option, value given, its value for the backend
        ("--thread-contact-stiffness", "thread_contact_stiffness", stiffness, stiffness),
        ("--smooth-joints", "thread_smooth_joints", args.smooth_joints or None, True),
        ("--thread-damping", "thread_damping", damping, damping),
        ("--thread-weight", "thread_weight", weight, None if weight is None else weight * 1e-3),
    ]  # fmt: skip
    for flag, option, given, value in thread:
        if given is None:
            continue
        if option not in accepted:
            ap.error(f"{flag}: backend {args.backend} takes no {option}")
        if (problem := thread_flag_problem(option, given)) is not None:
            ap.error(f"{flag}: {problem}")
        jobs = [j._replace(options={**j.options, option: value}) for j in jobs]
    what = "knot-algorithm-N.yaml (one throw)" if args.single else "square-knot.yaml"
    if args.set:
        what += " --set " + " --set ".join(args.set)
    if args.wound_gap is not None:
        what += f", wound gap {args.wound_gap:g} mm"
    if args.wound_depth is not None:
        what += f", wound open {args.wound_depth:g} mm deep"
    if args.pad_clear_depth is not None:
        what += f", pad contacts back within {args.pad_clear_depth:g} mm"
    if stiffness is not None:
        what += f", thread contacts {stiffness:g} N/m"
    if args.smooth_joints:
        what += ", smooth joints"
    if damping is not None:
        what += f", thread damping {damping:g} /s"
    if weight is not None:
        what += f", thread weight {weight:g} g/m"
    runs = f"{args.seeds} run(s)" if args.runs is None else f"runs {args.runs} of {args.seeds}"
    print(
        f"{what} on {args.backend}: {runs} per algorithm "
        f"{algorithms}, max {args.max_time:g} s simulated each, {args.workers} worker(s)"
    )
    if perturb:
        print(f"perturbations applied: {', '.join(applied) or 'none'}")
        if only is not None:
            print(f"  (--only {','.join(only)}: the others stay nominal)")
        if args.base_part != "all":
            print(f"  (--base-part {args.base_part}: that part of each base error only)")
        if calibrated and (only is None or "base" in only):
            print("  (base error as a calibration error: the robots stand where declared)")
        if missing:
            print(f"NOT applied (the backend takes no option for them): {', '.join(missing)}")
        if (
            "stiffness_scale" in applied
            and not nominal_ei
            and "suture_bending_stiffness" in accepted
        ):
            print(
                "NOTE: the stiffness factor scales the thread's bending stiffness EI, 0 by "
                "default:\n      no effect unless --bending-stiffness sets a nominal EI"
            )
    else:
        print("perturbations: off (--no-perturb)")
    t0 = time.perf_counter()
    results = args.out / "results.csv"
    rows: list[Row] = []
    if args.resume:
        try:
            kept = read_csv(results)
        except ValueError as exc:
            ap.error(f"--resume: {exc}")
        wanted = {_job_key(j) for j in jobs}
        rows = [r for r in kept if _row_key(r) in wanted]
        jobs = pending(jobs, rows)
        print(f"resuming: {len(rows)} run(s) kept from {results}, {len(jobs)} to run")
    ctx = get_context("spawn")
    with ProcessPoolExecutor(args.workers, mp_context=ctx) as pool:
        futures = [pool.submit(run_one, j) for j in jobs]
        for fut in as_completed(futures):
            row = fut.result()
            rows.append(row)
            write_csv(rows, results)  # after every run: a stopped sweep keeps its rows
            note = f"  {row.error}" if row.error else ""
            if not row.success and row.last_fault and not row.error:
                note = f"  [{row.last_fault[:90]}]"
            print(
                f"  alg {row.algorithm} run {row.run:3d} seed {row.seed:10d}: {row.outcome:9s} "
                f"knot {row.knot_type or '-':12s} {'OK ' if row.success else 'NO '}"
                f"{row.sim_time_s:6.1f} s sim {row.wall_time_s:6.1f} s wall{note}",
                flush=True,
            )
    write_csv(rows, results)
    print(
        f"\n{'algorithm':>9s} {'runs':>5s} {'success':>8s} {'rate':>6s} "
        f"{'95% Wilson':>15s} {'paths':>5s}  outcomes / knots"
    )
    for t in tally(rows):
        print(
            f"{t.algorithm:9d} {t.runs:5d} {t.successes:8d} {t.rate:6.0%} "
            f"[{t.low:5.0%}, {t.high:5.0%}] {t.paths:5d}  {t.outcomes} / {t.knots}"
        )
    for alg, steps in stops(rows).items():
        print(f"algorithm {alg}, where the failed runs stopped: {steps}")
    for alg, lays in square_lays(rows).items():
        print(f"algorithm {alg}, how the successes lie: {lays}")
    for alg, (peak, run, estimate) in true_peaks(rows).items():
        at = next((r.peak_true_at for r in rows if (r.algorithm, r.run) == (alg, run)), "")
        print(
            f"algorithm {alg}, true tension peak {peak:.2f} N (run {run}"
            f"{', ' + at if at else ''}); the base estimates' peak {estimate:.2f} N"
        )
    print(f"[{time.perf_counter() - t0:.0f} s wall; rows in {args.out / 'results.csv'}]")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
