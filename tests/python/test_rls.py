"""feedid.Rls against an independent numpy implementation of the same equations, on data with known parameters; the
vectorised update_many equals the per-sample update and runs without the GIL."""

import threading
import time

import numpy as np
import pytest

import feedid


def reference_exponential(phi, y, forgetting, p0):
    """The paper's eq. (7)-(9), written from the equations: L = P phi / (lambda + phi' P phi), theta += L e,
    P = (I - L phi') P / lambda."""
    n = phi.shape[1]
    theta, p = np.zeros(n), np.eye(n) * p0
    for row, target in zip(phi, y):
        gain = p @ row / (forgetting + row @ p @ row)
        theta = theta + gain * (target - row @ theta)
        p = (p - np.outer(gain, row) @ p) / forgetting
    return theta, p


def reference_directional(phi, y, forgetting, p0):
    """Directional forgetting (Kulhavy 1987): R <- R - (1 - lambda) phi phi' / (phi' P phi) + phi phi', written on P
    with the matrix inversion lemma: P <- P - eps / (lambda + r) (P phi)(P phi)', eps = 1 - (1 - lambda) / r."""
    n = phi.shape[1]
    theta, p = np.zeros(n), np.eye(n) * p0
    for row, target in zip(phi, y):
        p_phi = p @ row
        r = row @ p_phi
        theta = theta + p_phi / (forgetting + r) * (target - row @ theta)
        eps = 1.0 - (1.0 - forgetting) / r
        p = p - eps / (forgetting + r) * np.outer(p_phi, p_phi)
    return theta, p


def regression(samples, truth, noise=0.5, seed=1):
    rng = np.random.default_rng(seed)
    phi = np.column_stack([rng.normal(size=samples), rng.normal(size=samples) * 3, np.sign(rng.normal(size=samples)),
                           np.ones(samples)])[:, :len(truth)]
    return phi, phi @ truth + rng.normal(scale=noise, size=samples)


@pytest.mark.parametrize("variant,reference", [("exponential", reference_exponential),
                                               ("directional", reference_directional)])
def test_rls_equals_the_equations(variant, reference):
    truth = np.array([69.1, 54.2, 742.8])
    phi, y = regression(3000, truth)
    rls = feedid.Rls(3, forgetting_factor=0.999, initial_covariance=1e4, variant=variant)
    rls.update_many(phi, y)
    theta, p = reference(phi, y, 0.999, 1e4)
    np.testing.assert_allclose(rls.estimate, theta, rtol=1e-9)
    # normwise: the exponential variant's P drifts from symmetry by round-off, differently in each implementation
    assert np.abs(rls.covariance - p).max() <= 1e-7 * np.abs(p).max()
    # and the estimate is the truth within its noise
    np.testing.assert_allclose(rls.estimate, truth, rtol=0.01)
    assert rls.updates == 3000 and rls.last_counts == {"updated": 3000, "no_excitation": 0, "non_finite": 0}


def test_update_many_equals_update_sample_by_sample():
    phi, y = regression(2000, np.array([2.0, -1.0, 0.5, 3.0]))
    one = feedid.Rls(4)
    estimates = np.array([(one.update(row, target), one.estimate)[1] for row, target in zip(phi, y)])
    many = feedid.Rls(4)
    history = many.update_many(phi, y, history=True)
    assert history.shape == (2000, 4)
    np.testing.assert_array_equal(history, estimates)  # the same code: bitwise equal
    np.testing.assert_array_equal(many.covariance, one.covariance)
    chunked = feedid.Rls(4)
    for start in range(0, 2000, 300):  # streaming in chunks ends where one call ends
        assert chunked.update_many(phi[start:start + 300], y[start:start + 300]) is None
    np.testing.assert_array_equal(chunked.estimate, many.estimate)


