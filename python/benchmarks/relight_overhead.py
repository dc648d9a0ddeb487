#!/usr/bin/env python3
"""Relighting a field from Python against the CLI's job: medians over several runs.

    PYTHONPATH=build/python python3 python/benchmarks/relight_overhead.py [FIELD] [--runs N]

FIELD: a reflectance field (default: demo-out/field.exr, made by `lightstage demo`). Prints the
median wall time of
  cli       `lightstage relight FIELD --env MAP --out DIR --quiet` (a process each run)
  python    `python3 -c "import lightstage; lightstage.relight(FIELD, env=MAP, out=DIR)"`
            (a process each run: the interpreter's start and the import included)
  start     `python3 -c "import numpy"`: the interpreter's start (NumPy loaded, as the module does)
  in-proc   lightstage.relight(FIELD, env=MAP, out=DIR) in this process (no start at all)
and the overhead: python - start against cli.
"""

import argparse
import os
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]


def timed(command, env=None):
    start = time.perf_counter()
    subprocess.run(command, check=True, env=env, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("field", nargs="?", default="demo-out/field.exr")
    parser.add_argument("--env", default=str(ROOT / "data" / "envmaps" / "sky_sun.exr"))
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--cli", default=str(ROOT / "build" / "app" / "cli" / "lightstage"))
    args = parser.parse_args()
    python_dir = str(ROOT / "build" / "python")
    sys.path.insert(0, python_dir)
    import lightstage as ls  # noqa: PLC0415 (after the path is set)

    env = dict(os.environ, PYTHONPATH=python_dir)
    work = pathlib.Path(tempfile.mkdtemp(prefix="lightstage-bench-"))
    out = work / "relit"
    script = (f"import lightstage; lightstage.relight({args.field!r}, env={args.env!r}, "
              f"out={str(out)!r})")
    times = {"cli": [], "python": [], "start": [], "in-proc": []}
    try:
        for _ in range(args.runs):  # Interleaved, so a slow moment of the machine hits all.
            times["cli"].append(timed([args.cli, "relight", args.field, "--env", args.env,
                                       "--out", str(out), "--quiet"]))
            shutil.rmtree(out)
            times["python"].append(timed([sys.executable, "-c", script], env))
            shutil.rmtree(out)
            times["start"].append(timed([sys.executable, "-c", "import numpy"], env))
            start = time.perf_counter()
            ls.relight(args.field, env=args.env, out=out)
            times["in-proc"].append(time.perf_counter() - start)
            shutil.rmtree(out)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    median = {k: statistics.median(v) for k, v in times.items()}
    field = ls.Field.open(args.field)
    print(f"relight {args.field} ({field.width}x{field.height}, {field.shape[2]} lights) under "
          f"{pathlib.Path(args.env).name}, median of {args.runs} runs:")
    for name, value in median.items():
        spread = f"{min(times[name]):.3f}..{max(times[name]):.3f}"
        print(f"  {name:8s} {value:8.3f} s   ({spread})")
    overhead = (median["python"] - median["start"]) / median["cli"] - 1
    print(f"  python - start against cli: {100 * overhead:+.1f}%")
    print(f"  in-proc against cli:        {100 * (median['in-proc'] / median['cli'] - 1):+.1f}%")


if __name__ == "__main__":
    main()
