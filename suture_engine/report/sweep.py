"""``suture sweep``: run a procedure many times with varied parameters.

Each run ``i`` gets its own reproducible random stream,
``numpy.random.SeedSequence([base_seed, i])``: it draws the run's seed and the
values of the varied parameters, so a run's inputs depend only on the base seed
and its index (not on the number of workers, the order of completion, or an
interruption). Runs execute in a process pool (``concurrent.futures`` with the
``spawn`` context) or, when asked, on Ray (the ``[ray]`` extra, imported lazily).

``results.csv`` gets one row per finished run, appended and flushed as each run
ends, so an interrupted sweep resumes where it stopped: the runs already in the
file are not run again. ``sweep.json`` records the sweep's inputs so that a
resume with different inputs is refused. At the end, ``summary.json`` holds the
success rate per condition with its Wilson score interval, tension statistics
and durations, and ``sweep.png`` plots them.

Variation specs (``--vary``)::

    name=normal(mu, sigma)      mu, sigma: numbers with an optional unit (sigma >= 0)
    name=uniform(a, b)          a <= b, same unit
    name=choice(a, b, ...)      values passed as they are written (one per condition)
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import shutil
import tempfile
from collections import Counter
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from statistics import NormalDist
from typing import Any, NamedTuple

from suture_engine.errors import SutureError

__all__ = [
    "CSV_FIELDS",
    "RunJob",
    "RunRow",
    "SweepConfig",
    "SweepError",
    "SweepResult",
    "VarySpec",
    "VarySpecError",
    "condition_of",
    "make_jobs",
    "parse_vary",
    "read_results",
    "run_job",
    "run_sweep",
    "summarise",
    "wilson_interval",
]

CSV_FIELDS: tuple[str, ...] = (
    "run",
    "seed",
    "condition",
    "outcome",
    "final_state",
    "knot_type",
    "max_tension_N",
    "sim_time_s",
    "wall_time_s",
    "retries",
    "violations",
    "error",
)
"""The fixed columns of ``results.csv``; one ``vary:<name>`` column per varied
parameter follows ``seed``."""

_KINDS = {"normal": "normal(mu, sigma)", "uniform": "uniform(a, b)", "choice": "choice(a, b, ...)"}
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NUMBER = re.compile(
    r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\s\d.,()+-][^\s,()]*)?\s*$"
)


class VarySpecError(SutureError):
    """A ``--vary`` spec that cannot be parsed.

    Attributes:
        spec: the whole spec as given.
        position: 0-based character position of the problem in ``spec``.
        expected: what was expected there.
    """

    code = "bad-vary"

    def __init__(self, spec: str, position: int, expected: str) -> None:
        self.spec = spec
        self.position = position
        self.expected = expected
        caret = " " * position + "^"
        super().__init__(
            f"--vary {spec!r}: at column {position + 1}: expected {expected}\n  {spec}\n  {caret}"
        )


class SweepError(SutureError):
    """A sweep that cannot start or resume (Ray missing, another sweep's results).

    Attributes:
        reason: a short explanation.
    """

    code = "sweep"

    def __init__(self, reason: str) -> None:
        self.reason = reason
        super().__init__(reason)


@dataclass(frozen=True)
class VarySpec:
    """One varied parameter.

    Attributes:
        name: the procedure parameter (as for ``--set``).
        kind: ``normal``, ``uniform`` or ``choice``.
        numbers: the distribution's two numbers (normal: mu, sigma; uniform: a, b).
        unit: the unit written after the numbers (``"mm"``), or ``""``.
        choices: the values of ``choice``, as written.
        text: the spec as given.
    """

    name: str
    kind: str
    numbers: tuple[float, ...] = ()
    unit: str = ""
    choices: tuple[str, ...] = ()
    text: str = ""

    def sample(self, rng: Any) -> str:
        """A value for ``--set``, drawn with the numpy Generator ``rng``."""
        if self.kind == "choice":
            return self.choices[int(rng.integers(len(self.choices)))]
        a, b = self.numbers
        value = float(rng.normal(a, b)) if self.kind == "normal" else float(rng.uniform(a, b))
        text = repr(round(value, 12))
        return f"{text} {self.unit}" if self.unit else text


def _split_args(spec: str, start: int, end: int) -> list[tuple[str, int]]:
    """The comma-separated arguments between ``start`` and ``end`` with their positions."""
    out: list[tuple[str, int]] = []
    pos = start
    for piece in spec[start:end].split(","):
        out.append((piece, pos))
        pos += len(piece) + 1
    return out


def parse_vary(spec: str) -> VarySpec:
    """Parse ``name=normal(mu,sigma)``, ``name=uniform(a,b)`` or ``name=choice(a,b,...)``.

    Raises:
        VarySpecError: with the position of the problem and what was expected.
    """
    eq = spec.find("=")
    if eq < 0:
        raise VarySpecError(spec, len(spec), "'=' after a parameter name (name=kind(...))")
    name = spec[:eq].strip()
    if not _NAME.fullmatch(name):
        raise VarySpecError(spec, 0, "a parameter name (letters, digits, _) before '='")
    rest = spec[eq + 1 :]
    kind_match = re.match(r"\s*([A-Za-z_]+)\s*", rest)
    kind = kind_match.group(1) if kind_match else ""
    kind_pos = eq + 1 + (kind_match.start(1) if kind_match else 0)
    if kind not in _KINDS:
        raise VarySpecError(spec, kind_pos, f"one of {', '.join(_KINDS.values())}")
    open_pos = eq + 1 + (kind_match.end() if kind_match else 0)
    if open_pos >= len(spec) or spec[open_pos] != "(":
        raise VarySpecError(spec, open_pos, f"'(' after {kind}: {_KINDS[kind]}")
    close_pos = spec.rfind(")")
    if close_pos < open_pos:
        raise VarySpecError(spec, len(spec), f"')' closing {_KINDS[kind]}")
    if spec[close_pos + 1 :].strip():
        raise VarySpecError(spec, close_pos + 1, "nothing after ')'")
    args = _split_args(spec, open_pos + 1, close_pos)
    for text, pos in args:
        if not text.strip():
            raise VarySpecError(spec, pos, "a value (an empty argument)")
    if kind == "choice":
        return VarySpec(name, kind, choices=tuple(a.strip() for a, _ in args), text=spec)
    if len(args) != 2:
        where = args[2][1] if len(args) > 2 else close_pos
        raise VarySpecError(spec, where, f"exactly two numbers: {_KINDS[kind]}")
    numbers: list[float] = []
    units: list[str] = []
    for text, pos in args:
        m = _NUMBER.fullmatch(text)
        if m is None:
            raise VarySpecError(
                spec, pos + len(text) - len(text.lstrip()), "a number, e.g. 2 or 2 mm"
            )
        numbers.append(float(m.group(1)))
        units.append(m.group(2) or "")
    if units[0] != units[1] and units[0] and units[1]:
        raise VarySpecError(spec, args[1][1], f"the same unit as the first number ({units[0]})")
    unit = units[0] or units[1]
    if not all(math.isfinite(v) for v in numbers):
        raise VarySpecError(spec, args[0][1], "finite numbers")
    if kind == "normal" and numbers[1] < 0:
        raise VarySpecError(spec, args[1][1], "sigma >= 0")
    if kind == "uniform" and numbers[0] > numbers[1]:
        raise VarySpecError(spec, args[1][1], f"b >= a (a = {numbers[0]:g})")
    return VarySpec(name, kind, (numbers[0], numbers[1]), unit, text=spec)


class RunJob(NamedTuple):
    """One run of a sweep (picklable; what a worker gets).

    Attributes:
        run: the run index (0-based).
        seed: the run's simulation seed.
        values: the varied parameters' values, as ``--set`` text.
        procedure: the procedure file.
        sets: fixed ``name=value`` overrides.
        out_dir: the run's output folder.
        max_time_s: simulated time limit [s].
    """

    run: int
    seed: int
    values: Mapping[str, str]
    procedure: str
    sets: tuple[str, ...]
    out_dir: str
    max_time_s: float


class RunRow(NamedTuple):
    """One row of ``results.csv``.

    Attributes:
        run: the run index.
        seed: the run's seed.
        values: the varied values (``--set`` text).
        condition: the choice-varied values that define the run's condition.
        outcome: ``succeeded``, ``failed``, ``aborted`` or ``error``.
        final_state: the automaton's last state.
        knot_type: the knot type from the run's evaluation, ``""`` when none.
        max_tension_N: largest estimated tension [N] (NaN after an error).
        sim_time_s: simulated time [s].
        wall_time_s: wall time of the run [s].
        retries: retries made.
        violations: invariant violations.
        error: the error message when ``outcome`` is ``error``.
    """

    run: int
    seed: int
    values: Mapping[str, str]
    condition: str
    outcome: str
    final_state: str
    knot_type: str
    max_tension_N: float
    sim_time_s: float
    wall_time_s: float
    retries: int
    violations: int
    error: str


@dataclass(frozen=True)
class SweepConfig:
    """The inputs of a sweep (saved as ``sweep.json``; a resume must match them).

    Attributes:
        procedure: the procedure file.
        runs: the number of runs.
        vary: the variation specs.
        base_seed: the base seed.
        sets: fixed ``name=value`` overrides.
        max_time_s: simulated time limit per run [s].
    """

    procedure: Path
    runs: int
    vary: tuple[VarySpec, ...]
    base_seed: int = 0
    sets: tuple[str, ...] = ()
    max_time_s: float = 300.0

    def identity(self) -> dict[str, Any]:
        """What must not change between a sweep and its resume."""
        return {
            "procedure": str(self.procedure.resolve()),
            "vary": [v.text for v in self.vary],
            "base_seed": self.base_seed,
            "sets": list(self.sets),
            "max_time_s": self.max_time_s,
        }


@dataclass(frozen=True)
class SweepResult:
    """A finished sweep.

    Attributes:
        rows: every run's row, by run index.
        ran: the runs executed by this call (the others were already done).
        summary: what ``summary.json`` holds.
        out_dir: the output folder.
    """

    rows: list[RunRow]
    ran: list[int]
    summary: dict[str, Any]
    out_dir: Path
    files: dict[str, Path] = field(default_factory=dict)


def condition_of(vary: Sequence[VarySpec], values: Mapping[str, str]) -> str:
    """The condition of a run: its choice-varied values (``"all"`` without choices)."""
    parts = [f"{v.name}={values[v.name]}" for v in vary if v.kind == "choice"]
    return ", ".join(parts) if parts else "all"


def make_jobs(config: SweepConfig, out_dir: Path) -> list[RunJob]:
    """The sweep's runs, each with its seed and values from ``SeedSequence([base, i])``."""
    import numpy as np

    jobs = []
    for i in range(config.runs):
        ss = np.random.SeedSequence([config.base_seed, i])
        seed = int(ss.generate_state(1, dtype=np.uint32)[0] & 0x7FFFFFFF)
        rng = np.random.default_rng(ss.spawn(1)[0])
        values = {v.name: v.sample(rng) for v in config.vary}
        jobs.append(
            RunJob(
                i,
                seed,
                values,
                str(config.procedure),
                config.sets,
                str(out_dir / "runs" / f"run-{i:05d}"),
                config.max_time_s,
            )
        )
    return jobs


def run_job(job: RunJob) -> RunRow:
    """Run one job (in a worker process); a typed engine error becomes an ``error`` row.

    Raises:
        KeyboardInterrupt: the run was interrupted (Ctrl-C); it is not a result.
    """
    import contextlib
    import io
    import time

    from suture_engine.runtime.run import run_procedure

    sets = [*job.sets, *(f"{k}={v}" for k, v in job.values.items())]
    shutil.rmtree(job.out_dir, ignore_errors=True)  # a run cut short by an interruption
    start = time.perf_counter()
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            result = run_procedure(
                job.procedure, seed=job.seed, sets=sets, out=job.out_dir, max_time_s=job.max_time_s
            )
    except SutureError as exc:
        return RunRow(
            job.run, job.seed, dict(job.values), "", "error", "", "", math.nan,
            0.0, time.perf_counter() - start, 0, 0, f"{exc.code}: {exc.message}",
        )  # fmt: skip
    s = result.summary
    if str(s.metrics.get("stopped", "")).startswith("interrupted"):
        # Ctrl-C reached the run: it did not finish, so it must not count as done.
        raise KeyboardInterrupt
    knot = _knot_type(s.knot)
    return RunRow(
        job.run, job.seed, dict(job.values), "", s.outcome, s.final_state, str(knot or ""),
        float(s.max_tension_N), float(s.sim_time_s), float(s.wall_time_s), int(s.retries),
        len(s.violations), "",
    )  # fmt: skip


def _knot_type(knot: object) -> str:
    """The run's knot type: ``type`` of one knot, the types joined by ``+`` for one per stitch."""
    if isinstance(knot, Mapping):
        return str(knot.get("type", "") or "")
    if isinstance(knot, list):
        return "+".join(str(k.get("type", "") or "?") for k in knot if isinstance(k, Mapping))
    return ""


# -- results.csv ----------------------------------------------------------------------------


def _header(vary: Sequence[VarySpec]) -> list[str]:
    return [*CSV_FIELDS[:2], *(f"vary:{v.name}" for v in vary), *CSV_FIELDS[2:]]


def _row_dict(row: RunRow, vary: Sequence[VarySpec]) -> dict[str, Any]:
    out: dict[str, Any] = {"run": row.run, "seed": row.seed}
    out.update({f"vary:{v.name}": row.values[v.name] for v in vary})
    for name in CSV_FIELDS[2:]:
        value = getattr(row, name)
        out[name] = "" if isinstance(value, float) and math.isnan(value) else value
    return out


def read_results(path: Path, vary: Sequence[VarySpec]) -> dict[int, RunRow]:
    """The finished runs of a ``results.csv`` (a torn last line, from a kill, is ignored).

    Raises:
        SweepError: the header is not this sweep's.
    """
    if not path.is_file():
        return {}
    text = path.read_text(encoding="utf-8")
    if not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
    lines = text.splitlines()
    if not lines:
        return {}
    reader = csv.DictReader(lines)
    if reader.fieldnames != _header(vary):
        raise SweepError(
            f"{path}: columns {reader.fieldnames} are not this sweep's {_header(vary)}; "
            "use another --out folder"
        )
    rows: dict[int, RunRow] = {}
    for rec in reader:

        def num(key: str, rec: dict[str, str] = rec) -> float:
            return float(rec[key]) if rec[key] not in ("", None) else math.nan

        rows[int(rec["run"])] = RunRow(
            int(rec["run"]), int(rec["seed"]), {v.name: rec[f"vary:{v.name}"] for v in vary},
            rec["condition"], rec["outcome"], rec["final_state"], rec["knot_type"],
            num("max_tension_N"), num("sim_time_s"), num("wall_time_s"), int(rec["retries"]),
            int(rec["violations"]), rec["error"],
        )  # fmt: skip
    return rows


class _CsvAppender:
    """Appends rows to ``results.csv``, flushing each to disk."""

    def __init__(self, path: Path, vary: Sequence[VarySpec]) -> None:
        self.vary = vary
        fresh = not path.is_file() or path.stat().st_size == 0
        if not fresh:  # drop a torn last line left by a kill
            data = path.read_bytes()
            cut = data.rfind(b"\n") + 1
            if cut != len(data):
                with open(path, "r+b") as fh:
                    fh.truncate(cut)
        self.fh = open(path, "a", encoding="utf-8", newline="")
        self.writer = csv.DictWriter(self.fh, fieldnames=_header(vary), lineterminator="\n")
        if fresh:
            self.writer.writeheader()
            self._sync()

    def _sync(self) -> None:
        self.fh.flush()
        os.fsync(self.fh.fileno())

    def append(self, row: RunRow) -> None:
        self.writer.writerow(_row_dict(row, self.vary))
        self._sync()

    def close(self) -> None:
        self.fh.close()


# -- statistics -----------------------------------------------------------------------------


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion.

    ``(p + z^2/2n +- z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n)`` with ``p = k/n`` and
    ``z`` the ``(1 + confidence)/2`` normal quantile (Wilson 1927).

    Args:
        successes: successes k.
        n: trials (``n = 0`` gives ``(0, 1)``).
        confidence: the interval's confidence level.

    Raises:
        ValueError: ``k`` outside ``[0, n]`` or a confidence outside ``(0, 1)``.
    """
    if n < 0 or not 0 <= successes <= n:
        raise ValueError(f"need 0 <= successes <= n, found {successes} of {n}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), found {confidence}")
    if n == 0:
        return 0.0, 1.0
    z = NormalDist().inv_cdf(0.5 + confidence / 2.0)
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def _stats(values: Sequence[float]) -> dict[str, float | None]:
    import numpy as np

    arr = np.array([v for v in values if math.isfinite(v)], dtype=float)
    if arr.size == 0:
        return {"n": 0, "mean": None, "std": None, "min": None, "median": None, "max": None}
    return {
        "n": int(arr.size),
        "mean": float(arr.mean()),
        "std": float(arr.std(ddof=1)) if arr.size > 1 else 0.0,
        "min": float(arr.min()),
        "median": float(np.median(arr)),
        "max": float(arr.max()),
    }


def summarise(rows: Sequence[RunRow], confidence: float = 0.95) -> dict[str, Any]:
    """Success rate with its Wilson interval per condition, tension and duration statistics."""
    conditions: dict[str, list[RunRow]] = {}
    for row in rows:
        conditions.setdefault(row.condition, []).append(row)
    per_condition = {}
    for name, group in sorted(conditions.items()):
        k = sum(r.outcome == "succeeded" for r in group)
        lo, hi = wilson_interval(k, len(group), confidence)
        per_condition[name] = {
            "runs": len(group),
            "succeeded": k,
            "success_rate": k / len(group),
            "wilson_low": lo,
            "wilson_high": hi,
            "outcomes": dict(sorted(Counter(r.outcome for r in group).items())),
            "knot_types": dict(sorted(Counter(r.knot_type for r in group).items())),
            "max_tension_N": _stats([r.max_tension_N for r in group]),
        }  # fmt: skip
    return {
        "runs": len(rows),
        "confidence": confidence,
        "conditions": per_condition,
        "max_tension_N": _stats([r.max_tension_N for r in rows]),
        "sim_time_s": _stats([r.sim_time_s for r in rows]),
        "wall_time_s": _stats([r.wall_time_s for r in rows]),
        "errors": sum(r.outcome == "error" for r in rows),
    }


def _plot(
    rows: Sequence[RunRow], summary: Mapping[str, Any], vary: Sequence[VarySpec], path: Path
) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(14, 3.8), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax_rate, ax_t, ax_v = fig.subplots(1, 3)
    names = list(summary["conditions"])
    rates = [summary["conditions"][c]["success_rate"] for c in names]
    lows = [r - summary["conditions"][c]["wilson_low"] for r, c in zip(rates, names, strict=True)]
    highs = [summary["conditions"][c]["wilson_high"] - r for r, c in zip(rates, names, strict=True)]
    ax_rate.bar(range(len(names)), rates, yerr=[lows, highs], capsize=5, color="#1f77b4")
    ax_rate.set_xticks(range(len(names)), names, rotation=20, ha="right", fontsize=8)
    for i, c in enumerate(names):
        k, n = summary["conditions"][c]["succeeded"], summary["conditions"][c]["runs"]
        ax_rate.annotate(f"{k}/{n}", (i, rates[i]), ha="center", va="bottom", fontsize=8,
                         xytext=(0, 3), textcoords="offset points")  # fmt: skip
    ax_rate.set_ylim(0, 1.1)
    ax_rate.set_ylabel("success rate")
    ax_rate.set_title(f"Success rate, {summary['confidence']:.0%} Wilson interval")
    tensions = [r.max_tension_N for r in rows if math.isfinite(r.max_tension_N)]
    if tensions:
        ax_t.hist(tensions, bins=min(20, max(5, len(tensions) // 2)), color="#ff7f0e")
        ax_t.set_xlabel("max tension [N]")
        ax_t.set_ylabel("runs")
    else:
        ax_t.text(0.5, 0.5, "no tension data", ha="center", va="center", transform=ax_t.transAxes)
    ax_t.set_title("Largest estimated tension per run")
    numeric = next((v for v in vary if v.kind != "choice"), None)
    if numeric is None:
        ax_v.text(0.5, 0.5, "no numeric --vary", ha="center", va="center", transform=ax_v.transAxes)
    else:
        for outcome, colour in (("succeeded", "#2ca02c"), ("failed", "#d62728"),
                                ("aborted", "#ff7f0e"), ("error", "#7f7f7f")):  # fmt: skip
            pts = [
                (float(r.values[numeric.name].split()[0]), r.max_tension_N)
                for r in rows
                if r.outcome == outcome
            ]
            if pts:
                xs, ys = zip(*pts, strict=True)
                ax_v.plot(xs, [0.0 if math.isnan(y) else y for y in ys], "o", color=colour,
                          ms=4, ls="", label=f"{outcome} ({len(pts)})")  # fmt: skip
        ax_v.set_xlabel(f"{numeric.name}" + (f" [{numeric.unit}]" if numeric.unit else ""))
        ax_v.set_ylabel("max tension [N]")
        ax_v.legend(fontsize=8)
        ax_v.grid(True, alpha=0.3)
    ax_v.set_title("Outcome against the varied value")
    fd, tmp = tempfile.mkstemp(prefix=".sweep-", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, format="png")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _write_json(path: Path, data: Any) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=".json", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(data, fh, indent=2, sort_keys=True, allow_nan=False)
            fh.write("\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


# -- executors ------------------------------------------------------------------------------


def _pool_results(jobs: Sequence[RunJob], workers: int) -> Iterator[RunRow]:
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        pending = {pool.submit(run_job, job) for job in jobs}
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    yield fut.result()
        finally:
            for fut in pending:
                fut.cancel()


def _ray_results(jobs: Sequence[RunJob], address: str) -> Iterator[RunRow]:
    try:
        import ray
    except ImportError:
        raise SweepError(
            "--ray needs Ray, which is not installed: pip install 'suture-engine[ray]'"
        ) from None
    if not ray.is_initialized():
        if address == "local":
            ray.init(include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
    remote = ray.remote(run_job)
    pending = [remote.remote(job) for job in jobs]
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                yield ray.get(ref)
    finally:
        for ref in pending:
            ray.cancel(ref)


def run_sweep(
    config: SweepConfig,
    out_dir: str | os.PathLike[str],
    *,
    workers: int = 1,
    ray_address: str | None = None,
    on_row: Callable[[RunRow], None] | None = None,
    runner: Callable[[Sequence[RunJob]], Iterator[RunRow]] | None = None,
) -> SweepResult:
    """Run (or resume) a sweep; write ``results.csv``, ``summary.json``, ``sweep.png``.

    Args:
        config: the sweep's inputs.
        out_dir: the output folder.
        workers: processes of the pool (ignored with Ray).
        ray_address: run on Ray: ``local`` (a local instance), ``auto`` or an address.
        on_row: called with each row as it is written (progress).
        runner: runs the jobs and yields rows (default: the pool or Ray).

    Raises:
        SweepError: ``out_dir`` holds another sweep, or Ray is missing.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    identity = config.identity()
    sweep_json = out / "sweep.json"
    if sweep_json.is_file():
        previous = json.loads(sweep_json.read_text(encoding="utf-8"))
        if previous.get("identity") != identity:
            raise SweepError(
                f"{out} holds another sweep ({sweep_json} differs); use another --out folder"
            )
    results_csv = out / "results.csv"
    done = read_results(results_csv, config.vary)
    _write_json(sweep_json, {"identity": identity, "runs": config.runs})
    jobs = make_jobs(config, out)
    todo = [job for job in jobs if job.run not in done]
    if runner is None:
        if ray_address is not None:
            addr = ray_address

            def runner(js: Sequence[RunJob]) -> Iterator[RunRow]:
                return _ray_results(js, addr)
        elif workers <= 1:

            def runner(js: Sequence[RunJob]) -> Iterator[RunRow]:
                return (run_job(j) for j in js)
        else:

            def runner(js: Sequence[RunJob]) -> Iterator[RunRow]:
                return _pool_results(js, workers)

    appender = _CsvAppender(results_csv, config.vary)
    ran: list[int] = []
    try:
        for row in runner(todo) if todo else iter(()):
            row = row._replace(condition=condition_of(config.vary, row.values))
            appender.append(row)
            done[row.run] = row
            ran.append(row.run)
            if on_row is not None:
                on_row(row)
    finally:
        appender.close()
    rows = [done[i] for i in sorted(done) if i < config.runs]
    summary = summarise(rows)
    files = {"results": results_csv, "summary": out / "summary.json", "plot": out / "sweep.png"}
    _write_json(files["summary"], summary)
    _plot(rows, summary, config.vary, files["plot"])
    return SweepResult(rows, ran, summary, out, files)
