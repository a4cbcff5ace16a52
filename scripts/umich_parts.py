#!/usr/bin/env python3
"""Friction-only standard errors against the scatter of parts of one run: the UMich mill log experiment_01 cut into
3-6 contiguous parts (the first 50 rows, which hold the axis's one rapid, in every part), each identified with the
README's options; per part count, the scatter over the parts of B, F_C and the friction at the 6 mm/s feed
(F_C + 0.006 B) against their mean standard error. Run from the repository root after building:

    python3 scripts/umich_parts.py [build/feedid] [../shared/data/umich-cnc-mill/experiment_01.csv]
"""
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

FEEDID = sys.argv[1] if len(sys.argv) > 1 else "build/feedid"
SOURCE = Path(sys.argv[2] if len(sys.argv) > 2 else "../shared/data/umich-cnc-mill/experiment_01.csv")
OPTIONS = ["--sample-time", "0.1", "--unit", "position=mm", "--unit", "velocity=mm/s", "--unit",
           "reference_position=mm", "--unit", "velocity_command=mm/s", "--force-constant", "1", "--json", "-"]
FEED = 0.006  # m/s


def identify(header, rows, axis, path):
    """B, se(B), F_C, se(F_C), their correlation; None where identify gives no friction."""
    with open(path, "w") as out:
        out.write(header + "\n")
        for i, row in enumerate(rows):  # the pandas index counts 0, 1, 2, ... again
            out.write(str(i) + row[row.index(","):] + "\n")
    run = subprocess.run([FEEDID, "identify", str(path), "--axis", axis, *OPTIONS], capture_output=True, text=True)
    if run.returncode != 0:
        return None
    document = json.loads(run.stdout)
    viscous, coulomb = document["parameters"]["viscous_Ns_per_m"], document["parameters"]["coulomb_N"]
    if viscous["value"] is None or coulomb["value"] is None:
        return None
    correlation = document["fit"]["correlations"]["viscous_Ns_per_m"]["coulomb_N"]
    return viscous["value"], viscous["stderr"], coulomb["value"], coulomb["stderr"], correlation


def ratio(values, errors):
    mean = sum(values) / len(values)
    scatter = math.sqrt(sum((v - mean) ** 2 for v in values) / (len(values) - 1))
    return scatter / (sum(errors) / len(errors))


def main():
    lines = SOURCE.read_text().rstrip("\n").split("\n")
    header, data = lines[0], lines[1:]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "part.csv"
        for axis in ["X1", "Y1"]:
            whole = identify(header, data, axis, path)
            print(f"{axis} whole log: B {whole[0]:.1f} +- {whole[1]:.1f}, F_C {whole[2]:.3f} +- {whole[3]:.3f}")
            for parts in [3, 4, 5, 6]:
                edges = [50 + (len(data) - 50) * i // parts for i in range(parts + 1)]
                results = [identify(header, data[:edges[1]] if i == 0 else data[:50] + data[edges[i]:edges[i + 1]],
                                    axis, path) for i in range(parts)]
                results = [r for r in results if r]
                feed = [r[2] + FEED * r[0] for r in results]
                feed_errors = [math.sqrt(r[3] ** 2 + FEED ** 2 * r[1] ** 2 + 2 * FEED * r[4] * r[1] * r[3])
                               for r in results]
                print(f"  {parts} parts ({len(results)} answered), scatter / mean standard error: "
                      f"B {ratio([r[0] for r in results], [r[1] for r in results]):.2f}, "
                      f"F_C {ratio([r[2] for r in results], [r[3] for r in results]):.2f}, "
                      f"F(6 mm/s) {ratio(feed, feed_errors):.2f}")


if __name__ == "__main__":
    main()
