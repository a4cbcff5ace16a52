"""feedid.fleet.identify_many on a Dask LocalCluster of 2 workers gives the DataFrame a serial loop gives, over 200
synthetic traces of drives with known masses; bad files are rows, not an aborted batch; runs go into a history."""

import numpy as np
import pandas as pd
import pytest

import feedid
import feedid.fleet

FORCE = "force_constant_N_per_A"
TRACES = 200
FAST = {"systematic": False}  # standard errors only: the batch's mechanics, a fifth of the time


@pytest.fixture(scope="module")
def traces(tmp_path_factory):
    from conftest import TEST_TMP

    folder = TEST_TMP / "test_fleet" / "traces"
    folder.mkdir(parents=True, exist_ok=True)
    paths, masses = [], []
    for k in range(TRACES):
        drive = feedid.demo_drive()
        drive["axis"]["mass_kg"] = 50.0 + k  # each file its own drive
        drive["test"]["feedrates_mm_per_min"] = [2000, 5000, 9000]
        path = folder / f"axis{k:03d}.csv"
        feedid.synth(drive, seed=k + 1, slow_passes=False, out=path)
        paths.append(str(path))
        masses.append(50.0 + k)
    return paths, masses


@pytest.fixture(scope="module")
def client():
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0")
    client = Client(cluster)
    yield client
    client.close()
    cluster.close()


def test_identify_many_on_two_workers_equals_a_serial_loop(traces, client):
    paths, masses = traces
    assert len(client.scheduler_info()["workers"]) == 2
    frame = feedid.fleet.identify_many(paths, client, machine="plant", axis=lambda path: path[-7:-4],
                                       force_constant=FORCE, **FAST)
    rows = [feedid.fleet.identify_file(path, machine="plant", axis=path[-7:-4], force_constant=FORCE, **FAST)
            for path in paths]
    serial = pd.DataFrame(rows).reindex(columns=frame.columns).astype({"samples_used": "Int64"})
    pd.testing.assert_frame_equal(frame, serial)
    assert list(frame["path"]) == paths and set(frame["status"]) == {"partial"}  # partial: no slow passes, no F_B
    # each row is feedid.identify's result for that file, and recovers that file's drive
    for index in (0, 77, 199):
        result = feedid.identify(paths[index], force_constant=FORCE, **FAST)
        for key, estimate in result.parameters.items():
            value = frame.loc[index, key]
            assert (np.isnan(value) and estimate.value is None) or value == estimate.value
        assert frame.loc[index, "coulomb_N_stderr"] == result.parameters["coulomb_N"].standard_error
        assert frame.loc[index, "diagnostics"] == "\n".join(result.diagnostics)
    assert np.corrcoef(frame["mass_kg"], masses)[0, 1] > 0.99  # the rows follow their files' drives
    assert frame.loc[3, "axis"] == "003" and frame.loc[3, "machine"] == "plant"


def test_bad_files_are_rows_and_runs_go_into_the_history(traces, client, folder):
    paths, _ = traces
    missing = str(folder / "missing.csv")
    not_a_trace = folder / "notes.csv"
    not_a_trace.write_text("hello\n")
    batch = [paths[0], missing, str(not_a_trace), paths[1]]
    database = folder / "fleet.db"
    frame = feedid.fleet.identify_many(batch, client, machine="plant", axis="X", history=database,
                                       force_constant=FORCE, **FAST)
    assert list(frame["status"]) == ["partial", "error", "error", "partial"]
    with pytest.raises(feedid.InputError) as error:
        feedid.identify(missing, force_constant=FORCE, **FAST)
    assert frame.loc[1, "reason"] == str(error.value)
    assert frame.loc[0, "reason"] is None and np.isnan(frame.loc[1, "mass_kg"])
    with feedid.History(database, read_only=True) as history:
        runs = history.runs()
    assert [run["id"] for run in runs] == [frame.loc[0, "run_id"], frame.loc[3, "run_id"]]
    assert frame.loc[1, "run_id"] is pd.NA and frame["run_id"].dtype == "Int64"
    assert runs[1]["parameters"]["mass_kg"]["value"] == frame.loc[3, "mass_kg"]
    # recording again: the same traces with the same options are not added twice
    again = feedid.fleet.identify_many(batch[:1], client, machine="plant", axis="X", history=database,
                                       force_constant=FORCE, **FAST)
    assert again.loc[0, "run_id"] == frame.loc[0, "run_id"]


def test_a_local_cluster_is_made_when_no_client_is_given(traces):
    paths, _ = traces
    frame = feedid.fleet.identify_many(paths[:4], workers=2, force_constant=FORCE, model="asymmetric",
                                       **FAST)
    assert list(frame["model"]) == ["asymmetric"] * 4 and "coulomb_forward_N" in frame.columns
    assert feedid.fleet.identify_many([], force_constant=FORCE, **FAST).empty
