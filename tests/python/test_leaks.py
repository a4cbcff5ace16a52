"""The module does not leak: 10,000 calls of every kind (views, traces from arrays, identify and its result's
records, Rls, Estimate, the exception paths, History) leave the reference counts of the objects passed in as they
were, no Python objects or memory behind (gc, tracemalloc), and the process's resident memory where it was (the
C++ side)."""

import gc
import sys
import tracemalloc

import numpy as np
import pytest

import feedid

CALLS = 10_000
FORCE = "force_constant_N_per_A"


def resident_bytes():
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * 4096


@pytest.fixture(scope="module")
def small_trace():
    drive = feedid.demo_drive()
    drive["test"].update(feedrates_mm_per_min=[3000, 9000], stroke_mm=10.0, dwell_s=0.05)
    return feedid.synth(drive, slow_passes=False)  # about 1000 samples: identify takes a fraction of a millisecond


def one_of_each(trace, time, position, current, phi, y, rls, history, document):
    trace["x"]
    trace.role("position")
    trace.roles
    feedid.Trace.from_arrays(time=time, position=position, current=current, constants={"k": 1.0})
    result = feedid.identify(trace, force_constant=FORCE)
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


def test_no_leaks_over_ten_thousand_calls(small_trace, folder):
    time = np.arange(100) * 1e-3
    position = np.sin(time)
    current = np.cos(time)
    phi = np.random.default_rng(1).normal(size=(20, 3))
    y = phi @ np.array([1.0, 2.0, 3.0])
    rls = feedid.Rls(3)
    history = feedid.History(folder / "empty.db")
    document = feedid.identify(small_trace, force_constant=FORCE).to_dict()
    del document["rls"]["history"]
    watched = (small_trace, time, position, current, phi, y, rls, history, document)
    for _ in range(200):  # warm up: caches, interned strings, numpy's and pybind11's type tables
        one_of_each(*watched)
    gc.collect()
    references = [sys.getrefcount(o) for o in watched]
    objects = len(gc.get_objects())
    resident = resident_bytes()
    tracemalloc.start()
    traced = tracemalloc.get_traced_memory()[0]
    for _ in range(CALLS):
        one_of_each(*watched)
    gc.collect()
    grown = tracemalloc.get_traced_memory()[0] - traced
    tracemalloc.stop()
    assert [sys.getrefcount(o) for o in watched] == references
    assert len(gc.get_objects()) - objects < 100  # one object per call left behind would be 10,000
    assert grown < 64 * 1024, f"{grown} bytes of Python memory left after {CALLS} calls"
    # the C++ side: a leaked 1000-sample trace (3 x 8 kB) per call would be 240 MB
    assert resident_bytes() - resident < 16 * 1024 * 1024
    history.close()
