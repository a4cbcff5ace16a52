"""Every way the module refuses input or reports a failed analysis: InputError (a ValueError) with the message the
command line prints before exit 2, IdentificationError with what it prints before exit 1, TypeError/KeyError where
Python's own conventions say so."""

import inspect
import json
import re

import numpy as np
import pytest

import feedid
from conftest import EMPS_CHANNELS, cli_error, run_cli

FORCE = "force_constant_N_per_A"


@pytest.fixture(scope="module")
def ladder():
    return feedid.synth(seed=2, slow_passes=False)


def test_the_exception_classes():
    assert issubclass(feedid.InputError, ValueError)
    assert issubclass(feedid.IdentificationError, RuntimeError)
    error = feedid.IdentificationError("why", ["why", "also"])
    assert error.diagnostics == ["why", "also"] and error.result is None


def test_input_errors_carry_the_command_lines_message(emps, folder):
    missing = str(folder / "missing.csv")
    expected = cli_error("identify", missing, "--force-constant", "1", expect=2)
    with pytest.raises(feedid.InputError) as error:
        feedid.identify(missing, force_constant=1)
    assert str(error.value) == expected
    with pytest.raises(feedid.InputError) as error:
        feedid.read_trace(missing)
    assert str(error.value) == expected

    expected = cli_error("identify", emps, "--channel", "position=qm", "--channel", "current=vir", expect=2)
    with pytest.raises(feedid.InputError) as error:
        feedid.identify(emps, channels=EMPS_CHANNELS)
    assert str(error.value) == expected

    expected = cli_error("identify", emps, "--channel", "position=nope", "--force-constant", "gtau", expect=2)
    with pytest.raises(feedid.InputError) as error:
        feedid.identify(emps, channels={"position": "nope"}, force_constant="gtau")
    assert str(error.value) == expected

    expected = cli_error("identify", emps, "--channel", "position=qm", "--unit", "position=furlong", "--force-constant",
                         "gtau", expect=2)
    with pytest.raises(feedid.InputError) as error:
        feedid.identify(emps, channels={"position": "qm"}, units={"position": "furlong"}, force_constant="gtau")
    assert str(error.value) == expected

    expected = cli_error("identify", emps, "--force-constant", "gtau", "--kt", "1", "--lead", "10", expect=2)
    with pytest.raises(feedid.InputError) as error:
        feedid.identify(emps, force_constant="gtau", kt_Nm_per_A=1, lead_mm=10)
    assert str(error.value) == expected
    # a value out of its range: the command line refuses it while parsing ("--kt: -1 is outside ..."); the same range
    kt_range = r"^kt_Nm_per_A=-1 is outside the allowed range 1e-05 to 500000 N\*m/A$"
    with pytest.raises(feedid.InputError, match=kt_range):
        feedid.identify(emps, kt_Nm_per_A=-1, lead_mm=10)


def test_bad_options(ladder):
    cases = [
        (dict(model="elliptic"), "model='elliptic': one of 'symmetric', 'asymmetric'"),
        (dict(differentiation="spline"), "differentiation='spline': one of 'butterworth', 'central', 'savitzky-golay'"),
        (dict(velocity_source="tacho"), "velocity_source='tacho': one of 'auto', 'position', 'velocity'"),
        (dict(rls="kalman"), "rls='kalman': one of 'directional', 'paper'"),
        (dict(filter_order="4"), "filter_order='4': expected an integer, not str"),
        (dict(cutoff_hz="100"), "cutoff_hz='100': expected a number, not str"),
        (dict(offset="yes"), "offset='yes': expected True or False, not str"),
        (dict(edge_samples=-1), "edge_samples=-1 is outside the allowed range 0 to 1e+09 samples"),
        (dict(force_constant=0.0), "--force-constant 0 is not allowed: a force constant is a finite number of either "
                                   "sign with a magnitude from 1e-09 to 1e+09 N (N*m on a rotary axis) per unit of the "
                                   "drive signal"),
    ]
    for options, message in cases:
        options.setdefault("force_constant", FORCE)
        with pytest.raises(feedid.InputError) as error:
            feedid.identify(ladder, **options)
        assert str(error.value) == message, options
    with pytest.raises(feedid.InputError, match=r"^forgetting_factor=1.5 is outside the allowed range 1e-06 to 1$"):
        feedid.identify(ladder, force_constant=FORCE, forgetting_factor=1.5)
    with pytest.raises(TypeError):
        feedid.identify(ladder, force_constant=FORCE, no_such_option=1)
    with pytest.raises(feedid.InputError, match="^channels: a reading option, for a path; this trace is read already$"):
        feedid.identify(ladder, force_constant=FORCE, channels={"position": "x"})
    with pytest.raises(feedid.InputError, match="expected a feedid.Trace or the path of a trace file, not int"):
        feedid.identify(42, force_constant=FORCE)
    with pytest.raises(feedid.InputError, match=r"^channels\['position'\]=3: expected a str, not int$"):
        feedid.identify("x.csv", channels={"position": 3}, force_constant=FORCE)


