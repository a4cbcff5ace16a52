"""identify, gains, simulate, synth and plan through Python give what the command line gives (the same library
underneath: the documents agree to 1e-12 relative), and the Result's typed records hold the document's numbers."""

import json
import pickle

import numpy as np
import pandas as pd
import pytest

import feedid
from conftest import EMPS_CHANNELS, SHARED_DATA, assert_documents_equal, cli_json, run_cli, shared

TOLERANCE = 1e-12  # relative (issue 17)
EMPS_GAINS = {"position": "qm", "reference_position": "qg", "current": "vir"}


def test_emps_through_python_equals_the_cli(emps):
    expected = cli_json("identify", emps, "--channel", "position=qm", "--channel", "current=vir", "--force-constant",
                        "gtau", "--offset")
    result = feedid.identify(emps, channels=EMPS_CHANNELS, force_constant="gtau", offset=True)
    assert_documents_equal(result.to_dict(), expected, TOLERANCE)
    # the published IDIM-LS figures the README holds feedid to (tests/identify/test_identify.cpp): within 2 %
    assert result.parameters["mass_kg"].value == pytest.approx(95.1089, rel=0.02)
    assert result.parameters["offset_N"].value == pytest.approx(-3.1648, rel=0.02)


def test_emps_from_a_trace_read_first_and_the_reference_preprocessing(emps):
    options = ["--filter-order", "4", "--cutoff", "100", "--decimate", "12", "--edge-samples", "49",
               "--split-velocity", "0", "--moving-threshold", "0"]
    expected = cli_json("identify", emps, "--channel", "position=qm", "--channel", "current=vir", "--force-constant",
                        "gtau", "--offset", *options)
    trace = feedid.read_trace(emps, channels=EMPS_CHANNELS)
    result = feedid.identify(trace, force_constant="gtau", offset=True, filter_order=4, cutoff_hz=100, decimation=12,
                             edge_samples=49, split_velocity=0, moving_threshold=0)
    assert_documents_equal(result.to_dict(), expected, TOLERANCE)
    expected = cli_json("identify", emps, "--channel", "position=qm", "--channel", "current=vir", "--force-constant",
                        "gtau", "--model", "asymmetric", "--rls", "paper", "--differentiation", "savitzky-golay")
    result = feedid.identify(trace, force_constant="gtau", model="asymmetric", rls="paper",
                             differentiation="savitzky-golay")
    assert_documents_equal(result.to_dict(), expected, TOLERANCE)


