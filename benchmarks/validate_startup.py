"""Cold wall time of ``suture validate procedures/*.yaml``, beside a bare import.

Each measurement starts a fresh interpreter (as a user's shell would), so
module imports are included. Prints the median and the spread of several runs
of each command; the target is <= 0.6 s on a 2-core machine. The second row is
the floor before any file is read: the interpreter, the CLI library (with the
pydantic adapters it coerces the command's parameters through) and the
validator's modules.

Usage: python benchmarks/validate_startup.py [--runs N]
"""

from __future__ import annotations

import argparse
import glob
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
"""The children's environment: Python writes and reuses its bytecode (.pyc), as in a
user's shell. With PYTHONDONTWRITEBYTECODE set, every run compiles every module again."""


def _time(cmd: list[str], runs: int) -> tuple[list[float], list[float]]:
    """Wall times and CPU times (user + system of the child) [s]."""
    walls, cpus = [], []
    for _ in range(runs):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False, env=ENV)
        walls.append(time.perf_counter() - start)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
        if proc.returncode != 0:
            sys.exit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stdout}{proc.stderr}")
    return walls, cpus


def main() -> None:
    """Run the measurement and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=9)
    args = parser.parse_args()
    files = sorted(glob.glob(str(ROOT / "procedures" / "*.yaml")))
    # the console script installed beside this interpreter (a version manager's shim
    # found first on PATH would add its own start-up to every run)
    beside = Path(sys.executable).parent / "suture"
    suture = str(beside) if beside.is_file() else shutil.which("suture")
    validate = [suture] if suture else [sys.executable, "-m", "suture_engine.cli"]
    validate += ["validate", *[str(Path(f).relative_to(ROOT)) for f in files]]
    baseline = [sys.executable, "-c", "import pydantic, yaml"]
    # the floor: the interpreter, the CLI library with the pydantic adapters it builds
    # each command's parameters with, and the validator's own modules, before any file
    floor = [
        sys.executable,
        "-c",
        "import typer, typer._adapters; from suture_engine.validation.checks import validate_file",
    ]
    _time(validate, 1)  # warm the OS file cache and .pyc files once
    rows = [
        ("python -c 'import pydantic, yaml'", _time(baseline, args.runs)),
        ("imports before any file (CLI + validator)", _time(floor, args.runs)),
        (f"suture validate procedures/*.yaml ({len(files)} files)", _time(validate, args.runs)),
    ]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"runs: {args.runs} each; load average {load:.2f} on {os.cpu_count()} CPUs")
    if os.environ.get("PYTHONDONTWRITEBYTECODE"):
        print("(PYTHONDONTWRITEBYTECODE is set here; cleared for the measured runs)")
    print(f"  {'command':<48} {'wall median [min-max]':<26} cpu median")
    for label, (walls, cpus) in rows:
        wall = f"{statistics.median(walls):.3f} s [{min(walls):.3f}-{max(walls):.3f}]"
        print(f"  {label:<48} {wall:<26} {statistics.median(cpus):.3f} s")
    print("target: suture validate <= 0.600 s wall on an idle 2-core machine")


if __name__ == "__main__":
    main()
