"""feedid.History records runs as `feedid identify --record` does, and lists and checks them as `feedid history`."""

import json

import pytest

import feedid
from conftest import run_cli

FORCE = "force_constant_N_per_A"


def drive_with_coulomb(factor):
    drive = feedid.demo_drive()
    for key in ("coulomb_forward_N", "coulomb_reverse_N"):
        drive["axis"][key] *= factor
    for key in ("breakaway_forward_N", "breakaway_reverse_N"):
        drive["axis"][key] *= factor
    drive["test"]["feedrates_mm_per_min"] = [2000, 5000, 9000]
    return drive


def test_record_list_and_check_as_the_command_line(folder):
    database = folder / "shop.db"
    recorded = []
    with feedid.History(database) as history:
        for run in range(12):
            # Coulomb friction rises 3 % per run from run 9: a drift the CUSUM must catch
            path = folder / f"run{run:02d}.csv"
            feedid.synth(drive_with_coulomb(1.0 + 0.03 * max(0, run - 8)), seed=run + 1, slow_passes=False, out=path)
            result = feedid.identify(str(path), force_constant=FORCE)
            run_id, inserted = history.record(result, machine="DMU50", axis="X",
                                              recorded_at=f"2026-01-{run + 1:02d}T08:00:00Z")
            assert inserted
            recorded.append((run_id, result))
        # the same trace with the same options again: nothing added
        assert history.record(recorded[0][1], machine="DMU50", axis="X") == (recorded[0][0], False)
        runs = history.runs(machine="DMU50", axis="X")
        alarms = history.check()
        trends = history.trends()
        assert history.schema_version >= 4
    listed = json.loads(run_cli("history", database, "--json", "-").stdout)
    assert runs == listed["runs"]
    assert trends == listed["trends"]
    assert [run["id"] for run in runs] == [run_id for run_id, _ in recorded]
    stored, identified = runs[3]["parameters"]["mass_kg"], recorded[3][1].parameters["mass_kg"]
    assert (stored["value"], stored["stderr"]) == (identified.value, identified.standard_error)
    check = run_cli("history", database, "--check", expect=1)
    assert alarms == check.stdout.strip().splitlines()
    assert any("coulomb_N" in alarm for alarm in alarms)

    with feedid.History(database, read_only=True) as history:
        frame = history.to_pandas(axis="X")
        assert list(frame["id"]) == [run_id for run_id, _ in recorded]
        assert frame["mass_kg"].iloc[0] == recorded[0][1].parameters["mass_kg"].value
        assert frame["coulomb_N_stderr"].iloc[5] == recorded[5][1].parameters["coulomb_N"].standard_error
        with pytest.raises(feedid.InputError):
            history.record(recorded[0][1], machine="DMU50", axis="Y")  # read only


def test_pin_starts_a_new_baseline(folder):
    database = folder / "pinned.db"
    with feedid.History(database) as history:
        ids = []
        for run in range(3):
            path = folder / f"run{run}.csv"
            feedid.synth(drive_with_coulomb(1.0), seed=run + 1, slow_passes=False, out=path)
            ids.append(history.record(feedid.identify(str(path), force_constant=FORCE), machine="M", axis="Z",
                                      recorded_at=f"2026-02-0{run + 1}")[0])
        history.pin(ids[1])
        assert history.trends()[0]["pinned_run"] == ids[1]
    listed = json.loads(run_cli("history", database, "--json", "-").stdout)
    assert listed["trends"][0]["pinned_run"] == ids[1]


def test_a_postgresql_history_holds_what_a_sqlite_file_holds(folder, postgres):
    """The same runs recorded through Python into PostgreSQL and into SQLite list, trend and check alike, and the
    command line reads the PostgreSQL history as Python wrote it."""
    location = postgres.create_database("python_history")
    sqlite = folder / "shop.db"
    results = []
    for run in range(10):
        path = folder / f"run{run:02d}.csv"
        feedid.synth(drive_with_coulomb(1.0 + 0.04 * max(0, run - 6)), seed=run + 1, slow_passes=False, out=path)
        results.append(feedid.identify(str(path), force_constant=FORCE))
    for where in (location, sqlite):
        with feedid.History(where) as history:
            for run, result in enumerate(results):
                _, inserted = history.record(result, machine="DMU50", axis="X",
                                             recorded_at=f"2026-03-{run + 1:02d}T08:00:00Z")
                assert inserted
    with feedid.History(location, read_only=True) as on_postgres, feedid.History(sqlite) as on_sqlite:
        assert on_postgres.path == location
        listed = on_postgres.runs(axis="X")
        assert len(listed) == len(results)
        strip = lambda runs: [{k: v for k, v in r.items() if k not in ("id", "stored_at")} for r in runs]
        assert strip(listed) == strip(on_sqlite.runs(axis="X"))
        alarms = on_postgres.check()
        assert alarms == on_sqlite.check()
        assert any("coulomb_N" in alarm for alarm in alarms)
        assert on_postgres.to_pandas()["coulomb_N"].tolist() == on_sqlite.to_pandas()["coulomb_N"].tolist()
        with pytest.raises(feedid.InputError):
            on_postgres.record(results[0], machine="DMU50", axis="Y")  # read only
    cli = json.loads(run_cli("history", location, "--json", "-").stdout)
    assert [r["id"] for r in cli["runs"]] == [r["id"] for r in listed]
    assert run_cli("history", location, "--check", expect=1).stdout.strip().splitlines() == alarms


def test_an_unreachable_postgresql_history_is_an_input_error(postgres):
    with pytest.raises(feedid.InputError, match="127.0.0.1"):
        feedid.History(f"postgresql://feedid_admin@127.0.0.1:{postgres.port}/no_such_database")
