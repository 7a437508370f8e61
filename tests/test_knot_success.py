"""benchmarks/knot_success.py: perturbation draws, reproducible jobs, success rule, tally.

Oracles: the sample statistics of many draws against the stated distributions, and
scipy's own Wilson interval (``binomtest(...).proportion_ci(method="wilson")``).
The physics runs themselves are the benchmark's business (too long for a test).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from benchmark_modules import load_benchmark

ks = load_benchmark("knot_success")


def test_perturbation_draws_follow_the_stated_distributions() -> None:
    rng = np.random.default_rng(123)
    draws = [ks.draw_perturbation(rng) for _ in range(4000)]
    base = np.array([d.base_error[r] for d in draws for r in ks.ROBOTS])  # (8000, 3)
    assert base.shape == (8000, 3)
    # sigma = 1 mm per component: the sample std within ~4 % (8000 samples), mean ~ 0
    np.testing.assert_allclose(base.std(axis=0), 1e-3, rtol=0.04)
    np.testing.assert_allclose(base.mean(axis=0), 0.0, atol=4 * 1e-3 / math.sqrt(8000))
    fr = np.array([d.friction_scale for d in draws])
    st = np.array([d.stiffness_scale for d in draws])
    assert fr.min() >= 0.7 and fr.max() <= 1.3 and fr.max() - fr.min() > 0.58
    assert st.min() >= 0.8 and st.max() <= 1.2 and st.max() - st.min() > 0.38
    # uniform: variance (b - a)^2 / 12
    assert fr.var() == pytest.approx(0.6**2 / 12, rel=0.08)
    assert st.var() == pytest.approx(0.4**2 / 12, rel=0.08)


def _jobs(algorithms: list[int], accepted: set[str], perturb: bool = True) -> list:  # type: ignore[type-arg]
    return ks.make_jobs(
        algorithms, 3, base_seed=7, backend="x", out=Path("/tmp/unused"), max_time_s=10.0,
        perturb=perturb, accepted=accepted,
    )  # fmt: skip


def test_a_runs_inputs_do_not_depend_on_the_other_algorithms() -> None:
    alone = _jobs([2], set())
    together = [j for j in _jobs([1, 2, 3], set()) if j.algorithm == 2]
    assert [(j.seed, j.perturbation) for j in alone] == [(j.seed, j.perturbation) for j in together]
    seeds = [j.seed for j in _jobs([1, 2, 3], set())]
    assert len(set(seeds)) == len(seeds)
    assert len({j.out_dir for j in _jobs([1, 2, 3], set())}) == 9


def test_an_ablation_keeps_each_runs_own_draw_of_the_kinds_it_names() -> None:
    full = _jobs([2], set())
    common = {"base_seed": 7, "backend": "x", "out": Path("/tmp/unused"), "max_time_s": 10.0,
              "perturb": True, "accepted": set()}  # fmt: skip
    base = ks.make_jobs([2], 3, only=["base"], **common)  # type: ignore[arg-type]
    fric = ks.make_jobs([2], 3, only=["friction"], **common)  # type: ignore[arg-type]
    for f, b, c in zip(full, base, fric, strict=True):
        assert b.seed == c.seed == f.seed
        assert b.perturbation.base_error == f.perturbation.base_error
        assert (b.perturbation.friction_scale, b.perturbation.stiffness_scale) == (1.0, 1.0)
        assert c.perturbation.friction_scale == f.perturbation.friction_scale != 1.0
        assert dict(c.perturbation.base_error) == {} and c.perturbation.stiffness_scale == 1.0


def test_the_base_errors_parts_add_up_and_keep_what_they_say() -> None:
    common = {"base_seed": 0, "backend": "x", "out": Path("/tmp/unused"), "max_time_s": 10.0,
              "perturb": True, "accepted": {"base_error"}, "only": ["base"]}  # fmt: skip
    parts = {p: ks.make_jobs([2], 4, base_part=p, **common) for p in ks.BASE_PARTS}  # type: ignore[arg-type]
    for whole, shared, rel in zip(parts["all"], parts["common"], parts["relative"], strict=True):
        assert whole.seed == shared.seed == rel.seed
        e = {r: np.array(v) for r, v in whole.perturbation.base_error.items()}
        c = {r: np.array(v) for r, v in shared.perturbation.base_error.items()}
        d = {r: np.array(v) for r, v in rel.perturbation.base_error.items()}
        # the common part: both robots displaced alike, so their relative pose is exact
        np.testing.assert_array_equal(c["endobot_1"], c["endobot_2"])
        # the relative part: the same difference between the robots, nothing shared
        np.testing.assert_allclose(
            d["endobot_1"] - d["endobot_2"], e["endobot_1"] - e["endobot_2"], atol=1e-18
        )
        np.testing.assert_allclose(d["endobot_1"] + d["endobot_2"], 0.0, atol=1e-18)
        for r in e:
            np.testing.assert_allclose(c[r] + d[r], e[r], atol=1e-18)
        # the backend receives the part, not the whole
        assert shared.options["base_error"]["endobot_1"] == list(c["endobot_1"])
    with pytest.raises(ValueError, match="base part"):
        ks.split_base(ks.Perturbation(), "half")


def test_set_values_follow_the_runs_own() -> None:
    job = _jobs([2], set())[0]._replace(single=True, sets=("register=true",))
    assert ks.job_sets(job) == ["stitch=false", "register=true"]


def test_command_line_refuses_an_unknown_ablation() -> None:
    for bad in (["--only", "base,gravity"], ["--only", ","], ["--only", "base", "--no-perturb"],
                ["--base-part", "common", "--no-perturb"], ["--base-part", "half"],
                ["--set", "register"]):  # fmt: skip
        with pytest.raises(SystemExit) as err:
            ks.main(["--algorithms", "2", "--seeds", "1", *bad])
        assert err.value.code == 2


def test_perturbations_go_only_where_the_backend_takes_them() -> None:
    pert = ks.draw_perturbation(np.random.default_rng(1))
    opts, applied, missing = ks.backend_options(pert, {"friction_scale", "gui"})
    assert opts == {"friction_scale": pert.friction_scale}
    assert applied == ("friction_scale",) and set(missing) == {"base_error", "stiffness_scale"}
    opts, applied, missing = ks.backend_options(
        pert, {"base_error", "friction_scale", "suture_stiffness_scale"}
    )
    assert missing == () and len(applied) == 3
    assert opts["suture_stiffness_scale"] == pert.stiffness_scale
    assert opts["base_error"]["endobot_1"] == list(pert.base_error["endobot_1"])
    # without perturbation no options at all, and the identity perturbation
    plain = _jobs([1], {"friction_scale"}, perturb=False)
    assert all(j.options == {} and j.perturbation == ks.Perturbation() for j in plain)


def test_success_needs_the_outcome_and_the_ground_truth_square() -> None:
    assert ks.is_success("succeeded", "square")
    assert not ks.is_success("succeeded", "square", bound=False)  # binds no stitch
    assert ks.is_success("succeeded", "trefoil", single=True)
    assert not ks.is_success("succeeded", "square", single=True)
    assert not ks.is_success("succeeded", "trefoil", bound=False, single=True)
    assert ks.binds_stitch({"type": "trefoil", "through_tissue": True})
    assert not ks.binds_stitch({"type": "trefoil", "through_tissue": False})
    assert not ks.binds_stitch({"type": "trefoil"}) and not ks.binds_stitch(None)
    assert not ks.binds_stitch([{"through_tissue": True}, {"through_tissue": False}])
    assert not ks.is_success("succeeded", "granny")
    assert not ks.is_success("succeeded", "")
    assert not ks.is_success("failed", "square")
    assert ks.knot_type({"type": "square", "v3": 0}) == "square"
    assert ks.knot_type(None) == ""
    assert ks.knot_type([{"type": "square"}, {"type": "square"}]) == "square"
    assert ks.knot_type([{"type": "square"}, {"type": "granny"}]) == "mixed"


def _row(alg: int, ok: bool, outcome: str = "succeeded") -> object:
    return ks.Row(alg, 0, 1, outcome, "square" if ok else "granny", ok, 1.0, 1.0, 1.0,
                  1.0, 1.0, 0.5, "")  # fmt: skip


@pytest.mark.parametrize(("k", "n"), [(0, 5), (3, 5), (16, 20), (20, 20)])
def test_tally_rate_and_wilson_interval_match_scipy(k: int, n: int) -> None:
    from scipy.stats import binomtest

    rows = [_row(2, i < k) for i in range(n)] + [_row(3, True)]
    t2, t3 = ks.tally(rows)
    assert (t2.algorithm, t2.runs, t2.successes) == (2, n, k)
    assert t2.rate == pytest.approx(k / n)
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    assert t2.low == pytest.approx(ci.low, abs=1e-9)
    assert t2.high == pytest.approx(ci.high, abs=1e-9)
    assert t2.knots == {k_: v for k_, v in {"square": k, "granny": n - k}.items() if v}
    assert (t3.runs, t3.successes) == (1, 1)


def test_a_run_that_raises_is_a_failed_error_row(tmp_path: Path) -> None:
    job = ks.Job(2, 0, 5, ks.Perturbation(), {}, "no-such-backend", str(tmp_path / "r"), 1.0)
    row = ks.run_one(job)
    assert row.outcome == "error" and not row.success
    assert "no-such-backend" in row.error


def test_results_csv_has_one_row_per_run(tmp_path: Path) -> None:
    rows = [_row(1, False, "failed"), _row(2, True)]
    ks.write_csv(rows, tmp_path / "out" / "results.csv")
    lines = (tmp_path / "out" / "results.csv").read_text().splitlines()
    assert lines[0].split(",")[:4] == ["algorithm", "run", "seed", "outcome"]
    assert len(lines) == 3


def test_results_csv_reads_back_as_the_rows_written(tmp_path: Path) -> None:
    rows = [
        ks.Row(
            2,
            1,
            7,
            "failed",
            "unknot",
            False,
            5.6,
            119.6,
            268.4,
            1.22,
            1.13,
            1.69,
            "",
            "tug: skill-failure:taut after 30.0 mm, more than 9.37 mm",
        ),
        ks.Row(2, 0, 9, "error", "", False, float("nan"), 0.0, 2.5, 0.7, 1.0, 1.4, "E: x, y"),
        ks.Row(3, 0, 4, "succeeded", "square", True, 1.0, 150.0, 300.0, 1.0, 1.0, 0.5, ""),
    ]
    rows = [r._replace(peak_true_tension_N=0.9) if r.error == "" else r for r in rows]
    path = tmp_path / "results.csv"
    ks.write_csv(rows, path)
    back = ks.read_csv(path)
    assert [r.run for r in back] == [0, 1, 0]  # sorted by algorithm, then run
    assert back[1] == rows[0] and back[2] == rows[2]
    assert back[0].error == "E: x, y" and math.isnan(back[0].max_tension_N)
    assert math.isnan(back[0].peak_true_tension_N) and back[1].peak_true_tension_N == 0.9
    assert not list(tmp_path.glob("*.tmp"))
    assert ks.read_csv(tmp_path / "none.csv") == []


def test_the_failed_runs_are_counted_by_the_step_they_stopped_in() -> None:
    def row(run: int, ok: bool, fault: str, error: str = "") -> ks.Row:
        return ks.Row(2, run, run, "succeeded" if ok else "failed", "", ok, 1.0, 1.0, 1.0,
                      1.0, 1.0, 0.0, error, fault)  # fmt: skip

    rows = [
        row(0, False, "mirrored-knot.take-up: skill-failure:not taut within 6.5 mm"),
        row(1, True, "simple-knot.take-up: skill-failure:x"),  # a success is not counted
        row(2, False, "mirrored-knot.take-up: skill-failure:y"),
        row(3, False, "simple-knot.slide-to-tip: emergency:tension"),
        row(4, False, ""),
        row(5, False, "", "RuntimeError: x"),
    ]
    assert ks.stops(rows) == {
        2: {"mirrored-knot.take-up": 2, "simple-knot.slide-to-tip": 1, "-": 1, "error": 1}
    }
    assert ks.stops([row(0, True, "")]) == {}


def test_a_table_written_before_the_last_fault_column_reads_with_it_empty(
    tmp_path: Path,
) -> None:
    path = tmp_path / "results.csv"
    header = ",".join(ks.Row._fields[:-5])  # without last_fault and the later columns
    path.write_text(header + "\n2,3,1695199924,failed,unknot,False,1.59,85.35,137.5,1.0,1.0,0.0,\n")
    (row,) = ks.read_csv(path)
    assert (row.run, row.outcome, row.last_fault) == (3, "failed", "")


def test_a_foreign_results_table_is_refused_with_its_path(tmp_path: Path) -> None:
    path = tmp_path / "results.csv"
    path.write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match=r"results\.csv"):
        ks.read_csv(path)


def test_resume_runs_only_the_runs_without_a_row_of_the_same_seed(tmp_path: Path) -> None:
    jobs = ks.make_jobs([2], 3, base_seed=0, backend="pybullet-surgical-stitched",
                        out=tmp_path, max_time_s=1.0, perturb=True, accepted=set())  # fmt: skip

    def row(job: Any, seed: int, friction: float) -> Any:
        pert = job.perturbation
        base_mm = max(float(np.linalg.norm(v)) * 1e3 for v in pert.base_error.values())
        return ks.Row(2, job.run, seed, "failed", "", False, 0.0, 1.0, 1.0, friction,
                      pert.stiffness_scale, base_mm, "")  # fmt: skip

    f = [j.perturbation.friction_scale for j in jobs]
    # run 0 is done; run 1's row is of another seed (another base seed's run 1); run 2's
    # of another perturbation (an ablation's)
    done = [row(jobs[0], jobs[0].seed, f[0]), row(jobs[1], jobs[1].seed + 1, f[1]),
            row(jobs[2], jobs[2].seed, 1.0)]  # fmt: skip
    assert [j.run for j in ks.pending(jobs, done)] == [1, 2]
    back = tmp_path / "results.csv"
    ks.write_csv(done, back)
    assert [j.run for j in ks.pending(jobs, ks.read_csv(back))] == [1, 2]  # floats read back


def test_chosen_runs_are_read_as_numbers_and_ranges_within_the_draws() -> None:
    assert ks.parse_runs("1,2, 5-7,2", 20) == {1, 2, 5, 6, 7}
    assert ks.parse_runs("0", 1) == {0}
    for bad in ("", "a", "3-1", "-1", "19-20", "20"):
        with pytest.raises(ValueError):
            ks.parse_runs(bad, 20)


def test_command_line_refuses_runs_outside_the_draws(tmp_path: Path) -> None:
    for bad in ("2,9", "x"):
        with pytest.raises(SystemExit) as err:
            ks.main(["--algorithms", "3", "--seeds", "4", "--runs", bad, "--out", str(tmp_path)])
        assert err.value.code == 2
    assert not (tmp_path / "results.csv").exists()


def test_command_line_refuses_bad_algorithms() -> None:
    with pytest.raises(SystemExit) as err:
        ks.main(["--algorithms", "4", "--seeds", "1"])
    assert err.value.code == 2
    with pytest.raises(SystemExit):
        ks.main(["--algorithms", "a,b"])


def test_accepted_options_read_the_backend_constructors() -> None:
    names = ks.accepted_options("pybullet-surgical")
    assert {"gui", "dt", "tail"} <= names  # PyBulletBackend's own keywords, via the MRO
    assert "kwargs" not in names and "self" not in names
    assert ks.accepted_options("no-such-backend") == set()
    # an entry-point backend whose own constructor takes only **kwargs: its parents' options
    # (the stitched start's perturbations were silently dropped before)
    stitched = ks.accepted_options("pybullet-surgical-stitched")
    assert {"base_error", "friction_scale", "suture_stiffness_scale"} <= stitched


@pytest.mark.parametrize(
    ("backend", "single", "sets"),
    [
        ("pybullet-surgical-stitched", False, ["algorithm=2", "stitch=false"]),
        ("pybullet-surgical", False, ["algorithm=2", "stitch=true"]),
        ("pybullet-surgical-stitched", True, ["stitch=false"]),
    ],
)
def test_runs_on_the_stitched_start_skip_the_stitch_and_others_make_it(
    backend: str, single: bool, sets: list[str]
) -> None:
    job = ks.Job(2, 0, 5, ks.Perturbation(), {}, backend, "x", 10.0, single)
    assert ks.job_sets(job) == sets


def _trace(path: Path, *, seed: int, event_period_s: float) -> Path:
    from suture_engine.trace.synthetic import synthetic_messages, synthetic_meta
    from suture_engine.trace.writer import TraceWriter

    with TraceWriter(path, synthetic_meta(seed=seed)) as writer:
        for topic, t_ns, msg in synthetic_messages(2.0, seed=seed, event_period_s=event_period_s):
            writer.write(topic, t_ns, msg)
    return path


def test_the_path_digest_follows_the_transitions_not_the_noise(tmp_path: Path) -> None:
    """Two traces whose measurements differ (another noise seed) but whose states changed
    on the same ticks have one digest; a transition one step earlier changes it; an
    unreadable trace has none."""
    a = ks.path_digest(_trace(tmp_path / "a.mcap", seed=1, event_period_s=0.5))
    b = ks.path_digest(_trace(tmp_path / "b.mcap", seed=2, event_period_s=0.5))
    c = ks.path_digest(_trace(tmp_path / "c.mcap", seed=1, event_period_s=0.499))
    assert a and a == b
    assert c and c != a
    assert ks.path_digest(tmp_path / "missing.mcap") == ""


def test_the_tally_counts_runs_of_one_path_once() -> None:
    """Seeds whose runs share a path are one run for ``paths``; rows without a path
    (a run that raised, an older table) each count alone. The rate still counts rows."""
    rows = [
        _row(2, True)._replace(path="aaa"),
        _row(2, True)._replace(path="aaa"),
        _row(2, False, "failed")._replace(path="bbb"),
        _row(2, False, "failed"),
        _row(2, False, "failed"),
    ]
    (t,) = ks.tally(rows)
    assert (t.runs, t.successes, t.paths) == (5, 2, 4)


def test_a_table_written_before_the_path_column_reads_with_it_empty(tmp_path: Path) -> None:
    path = tmp_path / "results.csv"
    rows = [_row(2, True)._replace(last_fault="x: y", path="abc", peak_true_tension_N=0.5)]
    ks.write_csv(rows, path)
    lines = path.read_text().splitlines()
    cut = [",".join(line.split(",")[:-4]) for line in lines]  # drop path (and the later)
    path.write_text("\n".join(cut) + "\n")
    (row,) = ks.read_csv(path)
    assert (row.last_fault, row.path) == ("x: y", "")
    assert math.isnan(row.peak_true_tension_N)


def test_a_table_written_before_the_true_peak_column_reads_it_as_nan(tmp_path: Path) -> None:
    path = tmp_path / "results.csv"
    ks.write_csv(
        [_row(2, True)._replace(last_fault="x: y", path="abc", peak_true_tension_N=0.5)], path
    )
    lines = path.read_text().splitlines()  # drop the true peak (and the later columns)
    path.write_text("\n".join(",".join(line.split(",")[:-3]) for line in lines) + "\n")
    (row,) = ks.read_csv(path)
    assert (row.last_fault, row.path) == ("x: y", "abc")
    assert math.isnan(row.peak_true_tension_N)


def test_the_true_peak_is_reported_apart_from_the_estimate(tmp_path: Path) -> None:
    # an emergency lock where the tools met: the estimate is high, the thread slack; the
    # true peak is elsewhere (run 0's 5.23 N with the estimate at 1.59 N, 2026-12-03)
    rows = [
        _row(2, False, "failed")._replace(run=0, max_tension_N=1.59, peak_true_tension_N=5.23),
        _row(2, False, "failed")._replace(run=17, max_tension_N=6.38, peak_true_tension_N=0.02),
        _row(2, True)._replace(run=3, max_tension_N=1.0),  # no true peak (NaN): left out
        _row(3, True)._replace(run=1),
    ]
    path = tmp_path / "results.csv"
    ks.write_csv(rows, path)
    back = ks.read_csv(path)
    assert ks.true_peaks(back) == {2: (5.23, 0, 6.38)}


def test_where_the_true_peak_was_reached_is_read_from_the_summary(tmp_path: Path) -> None:
    at = {"t_s": 188.5, "state": "autonomous/mirrored-knot.tighten", "joint": 16}
    assert ks.peak_at_text(at) == "mirrored-knot.tighten at joint 16"
    assert ks.peak_at_text({**at, "joint": None}) == "mirrored-knot.tighten"
    assert ks.peak_at_text(None) == ""
    rows = [_row(3, True)._replace(run=26, peak_true_at="mirrored-knot.tighten at joint 16")]
    path = tmp_path / "results.csv"
    ks.write_csv(rows, path)
    assert [r.peak_true_at for r in ks.read_csv(path)] == ["mirrored-knot.tighten at joint 16"]
    # a table written before the column reads with it empty
    text = path.read_text().splitlines()
    path.write_text("\n".join(line.rsplit(",", 1)[0] for line in text) + "\n")
    assert [r.peak_true_at for r in ks.read_csv(path)] == [""]


@pytest.mark.parametrize(
    "bad",
    [
        ["--wound-gap", "-1"],
        ["--wound-depth", "0"],
        ["--wound-gap", "2.5", "--backend", "ideal"],
        ["--pad-clear-depth", "-0.1"],
        ["--pad-clear-depth", "0.1", "--backend", "ideal"],
        ["--thread-contact-stiffness", "0"],
        ["--thread-contact-stiffness", "1e4", "--backend", "ideal"],
        ["--smooth-joints", "--backend", "ideal"],
        ["--thread-damping", "-1"],
        ["--thread-damping", "20", "--backend", "ideal"],
        ["--thread-weight", "0"],
        ["--thread-weight", "4", "--backend", "ideal"],
    ],
)
def test_command_line_refuses_a_wound_gap_it_cannot_give(bad: list[str]) -> None:
    """A negative width, or a backend without a tissue pad to part, is a usage error."""
    with pytest.raises(SystemExit) as err:
        ks.main(["--algorithms", "3", "--seeds", "1", *bad])
    assert err.value.code == 2


def test_the_knots_lay_is_read_from_the_summary_and_counted_over_the_successes(
    tmp_path: Path,
) -> None:
    assert ks.knot_lay({"type": "square", "lay": "half-hitches"}) == "half-hitches"
    assert ks.knot_lay([{"lay": "square"}, {"lay": "square"}]) == "square"
    assert ks.knot_lay([{"lay": "square"}, {"lay": "half-hitches"}]) == "mixed"
    assert ks.knot_lay(None) == ks.knot_lay({"type": "unknot"}) == ""

    def row(run: int, ok: bool, lay: str) -> ks.Row:
        return ks.Row(3, run, run, "succeeded", "square", ok, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0,
                      "", "", "", 1.0, lay)  # fmt: skip

    rows = [row(0, True, "square"), row(1, True, "half-hitches"), row(2, True, "square"),
            row(3, False, "half-hitches"), row(4, True, "")]  # fmt: skip
    assert ks.square_lays(rows) == {3: {"square": 2, "half-hitches": 1, "-": 1}}
    assert ks.square_lays([row(0, False, "square")]) == {}
    # the column survives the table
    path = tmp_path / "results.csv"
    ks.write_csv(rows, path)
    assert [r.knot_lay for r in ks.read_csv(path)] == ["square", "half-hitches", "square",
                                                        "half-hitches", ""]  # fmt: skip
    # a table written before it reads with the lay empty
    text = path.read_text().splitlines()
    cut = [",".join(line.split(",")[:-2]) for line in text]  # the lay and the peak's place
    path.write_text("\n".join(cut) + "\n")
    assert [r.knot_lay for r in ks.read_csv(path)] == [""] * 5


def test_a_base_error_as_calibration_leaves_the_robots_where_declared() -> None:
    accepted = {"base_error", "friction_scale"}
    placed = _jobs([3], accepted)
    calibrated = [ks.as_calibration(j) for j in placed]
    for p, c in zip(placed, calibrated, strict=True):
        assert "base_error" in p.options and p.calibration is None
        # the backend builds no base error; the friction draw goes on as it was
        assert "base_error" not in c.options
        assert c.options["friction_scale"] == p.options["friction_scale"]
        # the skills' belief is off by minus the draw, so the tips land as placed ones do
        for robot, e in p.perturbation.base_error.items():
            np.testing.assert_array_equal(c.calibration[robot], -np.asarray(e))
        assert (c.seed, c.perturbation) == (p.seed, p.perturbation)
    with pytest.raises(SystemExit) as err:
        ks.main(["--algorithms", "3", "--seeds", "1", "--base-error-as", "calibration",
                 "--no-perturb"])  # fmt: skip
    assert err.value.code == 2


def test_the_threads_damping_and_weight_reach_every_job(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--thread-damping`` [1/s] and ``--thread-weight`` [g/m] become every job's backend
    options ``thread_damping`` [1/s] and ``thread_weight`` [kg/m]; no flag, no option."""
    from concurrent.futures import Future

    submitted: list[Any] = []

    class Recorder:
        def __init__(self, *_args: object, **_kwargs: object) -> None:
            pass

        def __enter__(self) -> Recorder:
            return self

        def __exit__(self, *_args: object) -> None:
            pass

        def submit(self, _fn: object, job: Any) -> Future[Any]:
            submitted.append(job)
            done: Future[Any] = Future()
            done.set_result(_row(3, True))
            return done

    monkeypatch.setattr(ks, "ProcessPoolExecutor", Recorder)
    base = ["--algorithms", "3", "--seeds", "2", "--backend", "pybullet-surgical-stitched"]
    ks.main([*base, "--out", str(tmp_path / "a"), "--thread-damping", "20", "--thread-weight", "4"])
    assert len(submitted) == 2
    for job in submitted:
        assert job.options["thread_damping"] == 20.0
        assert job.options["thread_weight"] == pytest.approx(4e-3)
    submitted.clear()
    ks.main([*base, "--out", str(tmp_path / "b")])
    assert submitted and all(
        "thread_damping" not in j.options and "thread_weight" not in j.options for j in submitted
    )
