"""The module does not leak: 10,000 calls of every kind (views, traces from arrays, identify and its result's
records, Rls, Estimate, the exception paths, History) leave the reference counts of the objects passed in as they
were, no Python objects or memory behind (gc, tracemalloc), and the process's resident memory where it was (the
C++ side).

The calls are measured in a fresh interpreter of their own (this file run as a script): in a process where other
tests ran first (Dask's threads, pandas, numpy's caches) tracemalloc sees a few hundred unrelated blocks come and go."""

import gc
import json
import os
import subprocess
import sys
import tracemalloc

import numpy as np

CALLS = 10_000
WARM_UP = 1_000
FORCE = "force_constant_N_per_A"


def resident_bytes():
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * 4096


def one_of_each(feedid, trace, time, position, current, phi, y, rls, history, document):
    trace["x"]
    trace.role("position")
    trace.roles
    feedid.Trace.from_arrays(time=time, position=position, current=current, constants={"k": 1.0})
    # without the systematic family: the same binding, a fifth of the time (the family's reruns are C++ inside)
    result = feedid.identify(trace, force_constant=FORCE, systematic=False)
    result.parameters["mass_kg"].to_dict()
    result.rls.history["mass_kg"]
    result.step1.batch
    result.friction_curve.forward
    feedid.Result.from_dict(document).to_dict()  # a document without the RLS history: cheap to convert
    rls.update(phi[0], y[0])
    rls.update_many(phi, y, history=True)
    rls.estimate
    feedid.Estimate(1.0, 0.5) == feedid.Estimate(value=1.0, standard_error=0.5)
    try:
        feedid.identify(trace, force_constant=FORCE, model="elliptic")
    except feedid.InputError:
        pass
    try:
        trace["nope"]
    except KeyError:
        pass
    try:
        feedid.Trace.from_arrays(time=time, position=np.full_like(position, np.nan))
    except feedid.InputError:
        pass
    history.runs()


def measure(folder):
    """The measurements, as a dict; run in a process of its own."""
    import feedid

    drive = feedid.demo_drive()
    drive["test"].update(feedrates_mm_per_min=[3000, 9000], stroke_mm=10.0, dwell_s=0.05)
    trace = feedid.synth(drive, slow_passes=False)  # about 1000 samples: identify takes a fraction of a millisecond
    time = np.arange(100) * 1e-3
    phi = np.random.default_rng(1).normal(size=(20, 3))
    document = feedid.identify(trace, force_constant=FORCE).to_dict()
    del document["rls"]["history"]
    history = feedid.History(os.path.join(folder, "empty.db"))
    watched = (trace, time, np.sin(time), np.cos(time), phi, phi @ np.array([1.0, 2.0, 3.0]), feedid.Rls(3), history,
               document)
    for _ in range(WARM_UP):  # caches, interned strings, type tables and Python's free lists filled
        one_of_each(feedid, *watched)
    gc.collect()
    references = [sys.getrefcount(o) for o in watched]
    objects = len(gc.get_objects())
    resident = resident_bytes()
    tracemalloc.start()
    traced = tracemalloc.get_traced_memory()[0]
    for _ in range(CALLS):
        one_of_each(feedid, *watched)
    gc.collect()
    grown = tracemalloc.get_traced_memory()[0] - traced
    tracemalloc.stop()
    measured = {"references_before": references, "references_after": [sys.getrefcount(o) for o in watched],
                "objects_grown": len(gc.get_objects()) - objects, "python_bytes_grown": grown,
                "resident_bytes_grown": resident_bytes() - resident}
    history.close()
    return measured


def test_no_leaks_over_ten_thousand_calls(folder):
    completed = subprocess.run([sys.executable, __file__, str(folder)], capture_output=True, text=True)
    assert completed.returncode == 0, completed.stderr
    measured = json.loads(completed.stdout)
    assert measured["references_after"] == measured["references_before"]
    assert measured["objects_grown"] < 100  # one object per call left behind would be 10,000
    # one leaked object per call, the smallest (an int, 28 bytes), would be 280 kB
    assert measured["python_bytes_grown"] < 64 * 1024, measured
    # the C++ side: a leaked 1000-sample trace (3 x 8 kB) per call would be 240 MB
    assert measured["resident_bytes_grown"] < 16 * 1024 * 1024, measured


if __name__ == "__main__":
    print(json.dumps(measure(sys.argv[1])))