def test_reading_options(emps):
    expected = cli_error("info", emps, "--channel", "speed=qm", expect=2)
    with pytest.raises(feedid.InputError) as error:
        feedid.read_trace(emps, channels={"speed": "qm"})
    assert str(error.value) == expected.replace("--channel", "channels")
    with pytest.raises(feedid.InputError, match="^skip_rows=-1 is outside the allowed range 0 to 1e\\+09 lines$"):
        feedid.read_trace(emps, skip_rows=-1)
    with pytest.raises(feedid.InputError, match="^join_max_shift_s needs join='FILE@auto'$"):
        feedid.read_trace(emps, join_max_shift_s=0.1)
    with pytest.raises(feedid.InputError, match="^tare time: not a role to zero"):
        feedid.read_trace(emps, tare=["time"])
    with pytest.raises(feedid.InputError, match="^invert time: not a role to invert"):
        feedid.read_trace(emps, invert=["time"])
    with pytest.raises(feedid.InputError, match="--invert force: the trace has no force channel"):
        feedid.read_trace(emps, channels=EMPS_CHANNELS, invert=["force"])
    with pytest.raises(feedid.InputError, match="unknown format"):
        feedid.read_trace(emps, format="xlsx")
    with pytest.raises(feedid.InputError, match="read_trace: expected a path"):
        feedid.read_trace(3.5)


def test_an_identification_that_fails_raises_with_the_command_lines_lines(sinumerik):
    completed = run_cli("identify", sinumerik, "--force-constant", "1", expect=1)
    findings = feedid.read_trace(sinumerik).findings
    printed = [line[len("feedid: "):] for line in completed.stderr.strip().splitlines()]
    expected = [line for line in printed if line not in findings]
    with pytest.raises(feedid.IdentificationError) as error:
        feedid.identify(sinumerik, force_constant=1)
    assert str(error.value).splitlines() == expected
    assert error.value.diagnostics == expected
    assert error.value.result.status == "failed"
    assert "carries no usable mass information" in str(error.value)


def test_gains_that_cannot_be_trusted_or_determined(folder, ladder):
    path = folder / "injected.csv"
    feedid.synth(seed=2, slow_passes=False, injection=(300.0, 1.0), out=path)
    expected = cli_error("gains", path, "--force-constant", FORCE, expect=1)
    with pytest.raises(feedid.IdentificationError) as error:
        feedid.gains(str(path), force_constant=FORCE)
    assert str(error.value) == expected
    assert error.value.result.status == "failed" and error.value.result.systematic_error_pct > 3.0
    # with the injection's role the fit is good
    assert feedid.gains(str(path), force_constant=FORCE, channels={"injection": "injection"}).status == "ok"
    # too few samples: the library's AnalysisError
    short = feedid.Trace.from_arrays(time=ladder["t"][:30], position=ladder["x"][:30], current=ladder["i"][:30],
                                     reference_position=ladder["x_ref"][:30], constants=ladder.constants)
    with pytest.raises(feedid.IdentificationError, match="too few to identify controller gains") as error:
        feedid.gains(short, force_constant=FORCE)
    assert error.value.result is None
    with pytest.raises(feedid.InputError, match="velocity_loop='pid': one of 'auto', 'p', 'pi'"):
        feedid.gains(ladder, force_constant=FORCE, velocity_loop="pid")
    with pytest.raises(feedid.InputError, match="^velocity_difference=9 is outside the allowed range 1 to 8 samples$"):
        feedid.gains(ladder, force_constant=FORCE, velocity_difference=9)


