"""Traces from files, arrays and DataFrames: channels are read-only views of the trace's own columns (no copy on the
way out), and arrays coming in are copied once, converted with a note, or refused naming the channel, as the
docstring of Trace.from_arrays says."""

import gc
import weakref

import numpy as np
import pandas as pd
import pytest

import feedid
from conftest import EMPS_CHANNELS, cli_json


def test_read_trace_matches_feedid_info(emps):
    trace = feedid.read_trace(emps, channels=EMPS_CHANNELS)
    info = cli_json("info", emps, "--channel", "position=qm", "--channel", "current=vir")
    assert trace.samples == len(trace) == info["samples"] == 24841
    assert trace.sample_time_s == pytest.approx(info["sample_time_s"], rel=1e-12)
    assert trace.format == info["format"] == "mat"
    assert trace.constants["gtau"] == info["constants"]["gtau"]
    for channel in info["channels"]:
        values = trace[channel["name"]]
        assert trace.units[channel["name"]] == channel["unit"]
        assert values.min() == pytest.approx(channel["min"], rel=1e-12)
        assert values.max() == pytest.approx(channel["max"], rel=1e-12)
    assert trace.roles == {"time": "t", "position": "qm", "current": "vir", "reference_position": "qg"}
    assert trace.findings == trace.findings and all(isinstance(f, str) for f in trace.findings)


def test_channels_are_read_only_views_that_keep_the_trace_alive(emps):
    trace = feedid.read_trace(emps, channels=EMPS_CHANNELS)
    position = trace["qm"]
    assert position.dtype == np.float64 and position.flags.c_contiguous
    assert not position.flags.writeable and not position.flags.owndata
    assert np.shares_memory(position, trace.role("position"))  # both views of the same column: no copy
    with pytest.raises(ValueError):
        position[0] = 1.0
    expected = position.copy()
    alive = weakref.ref(trace)
    del trace
    gc.collect()
    assert alive() is not None  # the view holds the trace
    np.testing.assert_array_equal(position, expected)
    del position
    gc.collect()
    assert alive() is None


def test_from_arrays_copies_float64_as_it_is():
    t = np.arange(2000) * 1e-3
    x = 0.01 * np.sin(2 * np.pi * t)
    i = np.cos(2 * np.pi * t)
    trace = feedid.Trace.from_arrays(time=t, position=x, current=i)
    np.testing.assert_array_equal(trace["position"], x)
    assert not np.shares_memory(trace["position"], x)  # the trace owns its columns
    assert trace.roles == {"time": "time", "position": "position", "current": "current"}
    assert not any("converted" in f or "strided" in f for f in trace.findings)
    # a role without a unit is taken as SI, and that is said
    assert any("channel 'position' (position) carries no unit: taken as m" in f for f in trace.findings)


def test_from_arrays_converts_float32_integers_and_strided_arrays_with_a_note():
    t = np.arange(1000) * 1e-3
    x32 = (np.sin(2 * np.pi * t) * 10).astype(np.float32)       # mm
    counts = np.arange(1000, dtype=np.int32)                     # um
    wide = np.column_stack([np.cos(2 * np.pi * t), np.zeros(1000)])
    current = wide[:, 0]                                         # a column of a 2-D array: strided
    assert not current.flags.c_contiguous
    trace = feedid.Trace.from_arrays(time=t, position=x32, reference_position=counts, current=current,
                                     units={"position": "mm", "reference_position": "um"})
    assert "channel 'position': float32 values converted to float64" in trace.findings
    assert "channel 'reference_position': int32 values converted to float64" in trace.findings
    assert "channel 'current': a strided array, gathered into the trace's own copy" in trace.findings
    np.testing.assert_array_equal(trace["position"], x32.astype(np.float64) * 1e-3)  # exact widening, then mm -> m
    np.testing.assert_array_equal(trace["reference_position"], counts * 1e-6)
    np.testing.assert_array_equal(trace["current"], current)
    assert trace["current"].flags.c_contiguous


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_from_arrays_refuses_a_value_that_is_not_finite_naming_the_channel(bad):
    t = np.arange(100) * 1e-3
    x = np.zeros(100)
    x[41] = bad
    with pytest.raises(feedid.InputError) as error:
        feedid.Trace.from_arrays(time=t, position=x, current=np.ones(100))
    assert isinstance(error.value, ValueError)
    assert str(error.value) == "trace: channel 'position' (position) has a missing or non-finite value at sample 42"