def test_the_results_records_hold_the_documents_numbers(emps):
    result = feedid.identify(emps, channels=EMPS_CHANNELS, force_constant="gtau", offset=True)
    document = result.to_dict()
    assert result.status == document["status"] == "partial"
    assert result.model == "symmetric" and result.offset and not result.rotary
    assert result.feedid_version == feedid.__version__
    for key, entry in document["parameters"].items():
        assert result.parameters[key].to_dict() == entry
    assert result.units["mass_kg"] == "kg" and result.symbols["viscous_Ns_per_m"] == "B"
    assert result.trace.samples == document["trace"]["samples"] == 24841
    assert result.preprocessing.cutoff_hz == document["preprocessing"]["cutoff_hz"]
    assert result.selection.notes == document["selection"]["notes"]
    assert result.step1.condition_number == document["fit"]["condition_number"]
    assert {k: e.to_dict() for k, e in result.step1.batch.items()} == document["step1"]["batch"]
    assert result.step1.r_diagonal.tolist() == document["fit"]["r_diagonal"]
    assert result.rls.final == document["rls"]["final"] and result.rls.averaged == document["rls"]["averaged"]
    assert result.rls.history_time_s.tolist() == document["rls"]["history"]["time_s"]
    assert result.rls.history["mass_kg"].tolist() == document["rls"]["history"]["mass_kg"]
    assert result.stribeck.forward.samples_used == document["stribeck"]["forward"]["log_linear"]["samples_used"]
    assert result.stribeck.nonlinear is None  # EMPS has no slow passes: no curve
    assert result.friction_curve.forward.speed.tolist() == document["friction_curve"]["forward"]["velocity_m_per_s"]
    assert result.friction_only is None
    mass = result.parameters["mass_kg"]  # the C++ Estimate's fields, each an attribute
    assert (mass.systematic, mass.uncertainty) == (document["parameters"]["mass_kg"]["systematic"],
                                                    document["parameters"]["mass_kg"]["uncertainty"])
    assert [v.label for v in result.systematic.variants] == \
        [v["preprocessing"] for v in document["systematic"]["variants"]]
    assert result.systematic.variants[0].parameters == document["systematic"]["variants"][0]["parameters"]
    keys = result.step1.keys
    assert result.step1.correlation[0, 1] == document["fit"]["correlations"][keys[0]][keys[1]]
    assert result.step1.white_noise_standard_error == document["step1"]["white_noise_stderr"]
    assert result.selection.passes == document["selection"]["passes"]
    assert result.diagnostics == document["diagnostics"]
    assert result.options == document["options"]
    # the DataFrame: one row per parameter, None as NaN
    frame = result.to_pandas()
    assert list(frame.index) == list(result.parameters) and sorted(frame.index) == sorted(document["parameters"])
    assert frame.loc["mass_kg", "value"] == document["parameters"]["mass_kg"]["value"]
    assert frame.loc["coulomb_N", "standard_error"] == document["parameters"]["coulomb_N"]["stderr"]
    assert np.isnan(frame.loc["breakaway_N", "value"])
    # back from its document
    again = feedid.Result.from_dict(document)
    assert again.to_dict() == document
    assert json.loads(result.to_json()) == document


def test_the_results_repr_is_the_brief_report_feedid_identify_prints(emps):
    result = feedid.identify(emps, channels=EMPS_CHANNELS, force_constant="gtau", offset=True, systematic=False)
    printed = run_cli("identify", emps, "--channel", "position=qm", "--channel", "current=vir", "--force-constant",
                      "gtau", "--offset", "--no-systematic").stdout
    brief = repr(result)
    assert printed.startswith(brief + "\n")
    lines = brief.splitlines()
    assert lines[0] == f"{emps} (24841 samples, 24.84 s)"
    assert lines[1] == "model: symmetric with offset, status: partial"
    for key, estimate in result.parameters.items():
        row = next(line for line in lines[3:] if line.split()[0] == result.symbols[key])
        if estimate.value is None:
            assert row.split() == [result.symbols[key], "—", result.units[key]]
        else:
            assert row.split()[:4] == [result.symbols[key], f"{estimate.value:.6g}", "±",
                                       f"{estimate.standard_error:.3g}"]
    assert repr(feedid.Result.from_dict(result.to_dict())) == brief


def test_without_the_systematic_family_and_with_an_inverted_channel(emps):
    expected = cli_json("identify", emps, "--channel", "position=qm", "--channel", "current=vir", "--force-constant",
                        "-35.15", "--invert", "current", "--no-systematic")
    result = feedid.identify(emps, channels=EMPS_CHANNELS, force_constant=-35.15, invert=["current"],
                             systematic=False)
    assert_documents_equal(result.to_dict(), expected, TOLERANCE)
    assert result.systematic is None and result.parameters["mass_kg"].uncertainty is None
    assert "channel 'vir' (current) inverted (--invert)" in feedid.read_trace(emps, channels=EMPS_CHANNELS,
                                                                             invert=["current"]).findings


def test_estimate_fields_come_from_the_cpp_struct():
    estimate = feedid.Estimate(95.11, 0.12)
    assert feedid.Estimate._fields == ("value", "standard_error", "systematic", "uncertainty")
    assert estimate == feedid.Estimate(value=95.11, standard_error=0.12)
    assert estimate != feedid.Estimate(95.11)
    assert estimate.to_dict() == {"value": 95.11, "stderr": 0.12}
    assert pickle.loads(pickle.dumps(estimate)) == estimate
    assert repr(feedid.Estimate()) == "Estimate(" + ", ".join(f"{f}=None" for f in feedid.Estimate._fields) + ")"
    assert not feedid.Estimate().determined and estimate.determined