def test_update_many_converts_arrays_and_skips_non_finite_rows():
    phi, y = regression(500, np.array([1.0, 2.0, 3.0]))
    reference = feedid.Rls(3)
    reference.update_many(phi, y)
    wide = np.asfortranarray(phi)  # not C-contiguous
    assert not wide.flags.c_contiguous
    converted = feedid.Rls(3)
    converted.update_many(wide, list(y))
    np.testing.assert_array_equal(converted.estimate, reference.estimate)
    single = feedid.Rls(3)
    single.update_many(phi.astype(np.float32), y.astype(np.float32))
    np.testing.assert_allclose(single.estimate, reference.estimate, rtol=1e-3)
    holes = phi.copy()
    holes[10, 1] = np.nan
    y_holes = y.copy()
    y_holes[20] = np.inf
    skipped = feedid.Rls(3)
    skipped.update_many(holes, y_holes)
    assert skipped.last_counts == {"updated": 498, "no_excitation": 0, "non_finite": 2}
    assert skipped.update([np.nan, 1.0, 1.0], 1.0) == "non_finite"
    assert np.all(np.isfinite(skipped.estimate))
    assert feedid.Rls(2).update([0.0, 0.0], 1.0) == "no_excitation"


def test_state_and_reset():
    rls = feedid.Rls(2, forgetting_factor=0.99, initial_covariance=100.0, variant="paper",
                     initial_estimate=[1.0, 2.0])
    assert (rls.n, rls.variant, rls.forgetting_factor, rls.initial_covariance) == (2, "exponential", 0.99, 100.0)
    np.testing.assert_array_equal(rls.estimate, [1.0, 2.0])
    np.testing.assert_array_equal(rls.covariance, np.eye(2) * 100.0)
    assert rls.update([1.0, 0.0], 5.0) == "updated"
    assert rls.updates == 1 and not rls.wound_up
    rls.reset()
    np.testing.assert_array_equal(rls.estimate, [0.0, 0.0])
    assert rls.updates == 0
    rls.estimate[0] = 7.0  # a copy: the estimator is not changed through it
    assert rls.estimate[0] == 0.0


@pytest.mark.parametrize("bad", [[np.inf, 0.0], [0.0, np.nan], [0.0, -np.inf]])
def test_reset_refuses_values_that_are_not_finite(bad):
    rls = feedid.Rls(2)
    rls.update([1.0, 0.0], 5.0)
    with pytest.raises(feedid.InputError, match="initial_estimate holds a value that is not finite"):
        rls.reset(bad)
    assert rls.updates == 1  # refused before anything changed
    with pytest.raises(feedid.InputError):
        feedid.Rls(2, initial_estimate=bad)


def test_two_threads_on_one_rls_give_one_order_or_the_other():
    """update_many runs without the GIL: two threads on one Rls must not interleave their samples. The result is
    that of one order or the other, to the last bit (each call holds the estimator's lock)."""
    first, second = [regression(400_000, np.array([2.0, -1.0, 0.5]), seed=s) for s in (11, 12)]
    orders = []
    for order in ((first, second), (second, first)):
        serial = feedid.Rls(3, forgetting_factor=0.9999)
        for phi, y in order:
            serial.update_many(phi, y)
        orders.append((serial.estimate, serial.covariance))
    for attempt in range(5):
        rls = feedid.Rls(3, forgetting_factor=0.9999)
        barrier = threading.Barrier(3)
        read = []

        def run(data):
            barrier.wait()
            rls.update_many(*data)
            read.append(rls.estimate)  # while the other thread may update: a whole state, never half of one

        threads = [threading.Thread(target=run, args=(data,)) for data in (first, second)]
        for thread in threads:
            thread.start()
        barrier.wait()
        for thread in threads:
            thread.join()
        assert rls.updates == 800_000 and len(read) == 2 and all(np.all(np.isfinite(e)) for e in read)
        assert any(np.array_equal(rls.estimate, e) and np.array_equal(rls.covariance, p) for e, p in orders), \
            (attempt, rls.estimate, [e for e, _ in orders])


def test_update_many_releases_the_gil():
    rng = np.random.default_rng(3)
    samples = 4_000_000
    phi = rng.normal(size=(samples, 3))
    y = phi @ np.array([1.0, 2.0, 3.0])
    rls = feedid.Rls(3)
    start = time.perf_counter()
    rls.update_many(phi[:200_000], y[:200_000])
    per_sample = (time.perf_counter() - start) / 200_000
    worker = threading.Thread(target=rls.update_many, args=(phi, y))
    stamps = []
    worker.start()
    while worker.is_alive():  # this thread runs Python while the other is inside update_many
        stamps.append(time.perf_counter())
    worker.join()
    duration = samples * per_sample
    longest_pause = np.diff(stamps).max() if len(stamps) > 1 else duration
    # holding the GIL would stop this loop for the whole call; Python's switch interval is 5 ms
    assert longest_pause < duration / 2, (longest_pause, duration)
    assert len(stamps) > 1000