def test_simulate_refuses_and_fails(ladder):
    result = feedid.identify(ladder, force_constant=FORCE)
    rotary = feedid.synth(rotary=True, slow_passes=False)
    with pytest.raises(feedid.InputError, match="the result is of a linear axis, the trace .* of a rotary axis"):
        feedid.simulate(rotary, result, force_constant="torque_constant_Nm_per_A")
    with pytest.raises(feedid.InputError, match="not an identify result|missing"):
        feedid.simulate(ladder, {"parameters": {}}, force_constant=FORCE)
    with pytest.raises(feedid.InputError, match="gains: expected a feedid result, a dict or the path"):
        feedid.simulate(ladder, result, 42, force_constant=FORCE)
    # a twin that diverges: the controller's gains two hundred times too high for the mass
    gains = feedid.gains(ladder, force_constant=FORCE).to_dict()
    gains["gains"]["velocity_gain_N_s_per_m"]["value"] *= 200
    with pytest.raises(feedid.IdentificationError) as error:
        feedid.simulate(ladder, result, gains, force_constant=FORCE)
    assert error.value.result.status == "failed"
    assert str(error.value) == error.value.result.to_dict()["diagnostics"][0] or str(error.value) in \
        error.value.result.diagnostics


def test_simulate_refuses_a_result_that_does_not_fit_the_trace(ladder, folder):
    """The command line's check that the result is of this axis in these units, made by Python too (both call the
    one twin): a result whose mass and friction are 1000 times too large (mm or mN read as m or N), or a drive signal
    of the opposite sign, is refused with the command line's message."""
    path = folder / "fit.csv"
    ladder.to_csv(str(path))
    result = feedid.identify(ladder, force_constant=FORCE).to_dict()
    scaled = json.loads(json.dumps(result))
    for key, entry in scaled["parameters"].items():
        if key.startswith(("mass", "viscous", "coulomb", "breakaway")) and entry["value"] is not None:
            entry["value"] *= 1000.0
    scaled_path = folder / "scaled.json"
    scaled_path.write_text(json.dumps(scaled))
    expected = cli_error("simulate", path, "--force-constant", FORCE, "--result", scaled_path, expect=2)
    assert expected.startswith(f"{scaled_path}: the result does not fit the trace {path}: "), expected
    with pytest.raises(feedid.InputError) as error:
        feedid.simulate(str(path), str(scaled_path), force_constant=FORCE)
    assert str(error.value) == expected
    with pytest.raises(feedid.InputError, match="^result: the result does not fit the trace .*0.001"):
        feedid.simulate(ladder, scaled, force_constant=FORCE)

    result_path = folder / "fit.json"
    result_path.write_text(json.dumps(result))
    flipped = -ladder.constants[FORCE]
    expected = cli_error("simulate", path, "--force-constant", repr(flipped), "--result", result_path, expect=2)
    assert "does not fit" in expected and "opposite" in expected, expected
    with pytest.raises(feedid.InputError) as error:
        feedid.simulate(str(path), str(result_path), force_constant=flipped)
    assert str(error.value) == expected
    # the result as it is, with the drive signal's own sign: simulated
    assert feedid.simulate(str(path), str(result_path), force_constant=FORCE).status == "ok"


