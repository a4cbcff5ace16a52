#!/usr/bin/python3
"""identify's memory budget, checked on every CI run: at most 100 bytes per sample at 16 million samples.

Runs bench_identify_scaling's 16M case (identify from arrays with its default options, the preprocessing family
included, in a child process whose peak resident set is the figure; docs/performance.md, "Identify: memory and
scaling") and fails when the peak per sample exceeds the budget. The peak is a property of the program, not of the
machine's load, so it can be held to a limit where a time could not. About a minute and 1.5 GB of memory.

Usage: scripts/check_memory.py [BENCH_BINARY]   (default: build/bench/bench_identify_scaling)
"""
import json
import subprocess
import sys

BUDGET_BYTES_PER_SAMPLE = 100.0
CASE = "BM_IdentifyScaling/samples:16000000/threads:0"


def main() -> int:
    binary = sys.argv[1] if len(sys.argv) > 1 else "build/bench/bench_identify_scaling"
    try:
        run = subprocess.run([binary, f"--benchmark_filter=^{CASE}/", "--benchmark_format=json"],
                             check=True, capture_output=True, text=True)
    except (OSError, subprocess.CalledProcessError) as error:
        print(f"check_memory: {binary} did not run: {error}", file=sys.stderr)
        return 1
    runs = [b for b in json.loads(run.stdout)["benchmarks"] if b["name"].startswith(CASE)]
    if not runs or "error_message" in runs[0]:
        print(f"check_memory: {binary} gave no figure for {CASE}: {runs[0].get('error_message') if runs else 'no run'}",
              file=sys.stderr)
        return 1
    figure = runs[0]["bytes_per_sample"]
    peak_mb = runs[0]["peak_MB"]
    verdict = "within" if figure <= BUDGET_BYTES_PER_SAMPLE else "OVER"
    print(f"check_memory: identify at 16M samples peaks at {figure:.1f} bytes per sample ({peak_mb:.0f} MB), "
          f"{verdict} the budget of {BUDGET_BYTES_PER_SAMPLE:g}")
    return 0 if figure <= BUDGET_BYTES_PER_SAMPLE else 1


if __name__ == "__main__":
    sys.exit(main())
