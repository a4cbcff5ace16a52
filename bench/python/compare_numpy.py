"""feedid from Python beside numpy/scipy implementations of the same jobs, measured side by side in one run
(README, "Python": the figures and the machine).

1. RLS on 1,000,000 samples of 3 parameters: feedid.Rls.update_many against the loop of padasip's FilterRLS.run
   written in numpy (one sample per iteration: y = w.x, e = d - y, R = (R - R x x' R / (mu + x' R x)) / mu,
   w += R x e, the weights recorded per sample as padasip records them). The same algorithm as feedid's exponential
   variant (the paper's eq. 7-9), so both are run with it, without forgetting (lambda = 1: with lambda < 1 the
   exponential update of P amplifies its round-off by 1/lambda per sample, and over 10^5..10^6 samples either
   implementation drifts away on its own path); feedid's default, directional forgetting with lambda 0.9999, is
   shown too.
2. Identification of a 1,000,000-sample trace (1 kHz, a drive with Stribeck friction on sinusoidal strokes at nine
   speeds, 50 nm encoder) from numpy arrays: feedid.Trace.from_arrays + feedid.identify (the whole pipeline: both
   steps, RLS, the Stribeck curve) against a competent numpy/scipy pipeline for M, B and F_C with standard errors:
   scipy.signal.sosfiltfilt (4th-order Butterworth at 100 Hz), numpy.gradient twice, edge trim, the moving samples
   above a tenth of the typical speed, numpy.linalg.lstsq, standard errors from the residuals.
3. (--fleet) feedid.fleet.identify_many over 200 synthetic trace files: a serial loop against a LocalCluster of 2
   worker processes.

    PYTHONPATH=build/python /usr/bin/python3 bench/python/compare_numpy.py [--rls-samples N] [--fleet]
"""

import argparse
import os
import pathlib
import platform
import statistics
import tempfile
import time

import numpy as np
import scipy
from scipy import signal

import feedid

SAMPLES = 1_000_000


def timed(function, repeats, clock=time.process_time):
    """Median time [s] of `repeats` runs, and the last result: CPU time of this process by default (the machine is
    shared; every job here runs on one core, numpy's and scipy's included), wall time for the cluster."""
    times, result = [], None
    for _ in range(repeats):
        start = clock()
        result = function()
        times.append(clock() - start)
    return statistics.median(times), result


# ---- 1. RLS

def padasip_rls_numpy(d, x, mu, eps):
    """padasip's FilterRLS.run loop in numpy: weights from zeros, R(0) = I / eps, forgetting factor mu."""
    samples, n = x.shape
    w = np.zeros(n)
    r = np.identity(n) / eps
    y, e, history = np.zeros(samples), np.zeros(samples), np.zeros((samples, n))
    for k in range(samples):
        history[k, :] = w
        y[k] = np.dot(w, x[k])
        e[k] = d[k] - y[k]
        r1 = r @ (x[k, :, None] * x[k, None, :]) @ r
        r2 = mu + np.dot(np.dot(x[k], r), x[k].T)
        r = 1 / mu * (r - r1 / r2)
        w += np.dot(r, x[k].T) * e[k]
    return y, e, history


def compare_rls(samples):
    rng = np.random.default_rng(1)
    truth = np.array([69.1, 54.2, 742.8])
    phi = np.column_stack([rng.normal(size=samples), rng.normal(size=samples) * 0.1, np.sign(rng.normal(size=samples))])
    y = phi @ truth + rng.normal(scale=5.0, size=samples)
    mu, eps = 1.0, 1e-6  # R(0) = 1e6 * I, as feedid's P(0)

    def feedid_rls(variant, forgetting, history):
        rls = feedid.Rls(3, forgetting_factor=forgetting, initial_covariance=1.0 / eps, variant=variant)
        out = rls.update_many(phi, y, history=history)
        return rls.estimate, out

    numpy_time, (_, _, numpy_history) = timed(lambda: padasip_rls_numpy(y, phi, mu, eps), 1)
    results = {}
    for variant, forgetting, history in (("exponential", mu, True), ("exponential", mu, False),
                                         ("directional", 0.9999, False)):
        results[(variant, forgetting, history)] = timed(lambda: feedid_rls(variant, forgetting, history), 5)
    exponential_time, (estimate, feedid_history) = results[("exponential", mu, True)]
    # the same algorithm: the weights agree (w(k) before sample k in padasip, after it in feedid)
    agreement = np.abs(feedid_history[-2] - numpy_history[-1]).max() / np.abs(truth).max()
    print(f"RLS, {samples} samples, 3 parameters (CPU time, median of 5; numpy once):")
    print(f"  numpy (padasip's loop, lambda {mu}, weights recorded)   {numpy_time * 1e3:10.1f} ms  "
          f"({numpy_time / samples * 1e9:.0f} ns per sample)")
    for (variant, forgetting, history), (seconds, (final, _)) in results.items():
        label = f"feedid.Rls.update_many {variant}, lambda {forgetting}{', history' if history else ''}"
        print(f"  {label:55s}{seconds * 1e3:10.1f} ms  ({seconds / samples * 1e9:.0f} ns per sample, "
              f"{numpy_time / seconds:.0f}x faster); estimate {np.round(final, 2)}")
    print(f"  truth {truth}; feedid's and numpy's weights agree to {agreement:.1e} (relative)")
    return numpy_time / exponential_time


