#!/usr/bin/python3
"""The drift check of `feedid history DB --check` written the way a data engineer would, with Python's sqlite3 and
pandas, for bench_history to time side by side with feedid: the same baseline (the first 8 runs of each machine and
axis, or from a pinned run), the same combined standard error and the same two-sided CUSUM (k = 1, h = 6) as
include/feedid/history/trend.hpp. Prints one line per alarm and the number of alarms last, so that the benchmark can
check that both found the same.

    /usr/bin/python3 bench/history_check.py shop.db
"""
import math
import sqlite3
import sys

import numpy as np
import pandas as pd

BASELINE_RUNS, K, H = 8, 1.0, 6.0
Z25 = -0.6744897501960817  # the 25 % quantile of the standard normal distribution


def scatter_factor(nu):
    """sqrt(nu / chi2_0.25(nu)) by Wilson and Hilferty's approximation, as trend.hpp."""
    if nu < 1:
        return 1.0
    a = 2.0 / (9.0 * nu)
    return math.sqrt(nu / (nu * (1.0 - a + Z25 * math.sqrt(a)) ** 3))


def check(path):
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    runs = pd.read_sql_query(
        "SELECT id, machine, axis, recorded_at FROM runs ORDER BY machine, axis, recorded_at, id", db)
    values = pd.read_sql_query("SELECT run_id AS id, key, value, stderr FROM parameters WHERE value IS NOT NULL", db)
    pins = dict(((m, a), r) for m, a, r in db.execute("SELECT machine, axis, run_id FROM baselines"))
    runs["order"] = runs.groupby(["machine", "axis"]).cumcount()
    start = runs[runs.id.isin(pins.values())].set_index(["machine", "axis"])["order"]
    runs["role"] = runs["order"] - runs.set_index(["machine", "axis"]).index.map(start).fillna(0).to_numpy()
    complete = runs.groupby(["machine", "axis"]).role.max() >= BASELINE_RUNS - 1  # a whole baseline from its start
    data = values.merge(runs, on="id").sort_values(["machine", "axis", "key", "order", "id"])
    alarms = 0
    for (machine, axis, key), group in data.groupby(["machine", "axis", "key"], sort=True):
        if not complete[(machine, axis)]:
            continue
        role = group.role.to_numpy()
        value = group.value.to_numpy()
        error = group.stderr.to_numpy()
        base = (role >= 0) & (role < BASELINE_RUNS)
        n = int(base.sum())
        if n == 0:
            continue
        mean = value[base].mean()
        scatter = value[base].std(ddof=1) if n > 1 else 0.0
        bound = scatter_factor(n - 1) * scatter if n > 1 else 0.0
        known = error[base][~np.isnan(error[base])]
        rms = math.sqrt((known ** 2).mean()) if len(known) else 0.0
        sigma_mean = max(rms, bound) / math.sqrt(n)
        if max(rms, bound) <= 0.0:
            continue
        sigma = np.sqrt(np.maximum(np.where(np.isnan(error), rms, error), bound) ** 2 + sigma_mean ** 2)
        z = (value - mean) / sigma
        up = down = 0.0
        for i in np.nonzero(role >= BASELINE_RUNS)[0]:
            up = max(0.0, up + z[i] - K)
            down = max(0.0, down - z[i] - K)
            if up > H or down > H:
                alarms += 1
                print(f"drift alarm: machine '{machine}' axis '{axis}' parameter {key} at run "
                      f"#{group.id.iloc[i]}: {'rose' if up > H else 'fell'}, CUSUM {max(up, down):.1f}")
                break
    print(alarms)
    return alarms


if __name__ == "__main__":
    sys.exit(1 if check(sys.argv[1]) else 0)