def test_from_arrays_refuses_what_is_not_a_column_of_numbers():
    t = np.arange(10) * 1e-3
    cases = {
        "a 1-D array is needed, not one of shape (10, 2)": np.zeros((10, 2)),
        "values of type complex128 are not real numbers": np.zeros(10, dtype=complex),
        "values of type object are not real numbers": np.array([0.0] * 9 + [None], dtype=object),
        "values of type bool are not real numbers": np.zeros(10, dtype=bool),
        "values of type <U1 are not real numbers": np.array(list("abcdefghij")),
    }
    for message, values in cases.items():
        with pytest.raises(feedid.InputError, match="^channel 'position': " + message.replace("(", r"\(")
                           .replace(")", r"\)")):
            feedid.Trace.from_arrays(time=t, position=values, current=np.ones(10))
    with pytest.raises(feedid.InputError, match="channel 'current' has 9 samples, the time channel 10"):
        feedid.Trace.from_arrays(time=t, position=np.zeros(10), current=np.ones(9))
    with pytest.raises(feedid.InputError, match="unit 'furlong'"):
        feedid.Trace.from_arrays(time=t, position=np.zeros(10), units={"position": "furlong"})
    with pytest.raises(feedid.InputError, match="no time column"):
        feedid.Trace.from_arrays(position=np.zeros(10))
    trace = feedid.Trace.from_arrays(position=np.zeros(10), current=np.ones(10), sample_time_s=0.002)
    assert trace.sample_time_s == pytest.approx(0.002)


def test_from_pandas_reads_columns_as_a_csv_reader_does():
    frame = pd.DataFrame({"t": np.arange(500) * 1e-3, "x [mm]": np.linspace(0, 5, 500),
                          "i/A": np.ones(500), "step": ["a"] * 500, "temperature": np.full(500, 21.5)})
    trace = feedid.Trace.from_pandas(frame)
    assert trace.roles == {"time": "t", "position": "x", "current": "i"}
    assert trace.units["x"] == "m" and trace["x"][-1] == pytest.approx(0.005)
    assert "columns that do not hold numbers left out: step" in trace.findings
    assert "temperature" in trace and trace["temperature"][0] == 21.5
    # a named index is a column too
    indexed = feedid.Trace.from_pandas(frame.set_index("t"), channels={"position": "x"})
    assert indexed.roles["time"] == "t"
    # a text column given a role is an error naming it
    with pytest.raises(feedid.InputError, match="channel 'step': values of type object are not real numbers"):
        feedid.Trace.from_pandas(frame, channels={"current": "step"})
    with pytest.raises(feedid.InputError, match="expected a pandas DataFrame"):
        feedid.Trace.from_pandas({"t": [0.0]})


def test_to_pandas_and_back():
    trace = feedid.synth(seed=3, slow_passes=False)
    frame = trace.to_pandas()
    assert list(frame.columns) == trace.channel_names
    np.testing.assert_array_equal(frame["x"].to_numpy(), trace["x"])
    assert not np.shares_memory(frame["x"].to_numpy(), trace["x"])  # a DataFrame of its own
    again = feedid.Trace.from_pandas(frame)
    assert again.roles == trace.roles and again.constants == trace.constants
    for name in trace.channel_names:
        np.testing.assert_array_equal(again[name], trace[name])


def test_trace_lookups():
    trace = feedid.synth(seed=3, slow_passes=False)
    with pytest.raises(KeyError, match="no channel 'nope'"):
        trace["nope"]
    with pytest.raises(feedid.InputError, match="unknown role 'speed'"):
        trace.role("speed")
    with pytest.raises(feedid.InputError, match="force"):
        trace.role("force")
    assert "x" in trace and "nope" not in trace
    assert "synthetic" in repr(trace)
