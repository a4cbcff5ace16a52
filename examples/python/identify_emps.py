"""Identify the EMPS drive from Python, as the README does on the command line, and set the figures beside the
published IDIM-LS results (Janot, Gautier, Brunot 2019).

    python3 examples/python/identify_emps.py [../shared/data/emps/DATA_EMPS.mat]
"""

import pathlib
import sys

import feedid

PUBLISHED = {  # IDIM-LS, value and standard deviation
    "mass_kg": (95.1089, 0.1085),
    "viscous_Ns_per_m": (203.5034, 1.1460),
    "coulomb_N": (20.3935, 0.1012),
    "offset_N": (-3.1648, 0.0444),
}


def main() -> None:
    default = pathlib.Path(__file__).resolve().parents[2].parent / "shared" / "data" / "emps" / "DATA_EMPS.mat"
    path = sys.argv[1] if len(sys.argv) > 1 else str(default)
    # position qm [m], drive signal vir [V]; gtau, a scalar in the file, turns volts into newtons
    trace = feedid.read_trace(path, channels={"position": "qm", "current": "vir"})
    print(f"{trace.path}: {trace.samples} samples at {trace.sample_time_s * 1e3:.3g} ms, gtau = "
          f"{trace.constants['gtau']:.4f} N/V")
    # the reference preprocessing: 4th-order Butterworth at 100 Hz, decimation by 12, least squares on every sample
    result = feedid.identify(trace, force_constant="gtau", offset=True, filter_order=4, cutoff_hz=100,
                             decimation=12, edge_samples=49, split_velocity=0, moving_threshold=0)
    frame = result.to_pandas()
    frame["published"] = [PUBLISHED.get(key, (None, None))[0] for key in frame.index]
    frame["published_stderr"] = [PUBLISHED.get(key, (None, None))[1] for key in frame.index]
    frame["difference_pct"] = 100 * (frame["value"] - frame["published"]) / frame["published"].abs()
    columns = ["symbol", "unit", "value", "standard_error", "uncertainty", "published", "published_stderr",
               "difference_pct"]
    print(frame.dropna(subset=["value"])[columns].to_string(float_format=lambda v: f"{v:.4f}"))
    print(f"relative error {result.step1.relative_error_pct:.2f} % (published 4.0834 %), condition number "
          f"{result.step1.condition_number:.1f} (published 25.9883)")
    for diagnostic in result.diagnostics:
        print("note:", diagnostic)


if __name__ == "__main__":
    main()
