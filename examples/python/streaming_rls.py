"""Streaming identification with feedid.Rls: force and motion arrive in chunks (as from a drive's trace buffer), each
chunk goes through Rls.update_many (the loop in C++, without the GIL), and the estimate follows the drive when a
load is clamped onto the table halfway through.

The drive: F = M*a + B*v + F_C*sgn(v) + noise with M 69.1 kg, then 89.1 kg from t = 60 s; B 54.2 N*s/m,
F_C 742.8 N; 1 kHz, 5 N of force noise. The regressor phi = [a, v, sgn v] [m/s^2, m/s, 1], y = F [N].

    python3 examples/python/streaming_rls.py [SECONDS]
"""

import sys
import time

import numpy as np

import feedid

RATE_HZ = 1000.0
CHUNK = 2000  # samples per chunk: 2 s


def drive_signals(seconds: float, rng: np.random.Generator):
    t = np.arange(0.0, seconds, 1.0 / RATE_HZ)
    # back-and-forth strokes at a few speeds: velocity [m/s] and acceleration [m/s^2]
    w = 2.0 * np.pi * 0.5
    speed = 0.05 + 0.1 * (np.floor(t / 10.0) % 3)
    v = speed * np.sin(w * t)
    a = speed * w * np.cos(w * t)
    mass = np.where(t < seconds / 2, 69.1, 89.1)
    force = mass * a + 54.2 * v + 742.8 * np.sign(v) + rng.normal(scale=5.0, size=t.size)
    phi = np.column_stack([a, v, np.sign(v)])
    return t, phi, force, mass


def main() -> None:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 120.0
    rng = np.random.default_rng(7)
    t, phi, force, mass = drive_signals(seconds, rng)
    # directional forgetting with lambda 0.9995: memory of about 1/(1 - lambda) = 2000 samples (2 s) of excitation
    rls = feedid.Rls(3, forgetting_factor=0.9995, variant="directional")
    print(f"{'t [s]':>7} {'M [kg]':>9} {'B [N*s/m]':>10} {'F_C [N]':>9}   true M")
    started = time.perf_counter()
    for start in range(0, t.size, CHUNK):
        chunk = slice(start, start + CHUNK)
        rls.update_many(phi[chunk], force[chunk])
        end = min(start + CHUNK, t.size) - 1
        if (end + 1) % (10 * CHUNK) == 0 or end == t.size - 1:
            m, b, fc = rls.estimate
            print(f"{t[end]:7.1f} {m:9.2f} {b:10.2f} {fc:9.2f}   {mass[end]:.1f}")
    elapsed = time.perf_counter() - started
    print(f"{t.size} samples in {elapsed * 1e3:.1f} ms ({elapsed / t.size * 1e9:.0f} ns per sample, "
          f"{rls.updates} updates)")


if __name__ == "__main__":
    main()