def test_synth_and_plan_refuse(folder):
    cases = [
        (dict(preset="fanuc"), "preset='fanuc': the presets are 'sinumerik'"),
        (dict(injection=(300.0,)), "injection: expected (amplitude_N, frequency_Hz), e.g. (300.0, 1.0)"),
        (dict(injection=("300N", "1Hz")), "injection: expected (amplitude_N, frequency_Hz), e.g. (300.0, 1.0)"),
        (dict(drive=42), "drive: expected a dict of the drive file's keys or the path of a drive file"),
        (dict(seed=-1), "seed=-1: must be 0 or more"),
        (dict(reference=[0.0, np.nan, 1.0]), "reference: a value that is not finite"),
    ]
    for options, message in cases:
        with pytest.raises(feedid.InputError) as error:
            feedid.synth(**options)
        assert str(error.value) == message
    with pytest.raises(feedid.InputError, match="^injection: "):
        feedid.synth(injection=(300.0, 1000.0))
    with pytest.raises(feedid.InputError, match="describes a linear axis"):
        feedid.synth(feedid.demo_drive(), rotary=True)
    with pytest.raises(feedid.InputError, match="cannot write the file"):
        feedid.synth(slow_passes=False, out=folder / "no-such-folder" / "x.csv")
    expected = cli_error("plan", "--travel=-100:100", "--centers=90", expect=2)
    with pytest.raises(feedid.InputError) as error:
        feedid.plan(travel_mm=(-100, 100), centers_mm=[90])
    assert str(error.value) == expected
    with pytest.raises(feedid.InputError, match=r"travel_mm: expected \(min, max\)"):
        feedid.plan(travel_mm=(-100, 0, 100), centers_mm=[0])
    with pytest.raises(feedid.InputError, match="centers_mm: 'a' is not a number"):
        feedid.plan(travel_mm=(-100, 100), centers_mm=["a"])
    with pytest.raises(feedid.InputError, match=r"^axis 'C' is a rotary axis: feedid.plan takes mm .* --axis C"):
        feedid.plan(axis="C", travel_mm=(-100, 100), centers_mm=[0])
    with pytest.raises(feedid.InputError, match="dialect='heidenhain'"):
        feedid.plan(travel_mm=(-400, 400), centers_mm=[0]).part_program("heidenhain")


def test_rls_refuses():
    with pytest.raises(feedid.InputError, match="n=0 parameters; 1 to 8 are supported"):
        feedid.Rls(0)
    with pytest.raises(feedid.InputError, match="n=9 parameters"):
        feedid.Rls(9)
    with pytest.raises(feedid.InputError, match="variant='kalman'"):
        feedid.Rls(3, variant="kalman")
    with pytest.raises(feedid.InputError, match="forgetting_factor=0: must be in"):
        feedid.Rls(3, forgetting_factor=0.0)
    with pytest.raises(feedid.InputError, match="initial_covariance=-1: must be positive"):
        feedid.Rls(3, initial_covariance=-1.0)
    with pytest.raises(feedid.InputError, match=r"initial_estimate must be 3 numbers"):
        feedid.Rls(3, initial_estimate=[1.0, 2.0])
    rls = feedid.Rls(3)
    with pytest.raises(feedid.InputError, match=r"phi must be 3 numbers"):
        rls.update([1.0, 2.0], 1.0)
    with pytest.raises(feedid.InputError, match=r"Phi must have shape \(m, 3\), not \(10, 2\)"):
        rls.update_many(np.zeros((10, 2)), np.zeros(10))
    with pytest.raises(feedid.InputError, match=r"Y must have shape \(10,\), not \(9,\)"):
        rls.update_many(np.zeros((10, 3)), np.zeros(9))
    with pytest.raises(feedid.InputError, match="Phi and Y must be arrays of numbers"):
        rls.update_many([["a", "b", "c"]], [1.0])
    with pytest.raises(TypeError):
        rls.update([1.0, 2.0, 3.0], "y")


def test_history_refuses(folder, ladder):
    not_history = folder / "other.db"
    not_history.write_bytes(b"SQLite format 3\x00" + bytes(100))
    with pytest.raises(feedid.InputError, match="other.db"):
        feedid.History(not_history)
    text = folder / "notes.txt"
    text.write_text("not a database")
    expected = cli_error("history", text, expect=2)
    with pytest.raises(feedid.InputError) as error:
        feedid.History(text)
    assert str(error.value) == expected
    result = feedid.identify(ladder, force_constant=FORCE)
    with feedid.History(folder / "runs.db") as history:
        with pytest.raises(feedid.InputError, match="History.record"):
            history.record(result, machine="", axis="X", trace=folder / "runs.db")
        with pytest.raises(feedid.InputError, match="trace|file"):
            history.record(result, machine="M", axis="X")  # a trace made in memory: no file to hash
        with pytest.raises(feedid.InputError, match="not a feedid identify result document"):
            history.record({"nothing": 1}, machine="M", axis="X", trace=folder / "runs.db")
        with pytest.raises(feedid.InputError, match="there is no run #7"):
            history.pin(7)
        with pytest.raises(feedid.InputError, match="baseline"):
            history.check(baseline_runs=0)
    with pytest.raises(feedid.InputError, match="the history is closed"):
        history.runs()


