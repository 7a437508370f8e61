"""Cold wall time of ``suture validate procedures/*.yaml``, beside a bare import.

Each measurement starts a fresh interpreter (as a user's shell would), so
module imports are included. Prints the median and the spread of several runs
of both commands; the target is <= 0.6 s on a 2-core machine.

Usage: python benchmarks/validate_startup.py [--runs N]
"""

from __future__ import annotations

import argparse
import glob
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _time(cmd: list[str], runs: int) -> list[float]:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
        times.append(time.perf_counter() - start)
        if proc.returncode != 0:
            sys.exit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stdout}{proc.stderr}")
    return times


def main() -> None:
    """Run the measurement and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=9)
    args = parser.parse_args()
    files = sorted(glob.glob(str(ROOT / "procedures" / "*.yaml")))
    suture = shutil.which("suture")
    validate = [suture] if suture else [sys.executable, "-m", "suture_engine.cli"]
    validate += ["validate", *[str(Path(f).relative_to(ROOT)) for f in files]]
    baseline = [sys.executable, "-c", "import pydantic, yaml"]
    _time(validate, 1)  # warm the OS file cache and .pyc files once
    rows = [
        ("python -c 'import pydantic, yaml'", _time(baseline, args.runs)),
        (f"suture validate procedures/*.yaml ({len(files)} files)", _time(validate, args.runs)),
    ]
    print(f"runs: {args.runs} each, median [min-max] wall time")
    for label, times in rows:
        print(f"  {label:<48} {statistics.median(times):.3f} s [{min(times):.3f}-{max(times):.3f}]")
    print("target: suture validate <= 0.600 s")


if __name__ == "__main__":
    main()
