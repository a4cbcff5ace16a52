#!/usr/bin/python3
"""An 8-hour, 1 kHz production trace for the `feedid scan` acceptance of issue 15 (28.8 million samples):
a `feedid synth` CSV (or any trace CSV with t, x_ref, x columns) repeated end to end, time and position shifted so
that each copy starts where the last one stopped (the traces start and end at rest).

    bench/long_trace.py IN.csv OUT.csv [--hours 8]
    /usr/bin/time -v build/feedid scan OUT.csv --kt 1.444 --lead 20
"""
import argparse
import numpy as np

parser = argparse.ArgumentParser()
parser.add_argument("source")
parser.add_argument("out")
parser.add_argument("--hours", type=float, default=8.0)
args = parser.parse_args()

preamble, header = [], None
with open(args.source) as f:
    for line in f:
        if line.startswith("#"):
            preamble.append(line)
        else:
            header = line
            break
names = [c.split("[")[0].strip() for c in header.split(",")]
data = np.loadtxt(args.source, delimiter=",", comments="#", skiprows=len(preamble) + 1)
dt = np.median(np.diff(data[:, names.index("t")]))
span = data.shape[0] * dt
shift_columns = [names.index(n) for n in ("x_ref", "x") if n in names]
rise = data[-1, names.index("x")] - data[0, names.index("x")]
copies = int(np.ceil(args.hours * 3600.0 / span))
with open(args.out, "w") as out:
    out.writelines(preamble)
    out.write(header)
    for copy in range(copies):
        block = data.copy()
        block[:, names.index("t")] += copy * span
        for c in shift_columns:
            block[:, c] += copy * rise
        np.savetxt(out, block, delimiter=",", fmt="%.10g")
print(f"{args.out}: {copies * data.shape[0]} samples, {copies * span / 3600:.2f} h")