# ---- 2. identification

def million_sample_trace():
    """A drive on sinusoidal strokes at nine speeds, 10 s each: t [s], x [m] (50 nm encoder), i [A] (450 N/A)."""
    dt = 1e-3
    t = np.arange(SAMPLES) * dt
    feeds = np.array([0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2])
    feed = feeds[(np.arange(SAMPLES) // 10000) % 9]
    w = 2 * np.pi / 2.0
    v = feed * np.sin(w * t)
    a = feed * w * np.cos(w * t)
    x = 50e-9 * np.round(np.cumsum(v * dt) / 50e-9)
    speed = np.abs(v)
    friction = np.where(speed > 0, 54.2 * speed + 742.8 + 203.4 * np.exp(-speed / 0.005), 0.0)
    current = (69.1 * a + np.copysign(friction, v)) / 450.0 + np.random.default_rng(2).uniform(-0.01, 0.01, SAMPLES)
    return t, x, current


def scipy_pipeline(t, x, current, force_per_ampere=450.0):
    """M, B, F_C with standard errors: zero-phase Butterworth, gradients, the fast moving samples, least squares."""
    dt = t[1] - t[0]
    sos = signal.butter(4, 100.0, fs=1.0 / dt, output="sos")
    position = signal.sosfiltfilt(sos, x)
    velocity = np.gradient(position, dt)
    acceleration = np.gradient(velocity, dt)
    force = current * force_per_ampere
    edge = int(2.5 / (100.0 * dt))  # the filter's start-up transient: 2.5 periods of the cut-off
    velocity, acceleration, force = velocity[edge:-edge], acceleration[edge:-edge], force[edge:-edge]
    speed = np.abs(velocity)
    split = 0.1 * np.percentile(speed, 95)  # above a tenth of the typical speed: no Stribeck rise
    fast = speed > split
    phi = np.column_stack([acceleration[fast], velocity[fast], np.sign(velocity[fast])])
    estimate, _, _, singular = np.linalg.lstsq(phi, force[fast], rcond=None)
    residual = force[fast] - phi @ estimate
    variance = residual @ residual / (len(residual) - phi.shape[1])
    standard_error = np.sqrt(np.diag(np.linalg.inv(phi.T @ phi)) * variance)
    return estimate, standard_error, singular[0] / singular[-1]


def compare_identify():
    t, x, current = million_sample_trace()

    def feedid_identify(systematic=True):
        trace = feedid.Trace.from_arrays(time=t, position=x, current=current)
        return feedid.identify(trace, force_constant=450.0, systematic=systematic)

    feedid_time, result = timed(feedid_identify, 5)
    feedid_wall, _ = timed(feedid_identify, 3, time.perf_counter)
    plain_time, plain = timed(lambda: feedid_identify(False), 5)
    scipy_time, (estimate, standard_error, condition) = timed(lambda: scipy_pipeline(t, x, current), 5)
    scipy_wall, _ = timed(lambda: scipy_pipeline(t, x, current), 3, time.perf_counter)
    p = result.parameters
    print(f"identify, {SAMPLES} samples, CPU time, median of 5 (truth M 69.1 kg, B 54.2 N*s/m, F_C 742.8 N, "
          "F_B 946.2 N, v_s 5 mm/s):")
    print(f"  numpy/scipy (sosfiltfilt + gradient + lstsq) {scipy_time * 1e3:8.1f} ms  M {estimate[0]:.2f} +- "
          f"{standard_error[0]:.2f} kg, B {estimate[1]:.1f} +- {standard_error[1]:.1f} N*s/m, F_C {estimate[2]:.1f} +- "
          f"{standard_error[2]:.1f} N (condition {condition:.0f})")
    print(f"  feedid (from_arrays + identify, everything) {feedid_time * 1e3:8.1f} ms  M {p['mass_kg'].value:.2f} +- "
          f"{p['mass_kg'].standard_error:.2f} kg, B {p['viscous_Ns_per_m'].value:.1f} +- "
          f"{p['viscous_Ns_per_m'].standard_error:.1f} N*s/m, F_C {p['coulomb_N'].value:.1f} +- "
          f"{p['coulomb_N'].standard_error:.1f} N, F_B {p['breakaway_N'].value:.1f} N, v_s "
          f"{p['stribeck_velocity_m_per_s'].value * 1e3:.2f} mm/s")
    print(f"  feedid without the systematic family (standard errors only) {plain_time * 1e3:8.1f} ms  M "
          f"{plain.parameters['mass_kg'].value:.2f} kg, B {plain.parameters['viscous_Ns_per_m'].value:.1f} N*s/m")
    print(f"  wall time (identify's family runs on every core): numpy/scipy {scipy_wall * 1e3:.1f} ms, feedid "
          f"{feedid_wall * 1e3:.1f} ms")
    print(f"  feedid / numpy-scipy CPU time: {feedid_time / scipy_time:.2f} (target at most 6), without the family "
          f"{plain_time / scipy_time:.2f} (target at most 2)")
    return feedid_time / scipy_time, plain_time / scipy_time


# ---- 3. fleet

def compare_fleet(count=200):
    import feedid.fleet

    with tempfile.TemporaryDirectory() as folder:
        paths = []
        for k in range(count):
            drive = feedid.demo_drive()
            drive["axis"]["mass_kg"] = 50.0 + k
            path = pathlib.Path(folder) / f"axis{k:03d}.csv"
            feedid.synth(drive, seed=k + 1, out=path)  # the demo test with slow passes: 45,566 samples each
            paths.append(str(path))
        options = dict(force_constant="force_constant_N_per_A")
        serial_cpu = time.process_time()
        serial_time, serial = timed(lambda: [feedid.fleet.identify_file(p, **options) for p in paths], 1,
                                    time.perf_counter)
        serial_cpu = time.process_time() - serial_cpu
        client, cluster = feedid.fleet._local_cluster(2)  # as identify_many makes it when given no client
        feedid.fleet.identify_many(paths[:4], client, **options)  # the workers import feedid once
        workers_before = client.run(time.process_time)
        client_cpu = time.process_time()
        parallel_time, frame = timed(lambda: feedid.fleet.identify_many(paths, client, **options), 1, time.perf_counter)
        client_cpu = time.process_time() - client_cpu
        workers = [client.run(time.process_time)[w] - start for w, start in workers_before.items()]
        client.close()
        cluster.close()
    same = [row["mass_kg"] for row in serial] == list(frame["mass_kg"])
    print(f"fleet, {count} traces of 45,566 samples (read, identify), wall time: serial {serial_time:.1f} s, "
          f"LocalCluster of 2 workers {parallel_time:.1f} s: {serial_time / parallel_time:.2f}x; same results: {same}")
    print(f"  CPU time: serial {serial_cpu:.1f} s; the workers {' and '.join(f'{w:.1f} s' for w in workers)}, "
          f"the calling process (client and scheduler) {client_cpu:.1f} s: on two free cores the batch takes the "
          f"busier worker's time, {serial_cpu / max(workers):.2f}x faster than the serial loop")


def machine():
    model = "unknown CPU"
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    load = os.getloadavg()
    return (f"{model}, {os.cpu_count()} cores, load {load[0]:.1f}; Python {platform.python_version()}, numpy "
            f"{np.__version__}, scipy {scipy.__version__}, feedid {feedid.__version__}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rls-samples", type=int, default=SAMPLES)
    parser.add_argument("--fleet", action="store_true", help="also the fleet comparison (about a minute)")
    arguments = parser.parse_args()
    print(machine())
    rls_ratio = compare_rls(arguments.rls_samples)
    full_ratio, plain_ratio = compare_identify()
    if arguments.fleet:
        compare_fleet()
    print(f"summary: Rls.update_many {rls_ratio:.0f}x faster than numpy (target >= 300x); identify takes "
          f"{full_ratio:.1f}x the numpy/scipy pipeline's CPU time (target <= 6x), {plain_ratio:.1f}x with "
          f"systematic=False (target <= 2x)")
    print(machine())


if __name__ == "__main__":
    main()