def test_a_friction_only_result_says_why():
    # the UMich mill log: 10 Hz, positions in whole mm; the mass is null, friction from the steady speeds
    path = shared(SHARED_DATA / "umich-cnc-mill" / "experiment_01.csv")
    units = {"position": "mm", "velocity": "mm/s", "reference_position": "mm", "velocity_command": "mm/s"}
    expected = cli_json("identify", path, "--axis", "X1", "--sample-time", "0.1",
                        *[f"--unit={role}={unit}" for role, unit in units.items()], "--force-constant", "1")
    result = feedid.identify(path, axis="X1", sample_time_s=0.1, units=units, force_constant=1)
    assert_documents_equal(result.to_dict(), expected, TOLERANCE)
    assert result.status == "partial" and result.parameters["mass_kg"].value is None
    assert result.friction_only.reason == expected["friction_only"]["reason"]
    assert result.friction_only.samples_used == expected["friction_only"]["samples_used"]


def test_gains_and_simulate_equal_the_cli(emps, folder):
    channels = ["--channel", "position=qm", "--channel", "reference_position=qg", "--channel", "current=vir"]
    expected_gains = cli_json("gains", emps, *channels, "--force-constant", "gtau", "--saturation", "10")
    gains = feedid.gains(emps, channels=EMPS_GAINS, force_constant="gtau", saturation=10)
    assert_documents_equal(gains.to_dict(), expected_gains, TOLERANCE)
    assert gains.status == "ok" and gains.failure is None
    assert gains.position_gain_per_s.value == expected_gains["gains"]["position_gain_per_s"]["value"]

    result_path = folder / "result.json"
    run_cli("identify", emps, "--channel", "position=qm", "--channel", "current=vir", "--force-constant", "gtau",
            "--offset", "--json", result_path)
    gains_path = folder / "gains.json"
    gains_path.write_text(json.dumps(gains.to_dict()))
    expected = cli_json("simulate", emps, *channels, "--force-constant", "gtau", "--result", result_path, "--gains",
                        gains_path)
    result = feedid.identify(emps, channels=EMPS_CHANNELS, force_constant="gtau", offset=True)
    for gains_argument in (gains, str(gains_path), gains.to_dict()):
        simulation = feedid.simulate(emps, result, gains_argument, channels=EMPS_GAINS, force_constant="gtau")
        assert_documents_equal(simulation.to_dict(), expected, TOLERANCE)
    assert simulation.status == "ok"
    assert simulation.metrics.position_relative_error_pct == expected["relative_error_pct"]["position"]
    frame = simulation.to_pandas()
    assert list(frame.columns)[:2] == ["reference", "position"] and len(frame) == 24841
    assert frame.index.name == "time"


def test_gains_give_the_setpoint_delay_with_its_standard_error():
    """The setpoint delay (structure.setpoint_delay_s of the document) as an Estimate, as every other gain: on a 1 kHz
    loop whose setpoint reaches the position loop 2 ms late, 2 ms."""
    drive = feedid.demo_drive()
    drive["controller"]["setpoint_delay_ms"] = 2.0
    drive["test"]["feedrates_mm_per_min"] = [2000, 6000]
    gains = feedid.gains(feedid.synth(drive, seed=3, slow_passes=False), force_constant="force_constant_N_per_A")
    assert gains.status == "ok"
    delay = gains.setpoint_delay_s
    expected = gains.to_dict()["structure"]["setpoint_delay_s"]
    assert delay.value == expected["value"] and delay.standard_error == expected["stderr"]
    assert delay.value == pytest.approx(2e-3, abs=1e-5)
    assert delay.standard_error is not None and abs(delay.value - 2e-3) <= 4.0 * delay.standard_error


