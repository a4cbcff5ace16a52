"""feedid identify as a user runs it, beside pandas + numpy/scipy doing the same on the same CSV, side by side in one
run (docs/performance.md, "End to end against pandas": the figures and the machine).

The file is bench_identify's million-sample trace (t, x, i and the force constant as a '# force_constant = 450'
comment; about 42 MB), written by this script with `feedid` itself if it is not there yet. Timed, wall clock, each
job in a fresh process, the jobs interleaved round by round (each round's order rotated by one, so that no job always
follows the same one), medians of --rounds:

- pandas.read_csv alone, and `feedid info` (read, map, convert, validate);
- the pandas + numpy/scipy pipeline: read_csv, sosfiltfilt (4th-order Butterworth at 100 Hz), numpy.gradient twice,
  the edge trim, the samples above a tenth of the typical speed, lstsq with standard errors (M, B, F_C);
- `feedid identify` with default options (the systematic uncertainty included) and with --no-systematic, for each
  binary given (this build's and, with --baseline, an earlier release's).

    /usr/bin/python3 bench/python/compare_pandas.py build/feedid [--baseline /path/to/feedid] [--rounds 5]
"""

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

PIPELINE = r'''
import sys
import numpy as np
import pandas as pd
from scipy import signal
frame = pd.read_csv(sys.argv[1], comment="#")
if len(sys.argv) > 2:
    sys.exit(0)  # read only
t, x, current = frame.iloc[:, 0].to_numpy(), frame.iloc[:, 1].to_numpy(), frame.iloc[:, 2].to_numpy()
dt = t[1] - t[0]
sos = signal.butter(4, 100.0, fs=1.0 / dt, output="sos")
velocity = np.gradient(signal.sosfiltfilt(sos, x), dt)
acceleration = np.gradient(velocity, dt)
force = current * 450.0
edge = int(2.5 / (100.0 * dt))
velocity, acceleration, force = velocity[edge:-edge], acceleration[edge:-edge], force[edge:-edge]
speed = np.abs(velocity)
fast = speed > 0.1 * np.percentile(speed, 95)
phi = np.column_stack([acceleration[fast], velocity[fast], np.sign(velocity[fast])])
estimate, _, _, _ = np.linalg.lstsq(phi, force[fast], rcond=None)
residual = force[fast] - phi @ estimate
variance = residual @ residual / (len(residual) - phi.shape[1])
print(estimate, np.sqrt(np.diag(np.linalg.inv(phi.T @ phi)) * variance))
'''


def measure(command):
    """Wall time and CPU time (user + system of the process and its threads) [s] of one run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return elapsed, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("feedid")
    parser.add_argument("--baseline")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--csv", default=os.path.join(tempfile.gettempdir(), "feedid-bench-identify-1M.csv"))
    args = parser.parse_args()
    if not os.path.exists(args.csv):
        sys.exit(f"{args.csv} is missing: run build/bench/bench_identify once, which writes it")
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as script:
        script.write(PIPELINE)
    python = "/usr/bin/python3"
    jobs = {
        "pandas.read_csv": [python, script.name, args.csv, "read-only"],
        "pandas + numpy/scipy pipeline": [python, script.name, args.csv],
    }
    binaries = [("feedid", args.feedid)] + ([("baseline", args.baseline)] if args.baseline else [])
    for label, binary in binaries:
        identify = [binary, "identify", args.csv, "--force-constant", "force_constant", "--json", os.devnull]
        jobs[f"{label} info"] = [binary, "info", args.csv]
        jobs[f"{label} identify"] = identify
        jobs[f"{label} identify --no-systematic"] = identify + ["--no-systematic"]
    walls = {name: [] for name in jobs}
    cpus = {name: [] for name in jobs}
    load_before = os.getloadavg()
    # Each round starts one job later than the round before: a job run right after the pandas pipeline pays more
    # (0.1-0.25 CPU s measured, the caches and pages the pipeline left), so no job keeps that place.
    names = list(jobs)
    for round_index in range(args.rounds):
        start = round_index % len(names)
        for name in names[start:] + names[:start]:
            elapsed, cpu = measure(jobs[name])
            walls[name].append(elapsed)
            cpus[name].append(cpu)
    os.unlink(script.name)
    load = os.getloadavg()
    print(f"{os.cpu_count()} cores, load average {load_before[0]:.1f} before, {load[0]:.1f} after; medians of "
          f"{args.rounds} runs, interleaved round by round, each round's order rotated; CPU = user + system of the "
          f"process and its threads")
    print(f"{'job':40s} {'CPU s':>7s} {'ratio':>6s}  {'wall s':>7s} {'ratio':>6s}  against")
    for name in jobs:
        cpu, elapsed = statistics.median(cpus[name]), statistics.median(walls[name])
        reference = "pandas.read_csv" if name.endswith("read_csv") or name.endswith(" info") else \
            "pandas + numpy/scipy pipeline"
        cpu_ratio = cpu / statistics.median(cpus[reference])
        wall_ratio = elapsed / statistics.median(walls[reference])
        print(f"{name:40s} {cpu:7.3f} {cpu_ratio:5.2f}x  {elapsed:7.3f} {wall_ratio:5.2f}x  {reference}")


if __name__ == "__main__":
    main()
