"""pandas for feedid's objects: Trace.from_pandas / to_pandas, Result.to_pandas, Simulation.to_pandas,
History.to_pandas. pandas is imported when one of them is called, not with feedid."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Mapping, Optional

if TYPE_CHECKING:  # pragma: no cover
    import pandas

from . import _feedid as _native


def trace_from_pandas(frame: "pandas.DataFrame", channels: Optional[Mapping[str, str]] = None,
                      units: Optional[Mapping[str, str]] = None, *, constants: Optional[Mapping[str, float]] = None,
                      path: str = "", axis: Optional[str] = None, sample_time_s: Optional[float] = None,
                      lead_mm: Optional[float] = None, gear_ratio: Optional[float] = None,
                      rated: Optional[str] = None) -> "_native.Trace":
    """A trace from a DataFrame: its columns of numbers become channels, as the columns of a CSV file do.

    Column names may carry units (``"x [mm]"``, ``"v (mm/min)"``, ``"i/A"``); roles not given in ``channels`` are
    guessed from the names (``t``, ``x``, ``i``, ``X1_ActualPosition``, ...), each guess in ``trace.findings``. A named
    index (``df.set_index("t")``) is a column too. Columns that do not hold numbers (text, dates, categories) are left
    out with a finding, unless ``channels`` names them (then :class:`feedid.InputError`). A DataFrame made by
    :meth:`Trace.to_pandas` carries its roles, units and constants in ``frame.attrs``, which are used where
    ``channels``, ``units`` and ``constants`` say nothing. Values are copied as :meth:`Trace.from_arrays` copies them.

    Args:
        frame: the DataFrame.
        channels: role -> column name (without its unit), e.g. ``{"position": "x"}``.
        units: role -> unit, for columns whose names carry none.
        constants, path, axis, sample_time_s, lead_mm, gear_ratio, rated: as :func:`feedid.read_trace` and
            :meth:`Trace.from_arrays`.

    Example::

        >>> import pandas as pd, feedid
        >>> df = pd.DataFrame({"t": [0.0, 0.001, 0.002], "x [mm]": [0.0, 0.01, 0.02], "i [A]": [0.1, 0.2, 0.1]})
        >>> trace = feedid.Trace.from_pandas(df)
        >>> trace.roles, trace.units["x"]
        ({'time': 't', 'position': 'x', 'current': 'i'}, 'm')
    """
    import pandas as pd

    if not isinstance(frame, pd.DataFrame):
        raise _errors().InputError(f"from_pandas: expected a pandas DataFrame, not {type(frame).__name__}")
    if frame.index.name is not None or any(name is not None for name in frame.index.names[1:]):
        frame = frame.reset_index()
    named = {str(name) for name in (channels or {}).values()}
    attributes = frame.attrs if isinstance(frame.attrs, dict) else {}
    roles = dict(attributes.get("feedid_roles", {}))
    roles.update(channels or {})
    stated_units = {role: unit for role, unit in dict(attributes.get("feedid_units", {})).items()
                    if role in roles and roles[role] is not None}
    stated_units.update(units or {})
    if constants is None:
        constants = attributes.get("feedid_constants")
    columns, left_out = [], []
    for name in frame.columns:
        column = frame[name]
        label = str(name)
        numeric = pd.api.types.is_numeric_dtype(column.dtype) and not pd.api.types.is_bool_dtype(column.dtype)
        given = label in named or any(label.startswith(n) and label[len(n):len(n) + 2] in (" [", " (") or
                                      label.startswith(n + "/") for n in named)
        if numeric or given:
            columns.append((label, column.to_numpy()))
        else:
            left_out.append(label)
    findings = [f"columns that do not hold numbers left out: {', '.join(left_out)}"] if left_out else []
    options = dict(channels=roles, units=stated_units, constants=constants, path=path, axis=axis,
                   sample_time_s=sample_time_s, lead_mm=lead_mm, gear_ratio=gear_ratio, rated=rated,
                   source_format="pandas", findings=findings)
    return _native.trace_from_columns(columns, options)


def trace_to_pandas(trace: "_native.Trace") -> "pandas.DataFrame":
    """The trace as a DataFrame: one column per channel (SI values, copied), named as the channels are.

    ``frame.attrs`` holds the roles (``feedid_roles``: role -> column), SI units (``feedid_units``: role -> unit),
    the source path and the constants, so that ``Trace.from_pandas(trace.to_pandas())`` gives the trace back.

    Example::

        >>> df = feedid.synth(seed=1, slow_passes=False).to_pandas()
        >>> list(df.columns), df.attrs["feedid_roles"]["position"]
        (['t', 'x_ref', 'x', 'v_cmd', 'i'], 'x')
    """
    import pandas as pd

    frame = pd.DataFrame({name: trace[name] for name in trace.channel_names}, copy=True)
    roles = trace.roles
    frame.attrs["feedid_roles"] = roles
    frame.attrs["feedid_units"] = {role: trace.units[name] for role, name in roles.items()}
    frame.attrs["feedid_path"] = trace.path
    frame.attrs["feedid_constants"] = trace.constants
    return frame


def result_to_pandas(result: "_native.Result") -> "pandas.DataFrame":
    """The parameters as a DataFrame: one row per parameter key (``mass_kg``, ...), columns ``symbol``, ``unit`` and
    the fields of :class:`feedid.Estimate` (``value``, ``standard_error``; NaN where None).

    Example::

        >>> result = feedid.identify(feedid.synth(seed=1), force_constant="force_constant_N_per_A")
        >>> result.to_pandas().loc["mass_kg", ["symbol", "unit"]].tolist()
        ['M', 'kg']
    """
    import pandas as pd

    fields = _native.Estimate._fields
    rows = []
    for key, estimate in result.parameters.items():
        row = {"symbol": result.symbols[key], "unit": result.units[key]}
        for field in fields:
            value = getattr(estimate, field)
            row[field] = float("nan") if value is None else value
        rows.append(row)
    frame = pd.DataFrame(rows, index=pd.Index(list(result.parameters), name="parameter"),
                         columns=["symbol", "unit", *fields])
    return frame


def simulation_to_pandas(simulation: "_native.Simulation") -> "pandas.DataFrame":
    """The simulated signals as a DataFrame indexed by time [s]: reference, position, measured_position, velocity,
    acceleration, velocity_command, force_command, force, tracking_error (SI; rad, N*m on a rotary axis)."""
    import pandas as pd

    signals = dict(simulation.signals)
    time = signals.pop("time")
    return pd.DataFrame(signals, index=pd.Index(time, name="time"), copy=True)


def history_to_pandas(history: "_native.History", *, machine: str = "", axis: str = "",
                      location: str = "") -> "pandas.DataFrame":
    """The runs as a DataFrame: one row per run (id, machine, axis, location, recorded_at, status, model, ...) and
    two columns per parameter, ``KEY`` (the value) and ``KEY_stderr``; the filters as :meth:`History.runs`."""
    import pandas as pd

    rows = []
    for run in history.runs(machine=machine, axis=axis, location=location):
        row = {key: value for key, value in run.items() if not isinstance(value, (dict, list))}
        row.update(estimate_columns(run.get("parameters", {})))
        rows.append(row)
    return pd.DataFrame(rows)


def estimate_columns(parameters: Mapping[str, Any]) -> dict:
    """Flat columns of a result document's parameters: ``KEY`` for the value and ``KEY_FIELD`` for every other field
    of the estimate's entry (``KEY_stderr``, and any field the C++ Estimate adds), None as NaN."""
    out = {}
    for key, entry in parameters.items():
        for field, value in (entry.items() if isinstance(entry, Mapping) else (("value", entry),)):
            out[key if field == "value" else f"{key}_{field}"] = float("nan") if value is None else value
    return out


def _errors():
    from . import _errors

    return _errors