def test_estimates_results_and_documents_refuse():
    with pytest.raises(feedid.InputError, match="Estimate has no field 'error'"):
        feedid.Estimate(error=1.0)
    with pytest.raises(feedid.InputError, match="Estimate takes at most"):
        feedid.Estimate(*range(len(feedid.Estimate._fields) + 1))
    with pytest.raises(feedid.InputError, match="Estimate: value must be a number or None, not str"):
        feedid.Estimate("95")
    with pytest.raises(feedid.InputError, match=r"not an identify result \(no \"parameters\" object\)"):
        feedid.Result.from_dict({"model": "symmetric"})
    with pytest.raises(feedid.InputError, match=r"result.parameters: a key that is not a string \(1\)"):
        feedid.Result.from_dict({"parameters": {1: {}}})
    with pytest.raises(feedid.InputError, match="is not a JSON value"):
        feedid.Result.from_dict({"parameters": {}, "extra": object()})
    with pytest.raises(feedid.InputError, match="constants\\['k'\\]: not a number"):
        feedid.Trace.from_arrays(time=[0.0, 1.0], position=[0.0, 1.0], constants={"k": "x"})


def test_fleet_refuses_before_it_starts():
    with pytest.raises(TypeError):
        feedid.fleet.identify_many(["a.csv"], misspelt_option=1)
    with pytest.raises(feedid.InputError, match="needs machine= and axis="):
        feedid.fleet.identify_many(["a.csv"], history="runs.db")


def test_json_documents_from_paths(folder, ladder):
    broken = folder / "broken.json"
    broken.write_text("{")
    with pytest.raises(feedid.InputError, match="broken.json: not a JSON document"):
        feedid.simulate(ladder, broken, force_constant=FORCE)
    result = folder / "result.json"
    result.write_text(json.dumps(feedid.identify(ladder, force_constant=FORCE).to_dict()))
    assert feedid.simulate(ladder, result, force_constant=FORCE).status == "ok"


def test_no_option_takes_nan_or_an_infinity(ladder, folder):
    """Every number-valued keyword of the functions that take options (from their signatures, so that a new option
    is covered) refuses nan and infinities naming the option, as the command line does while parsing."""
    path = str(folder / "ladder.csv")
    ladder.to_csv(path)
    result = feedid.identify(ladder, force_constant=FORCE)
    calls = {
        feedid.identify: lambda **o: feedid.identify(path, **{"force_constant": FORCE, **o}),
        feedid.gains: lambda **o: feedid.gains(path, **{"force_constant": FORCE, **o}),
        feedid.simulate: lambda **o: feedid.simulate(path, result, **{"force_constant": FORCE, **o}),
        feedid.plan: lambda **o: feedid.plan(**{"travel_mm": (-400, 400), "centers_mm": [0], **o}),
        feedid.read_trace: lambda **o: feedid.read_trace(path, **o),
    }
    checked = 0
    for function, call in calls.items():
        for name, parameter in inspect.signature(function).parameters.items():
            if str(parameter.annotation) not in ("float", "Optional[float]", "Union[float, str, None]"):
                continue  # a number alone (lists of numbers: below)
            for bad in (float("nan"), float("inf"), -float("inf")):
                with pytest.raises(feedid.InputError, match=f"^{name}={bad!r}: not a finite number$"):
                    call(**{name: bad})
            checked += 1
    assert checked >= 30
    with pytest.raises(feedid.InputError, match="centers_mm: nan is not a finite number"):
        feedid.plan(travel_mm=(-400, 400), centers_mm=[float("nan")])
    with pytest.raises(feedid.InputError, match="travel_mm: inf is not a finite number"):
        feedid.plan(travel_mm=(-400, float("inf")), centers_mm=[0])
    with pytest.raises(feedid.InputError, match="slow_feeds_mm_per_min: nan is not a finite number"):
        feedid.plan(travel_mm=(-400, 400), centers_mm=[0], slow_feeds_mm_per_min=[10.0, float("nan")])
    with pytest.raises(feedid.InputError, match="^injection: expected"):
        feedid.synth(injection=(float("nan"), 1.0))


