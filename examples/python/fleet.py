"""Identify a folder of traces on a Dask cluster with feedid.fleet.identify_many: one row per file.

Makes a folder of synthetic traces first (drives whose mass and Coulomb friction differ, as a plant's axes do), then
identifies them on a LocalCluster of worker processes, or on an existing cluster with --scheduler tcp://host:8786
(every worker needs feedid installed and the files at the same path).

    python3 examples/python/fleet.py [--traces 40] [--workers 2] [--folder DIR] [--scheduler ADDRESS]
"""

import argparse
import pathlib
import tempfile
import time

import feedid
import feedid.fleet


def make_traces(folder: pathlib.Path, count: int) -> list:
    paths = []
    for k in range(count):
        drive = feedid.demo_drive()
        drive["axis"]["mass_kg"] = 60.0 + 2.0 * k
        for key in ("coulomb_forward_N", "coulomb_reverse_N"):
            drive["axis"][key] *= 1.0 + 0.01 * k
        drive["test"]["feedrates_mm_per_min"] = [2000, 5000, 9000]
        path = folder / f"axis{k:03d}.csv"
        feedid.synth(drive, seed=k + 1, slow_passes=False, out=path)
        paths.append(path)
    return paths


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--traces", type=int, default=40)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--folder", type=pathlib.Path, default=None)
    parser.add_argument("--scheduler", default=None, help="address of a running Dask scheduler")
    arguments = parser.parse_args()
    with tempfile.TemporaryDirectory() as temporary:
        folder = arguments.folder or pathlib.Path(temporary)
        folder.mkdir(parents=True, exist_ok=True)
        paths = make_traces(folder, arguments.traces)
        client = None
        if arguments.scheduler:
            from dask.distributed import Client

            client = Client(arguments.scheduler)
        started = time.perf_counter()
        frame = feedid.fleet.identify_many(paths, client, workers=arguments.workers, machine="line 3",
                                           axis=lambda path: pathlib.Path(path).stem,
                                           force_constant="force_constant_N_per_A")
        elapsed = time.perf_counter() - started
        columns = ["axis", "status", "mass_kg", "mass_kg_stderr", "coulomb_N", "coulomb_N_stderr"]
        print(frame[columns].to_string(index=False, float_format=lambda v: f"{v:.2f}"))
        print(f"{len(frame)} traces in {elapsed:.1f} s ({frame['status'].value_counts().to_dict()})")


if __name__ == "__main__":
    main()