def test_synth_writes_the_file_the_cli_writes(folder):
    ours = folder / "python.csv"
    theirs = folder / "cli.csv"
    drive = feedid.demo_drive()
    drive["axis"]["mass_kg"] = 120.0
    drive["test"]["feedrates_mm_per_min"] = [2000, 6000]
    (folder / "drive.json").write_text(json.dumps(drive))
    trace = feedid.synth(drive, seed=7, slow_passes=False, injection=(300.0, 1.0), out=ours)
    run_cli("synth", "--drive", folder / "drive.json", "--seed", "7", "--no-slow-passes", "--injection", "300N@1Hz",
            "--out", theirs)
    assert ours.read_bytes() == theirs.read_bytes()
    assert trace.constants["true_mass_kg"] == 120.0
    assert trace.roles == {"time": "t", "reference_position": "x_ref", "position": "x", "velocity_command": "v_cmd",
                           "current": "i", "injection": "injection"}
    rotary = feedid.synth(rotary=True, preset="sinumerik", slow_passes=False)
    assert rotary.rotary and rotary.units[rotary.roles["position"]] == "rad"


def test_plan_equals_the_cli(folder):
    expected = cli_json("plan", "--travel=-400:400", "--centers=-250,0,250", "--slow-feeds", "10:1000:3",
                        "--max-pass-time", "4")
    program = folder / "test.ngc"
    run_cli("plan", "--travel=-400:400", "--centers=-250,0,250", "--slow-feeds", "10:1000:3", "--max-pass-time", "4",
            "--dialect", "linuxcnc", "-o", program)
    plan = feedid.plan(travel_mm=(-400, 400), centers_mm=[-250, 0, 250], slow_feeds_mm_per_min="10:1000:3",
                       max_pass_time_s=4)
    assert_documents_equal(plan.to_dict(), expected, TOLERANCE)
    assert plan.part_program("linuxcnc") == program.read_text()
    reference = plan.reference()
    assert reference.roles == {"time": "t", "reference_position": "x_ref"}
    assert reference.duration_s == pytest.approx(plan.duration_s, rel=0.01)
    assert plan.blocks == expected["blocks"] and plan.passes == expected["passes"]


def test_identify_on_arrays_and_on_their_dataframe_agree():
    trace = feedid.synth(seed=4, slow_passes=False)
    frame = trace.to_pandas()
    again = feedid.Trace.from_pandas(frame)
    arrays = feedid.Trace.from_arrays(time=trace["t"], position=trace["x"], current=trace["i"],
                                      constants=trace.constants)
    results = [feedid.identify(t, force_constant="force_constant_N_per_A").to_dict() for t in (trace, again, arrays)]
    for document in results[1:]:
        assert document["parameters"] == results[0]["parameters"]
    assert isinstance(frame, pd.DataFrame)


def test_fingerprint_is_the_cli_document(sinumerik, folder):
    """feedid.fingerprint on the SINUMERIK reversal trace: the lost motion of ``feedid fingerprint``, the stiffness
    null with its reason (no force constant); and against the truth of ``feedid synth --backlash --stiffness``."""
    document = feedid.fingerprint(sinumerik)
    cli = cli_json("fingerprint", sinumerik)
    assert document["fingerprint"] == cli["fingerprint"] and document["reasons"] == cli["reasons"]
    lost = document["fingerprint"]["lost_motion_m"]["value"]
    assert 0.5e-6 <= lost <= 3e-6
    assert document["fingerprint"]["stiffness_N_per_m"]["value"] is None
    assert "--force-constant" in document["reasons"]["stiffness"]
    synthetic = str(folder / "rev-synth.csv")
    run_cli("synth", "--backlash", "8", "--stiffness", "150", "--out", synthetic)
    figures = feedid.fingerprint(synthetic, force_constant="force_constant_N_per_A")["fingerprint"]
    assert abs(figures["backlash_m"]["value"] - 8e-6) <= 0.1 * 8e-6
    assert abs(figures["stiffness_N_per_m"]["value"] - 150e6) <= 0.1 * 150e6