# Python keyword -> the command line's option, per command: the ranges the command line states for its options.
RANGED = {
    "identify": {"filter_order": "--filter-order", "cutoff_hz": "--cutoff", "savitzky_golay_window": "--sg-window",
                 "savitzky_golay_order": "--sg-order", "decimation": "--decimate", "edge_samples": "--edge-samples",
                 "from_s": "--from", "to_s": "--to", "split_velocity": "--split-velocity",
                 "moving_threshold": "--moving-threshold", "forgetting_factor": "--lambda",
                 "initial_covariance": "--p0", "kt_Nm_per_A": "--kt", "lead_mm": "--lead", "gear_ratio": "--gear-ratio",
                 "sample_time_s": "--sample-time", "skip_rows": "--skip-rows", "join_max_shift_s": "--join-max-shift"},
    "gains": {"velocity_difference": "--velocity-difference", "current_lag_ms": "--current-lag-ms",
              "saturation": "--saturation", "forgetting": "--forgetting"},
    "simulate": {"substeps": "--substeps"},
    "plan": {"stroke_mm": "--stroke", "max_pass_time_s": "--max-pass-time", "cycles": "--cycles",
             "acceleration_m_per_s2": "--acceleration", "jerk_m_per_s3": "--jerk", "dwell_s": "--dwell",
             "sample_time_s": "--sample-time", "max_feed_mm_per_min": "--max-feed",
             "positioning_feed_mm_per_min": "--positioning-feed", "start_mm": "--start", "mass_kg": "--mass",
             "viscous_Ns_per_m": "--viscous", "coulomb_N": "--coulomb", "breakaway_N": "--breakaway",
             "stribeck_velocity_mm_per_s": "--stribeck-velocity", "force_noise_N": "--force-noise",
             "level_error_N": "--level-error", "position_resolution_um": "--position-resolution"},
}


def test_options_have_the_command_lines_ranges(ladder, folder):
    """A value the command line refuses as outside an option's range, Python refuses for that keyword, stating the same
    range (the command line refuses while parsing, before any file is read)."""
    path = str(folder / "ladder.csv")
    ladder.to_csv(path)
    result_path = folder / "result.json"
    result_path.write_text(json.dumps(feedid.identify(ladder, force_constant=FORCE).to_dict()))
    base = {"identify": ["identify", path, "--force-constant", "1"], "gains": ["gains", path, "--force-constant", "1"],
            "simulate": ["simulate", path, "--force-constant", "1", "--result", str(result_path)],
            "plan": ["plan", "--travel=-400:400", "--centers=0"]}
    python = {"identify": lambda **o: feedid.identify(path, **o), "gains": lambda **o: feedid.gains(path, **o),
              "simulate": lambda **o: feedid.simulate(path, str(result_path), **o),
              "plan": lambda **o: feedid.plan(travel_mm=(-400, 400), centers_mm=[0], **o)}
    compared = 0
    for command, options in RANGED.items():
        for keyword, option in options.items():
            parameter = inspect.signature(getattr(feedid, command)).parameters[keyword]
            whole = "int" in str(parameter.annotation)
            for value in ((10**9 + 7, -10**9 - 7) if whole else (1e300, -1e300)):
                refused = run_cli(*base[command], option, str(value), expect=None)
                # plan's ranges name both units of an option (mm or deg); Python's keywords are the linear ones
                cli = re.search(r"is outside the allowed range (.*?)(?: or \S+)?$", refused.stderr.strip())
                if refused.returncode != 2 or not cli:
                    continue
                extra = {"lead_mm": 10} if keyword == "kt_Nm_per_A" else {}
                with pytest.raises(feedid.InputError) as error:
                    python[command](**{keyword: value, **extra})
                ours = re.search(r"is outside the allowed range (.*?)(?: or \S+)?$", str(error.value))
                assert ours and ours.group(1) == cli.group(1), (command, keyword, value, str(error.value))
                compared += 1
    assert compared >= 70
