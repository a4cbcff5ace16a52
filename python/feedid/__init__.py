"""feedid: rapid parameter estimation and health monitoring of CNC feed drives, for numpy and pandas.

From the traces an NC records (axis position and motor current) feedid estimates the drive's mass and its viscous,
Coulomb and breakaway friction and Stribeck velocity, each with a standard error; identifies the position and
velocity loop gains; simulates the identified axis in closed loop; designs the test; and keeps results over time.
This package is feedid's C++ library (the one the ``feedid`` command line uses) with numpy arrays in and out:

- :func:`read_trace`, :meth:`Trace.from_arrays`, :meth:`Trace.from_pandas` make a :class:`Trace` (SI units; its
  channels are read-only numpy views, ``trace.to_pandas()`` a DataFrame);
- :func:`identify` gives a :class:`Result` (``result.parameters``: key -> :class:`Estimate`; ``result.to_dict()`` is
  the document ``feedid identify --json`` writes; ``result.to_pandas()``);
- :func:`gains`, :func:`simulate`, :func:`synth`, :func:`plan` as the subcommands of the same names;
- :class:`Rls`, the recursive least squares estimator, sample by sample or a whole array in C++ without the GIL;
- :class:`History`, the parameter history store (SQLite or PostgreSQL) of ``feedid history``;
- :mod:`feedid.fleet`, identification of many files on a Dask cluster.

Units are SI (m, s, kg, N, A; rad, kg*m^2, N*m on rotary axes) unless an argument's name says otherwise
(``lead_mm``, ``travel_mm``). Bad input raises :class:`InputError` (a ValueError), a failed analysis
:class:`IdentificationError`, each with the message the command line prints.

Example::

    >>> import feedid
    >>> trace = feedid.synth(seed=1)           # the demo drive: M 69.1 kg, F_C 742.8 N, ...
    >>> result = feedid.identify(trace, force_constant="force_constant_N_per_A")
    >>> print(f"M = {result.parameters['mass_kg'].value:.1f} kg")   # the truth: 69.1 kg
    M = 69.4 kg
"""

from __future__ import annotations

import os
from typing import Any, Mapping, Optional, Sequence, Tuple, Union

from ._errors import IdentificationError, InputError
from . import _feedid as _native
from ._feedid import (  # noqa: F401  (re-exported)
    Estimate,
    SystematicReport,
    SystematicVariant,
    FrictionCurvePoints,
    FrictionCurveReport,
    FrictionOnlyReport,
    Gains,
    History,
    LogLinearStribeck,
    NonlinearFitReport,
    Plan,
    PreprocessReport,
    Result,
    Rls,
    RlsReport,
    SelectionReport,
    Simulation,
    Step1Report,
    StribeckReport,
    Trace,
    TraceSummary,
    ValidationMetrics,
    __version__,
)
from . import _pandas

# The native classes are feedid's: named so in repr, help and pickles.
for _class in (Estimate, FrictionCurvePoints, FrictionCurveReport, FrictionOnlyReport, Gains, History,
               LogLinearStribeck, NonlinearFitReport, Plan, PreprocessReport, Result, Rls, RlsReport, SelectionReport,
               Simulation, Step1Report, StribeckReport, SystematicReport, SystematicVariant, Trace, TraceSummary,
               ValidationMetrics):
    _class.__module__ = __name__
del _class

__all__ = [
    "__version__", "InputError", "IdentificationError", "ROLES", "Trace", "read_trace", "Estimate", "Result",
    "identify", "Gains", "gains", "Simulation", "simulate", "synth", "demo_drive", "Plan", "plan", "Rls", "History",
    "fingerprint",
]

#: The roles a channel can have (``channels={"position": "qm"}``; ``Trace.from_arrays(position=...)``).
ROLES = ("time", "position", "reference_position", "velocity", "velocity_command", "current", "force",
         "external_force", "injection", "motor_position")

# The keyword defaults are the library's: each read from a default-constructed Options struct (identify's
# IdentifyOptions, plan's TestPlanOptions and PredictionOptions, ...) in the unit the keyword's name states.
_DEFAULTS = _native.defaults()
_IDENTIFY, _GAINS, _SIMULATE = _DEFAULTS["identify"], _DEFAULTS["gains"], _DEFAULTS["simulate"]
_SYNTH, _PLAN = _DEFAULTS["synth"], _DEFAULTS["plan"]

PathLike = Union[str, "os.PathLike[str]"]
TraceArgument = Union[Trace, str, "os.PathLike[str]"]


def _options(arguments: Mapping[str, Any], *leave_out: str) -> dict:
    return {key: value for key, value in arguments.items() if key not in leave_out}


def read_trace(path: PathLike, channels: Optional[Mapping[str, str]] = None,
               units: Optional[Mapping[str, str]] = None, *, axis: Optional[str] = None,
               format: Optional[str] = None, sample_time_s: Optional[float] = None, skip_rows: Optional[int] = None,
               lead_mm: Optional[float] = None, gear_ratio: Optional[float] = None, rated: Optional[str] = None,
               join: Optional[str] = None, join_max_shift_s: Optional[float] = None,
               tare: Optional[Sequence[str]] = None, invert: Optional[Sequence[str]] = None) -> Trace:
    """Reads a trace file and converts it to SI units, as ``feedid info FILE`` does.

    Formats are detected from the content: CSV, MATLAB .mat, SINUMERIK trace XML, TwinCAT Scope CSV, halscope text,
    MR Configurator2 and NI DAQ CSV. Roles not given in ``channels`` are guessed from the channel names, and each guess
    is in ``trace.findings``.

    Args:
        path: the file.
        channels: role -> channel name, e.g. ``{"position": "qm", "current": "vir"}`` (``--channel ROLE=NAME``).
        units: role -> unit where the file gives none, e.g. ``{"position": "mm"}`` (``--unit ROLE=UNIT``).
        axis: the axis of a multi-axis file (``"X1"``, NC axis index ``"2"``).
        format: read as this format instead of detecting it (``"csv"``, ``"mat"``, ``"sinumerik-trace"``, ...).
        sample_time_s: time between samples [s] for a file without a time column.
        skip_rows: CSV lines to skip before the header.
        lead_mm: ball-screw lead [mm per revolution]: a motor speed in rpm becomes a table velocity.
        gear_ratio: motor revolutions per screw revolution (with ``lead_mm``; default 1).
        rated: what 100 % is for channels in percent, with its unit (``"18A"``, ``"2.4Nm"``).
        join: a second recording of the same move, ``"FILE[@SHIFT]"`` (``@4ms``; ``@auto``), resampled onto this
            one's time base.
        join_max_shift_s: the largest shift ``@auto`` searches [s] (default 0.1).
        tare: roles to zero from the samples at rest before the move (e.g. ``["force"]``).
        invert: roles whose sign is flipped (e.g. ``["current"]``: a drive that counts positive current in the
            direction the NC counts negative).

    Returns:
        The Trace (SI units: m, s, m/s, A, N; rad, rad/s, N*m on a rotary axis).

    Raises:
        InputError: a file that cannot be read, an unknown unit or role, a missing channel.

    Example::

        >>> import feedid
        >>> trace = feedid.read_trace(EMPS, channels={"position": "qm", "current": "vir"})
        >>> trace.samples, round(trace.sample_time_s, 9), trace.roles["position"]
        (24841, 0.001, 'qm')
        >>> trace.role("position")[:3]            # metres, a read-only view of the trace's column
        array([7.450e-06, 1.430e-05, 2.185e-05])
    """
    return _native.read_trace(path, _options(locals(), "path"))


def _from_arrays(time: Any = None, position: Any = None, current: Any = None, *, reference_position: Any = None,
                 velocity: Any = None, velocity_command: Any = None, force: Any = None, external_force: Any = None,
                 injection: Any = None, units: Optional[Mapping[str, str]] = None,
                 constants: Optional[Mapping[str, float]] = None, path: str = "",
                 sample_time_s: Optional[float] = None, lead_mm: Optional[float] = None,
                 gear_ratio: Optional[float] = None, rated: Optional[str] = None) -> Trace:
    """A trace from arrays, one per role (1-D, equal lengths), in the units ``units`` names (SI where none).

    Each array is copied once into the trace (which owns its columns; its channels are then read-only views of them).
    A float64 array in C order is copied as it is. A float32 or integer array is widened to float64, and a strided
    (non-contiguous) array gathered, in that copy, each with a note in ``trace.findings``. A NaN or infinite value in
    any array raises :class:`InputError` (a ValueError) naming the channel and the sample; so does an array that is
    not 1-D or not of real numbers, and arrays of different lengths.

    Args:
        time: time stamps [s] (or give ``sample_time_s`` instead).
        position, current, reference_position, velocity, velocity_command, force, external_force, injection: the
            channels of those roles (channel names are the role names).
        units: role -> unit of the given values, e.g. ``{"position": "mm", "velocity": "mm/min"}``.
        constants: scalars usable as ``force_constant="name"``.
        path: a name for the trace in messages and in the result document (no file is read).
        sample_time_s: time between samples [s] when ``time`` is not given.
        lead_mm, gear_ratio, rated: what converts rpm and % units (see :func:`read_trace`).

    Example::

        >>> import numpy as np, feedid
        >>> t = np.arange(0, 2, 0.001)
        >>> x = np.float32(10.0) * np.sin(np.float32(np.pi) * t.astype(np.float32))      # mm, float32
        >>> trace = feedid.Trace.from_arrays(time=t, position=x, current=np.cos(np.pi * t), units={"position": "mm"})
        >>> trace.findings[0]
        "channel 'position': float32 values converted to float64"
        >>> float(trace.role("position").max()) <= 0.010                                 # metres
        True
    """
    columns = [(role, values) for role, values in (
        ("time", time), ("position", position), ("reference_position", reference_position), ("velocity", velocity),
        ("velocity_command", velocity_command), ("current", current), ("force", force),
        ("external_force", external_force), ("injection", injection)) if values is not None]
    options = dict(channels={role: role for role, _ in columns}, units=units, constants=constants, path=path,
                   sample_time_s=sample_time_s, lead_mm=lead_mm, gear_ratio=gear_ratio, rated=rated,
                   source_format="arrays")
    return _native.trace_from_columns(columns, options)


Trace.from_arrays = staticmethod(_from_arrays)  # type: ignore[attr-defined]
Trace.from_pandas = staticmethod(_pandas.trace_from_pandas)  # type: ignore[attr-defined]
Trace.to_pandas = _pandas.trace_to_pandas  # type: ignore[attr-defined]
Result.to_pandas = _pandas.result_to_pandas  # type: ignore[attr-defined]
Simulation.to_pandas = _pandas.simulation_to_pandas  # type: ignore[attr-defined]
History.to_pandas = _pandas.history_to_pandas  # type: ignore[attr-defined]


def identify(trace: TraceArgument, *, model: str = _IDENTIFY["model"], offset: Optional[bool] = None,
             delay: Union[str, float, None] = None, stribeck: bool = _IDENTIFY["stribeck"],
             force_constant: Union[float, str, None] = None,
             kt_Nm_per_A: Optional[float] = None, lead_mm: Optional[float] = None,
             gear_ratio: float = _IDENTIFY["gear_ratio"], differentiation: str = _IDENTIFY["differentiation"],
             velocity_source: str = _IDENTIFY["velocity_source"], filter_order: int = _IDENTIFY["filter_order"],
             cutoff_hz: Optional[float] = None, savitzky_golay_window: Optional[int] = None,
             savitzky_golay_order: int = _IDENTIFY["savitzky_golay_order"], decimation: Optional[int] = None,
             edge_samples: Optional[int] = None, from_s: Optional[float] = None, to_s: Optional[float] = None,
             split_velocity: Optional[float] = None, moving_threshold: Optional[float] = None,
             rls: str = _IDENTIFY["rls"], forgetting_factor: float = _IDENTIFY["forgetting_factor"],
             initial_covariance: float = _IDENTIFY["initial_covariance"], channels: Optional[Mapping[str, str]] = None,
             units: Optional[Mapping[str, str]] = None, axis: Optional[str] = None, format: Optional[str] = None,
             sample_time_s: Optional[float] = None, skip_rows: Optional[int] = None, rated: Optional[str] = None,
             join: Optional[str] = None, join_max_shift_s: Optional[float] = None, tare: Optional[Sequence[str]] = None,
             invert: Optional[Sequence[str]] = None, systematic: bool = _IDENTIFY["systematic"],
             threads: int = _IDENTIFY["threads"]) -> Result:
    """Mass and friction of the axis, each with a standard error: ``feedid identify`` (README, "Identification").

    The options are the command line's, with the same defaults; the reading options (``channels`` to ``invert``, see
    :func:`read_trace`) apply when ``trace`` is a path. The drive force is the trace's force channel, or its current
    times a constant: ``force_constant`` [N per signal unit] (a number, or the name of a scalar in the file such as
    ``"gtau"``), or ``kt_Nm_per_A`` [N*m/A] with ``lead_mm`` [mm] and ``gear_ratio``.

    Args:
        trace: a Trace, or the path of a trace file.
        model: ``"auto"`` (chosen from the data, with the offset and the drive signal's delay: the
            result's ``model_selection``), ``"symmetric"`` (the paper's eq. 11) or ``"asymmetric"`` (friction per
            direction); a model given forces it.
        offset: None (the data decide), True (force a constant force offset F_0 [N] into the model) or False
            (force the model without one).
        delay: the drive signal's delay behind the position: None (estimated and applied where significant with an
            automatic model; with a forced one only said), ``"auto"`` (estimated and applied where significant),
            ``"none"``, or a known delay [s].
        stribeck: run step 2 (breakaway friction F_B [N], Stribeck velocity v_s [m/s]).
        differentiation: ``"butterworth"`` (zero-phase low-pass, then central differences), ``"central"``,
            ``"savitzky-golay"``.
        velocity_source: ``"auto"``, ``"position"`` (differentiated) or ``"velocity"`` (the logged velocity).
        filter_order, cutoff_hz: the Butterworth's order and cut-off [Hz] (default min(100 Hz, fs/10)).
        savitzky_golay_window, savitzky_golay_order: window [samples, odd; default about 20 ms] and order.
        decimation: keep every N-th sample after an anti-alias filter (None or 1: none).
        edge_samples: samples dropped at each end after filtering (default 2.5 filter periods).
        from_s, to_s: the analysis window [s].
        split_velocity: step 1 uses |v| above, step 2 the quasi-static samples below [m/s or rad/s].
        moving_threshold: |v| above which a sample is moving [m/s or rad/s] (default 5x the noise floor).
        rls, forgetting_factor, initial_covariance: the RLS variant (``"directional"`` or ``"paper"``), lambda, P(0).
        systematic: rerun the stages over a family of preprocessing choices for each parameter's systematic
            uncertainty (``Estimate.systematic``, ``Estimate.uncertainty``, same unit); False: standard errors only,
            about 5x faster (``--no-systematic``).
        threads: threads the family runs on (``--threads``); 0: one per core. In a batch that already runs one
            identify per core, 1.

    Returns:
        The Result; ``result.status`` is ``"ok"``, or ``"partial"`` when some parameters are None (a diagnostic says
        why for each).

    Raises:
        InputError: bad options, a trace without what is needed (position or velocity, a drive signal and its
            constant).
        IdentificationError: the data cannot identify the model (exit 1 of the command line); ``error.result`` is
            the failed Result.

    Example (EMPS, as in the README)::

        >>> import feedid
        >>> result = feedid.identify(EMPS, channels={"position": "qm", "current": "vir"}, force_constant="gtau",
        ...                          offset=True)
        >>> m = result.parameters["mass_kg"]        # standard error and combined uncertainty, both in kg
        >>> print(f"M = {m.value:.2f} +- {m.standard_error:.3f} kg (uncertainty {m.uncertainty:.3f} kg)")
        M = 95.01 +- 0.951 kg (uncertainty 1.073 kg)
    """
    options = _options(locals(), "trace")
    result = _native.identify(trace, options)
    if result.status == "failed":
        raise IdentificationError(result.failure, result.diagnostics, result)
    return result


def gains(trace: TraceArgument, *, force_constant: Union[float, str, None] = None, kt_Nm_per_A: Optional[float] = None,
          lead_mm: Optional[float] = None, gear_ratio: float = _GAINS["gear_ratio"],
          velocity_loop: str = _GAINS["velocity_loop"], feedforward: bool = _GAINS["feedforward"],
          velocity_difference: Optional[int] = None, current_lag_ms: Optional[float] = None,
          saturation: Optional[float] = None, forgetting: float = _GAINS["forgetting"],
          channels: Optional[Mapping[str, str]] = None, units: Optional[Mapping[str, str]] = None,
          axis: Optional[str] = None, format: Optional[str] = None, sample_time_s: Optional[float] = None,
          skip_rows: Optional[int] = None, rated: Optional[str] = None, join: Optional[str] = None,
          join_max_shift_s: Optional[float] = None, tare: Optional[Sequence[str]] = None,
          invert: Optional[Sequence[str]] = None) -> Gains:
    """The controller's gains: position loop K_v [1/s], velocity loop K_p [N*s/m] and K_i [N/m]; ``feedid gains``.

    Needs the reference position, the position and the drive signal (a logged velocity command lets each loop be
    identified on its own). A signal injected at the controller's output (role ``injection``) is taken out first.

    Args:
        trace: a Trace, or the path of a trace file (then the reading options apply, see :func:`read_trace`).
        force_constant, kt_Nm_per_A, lead_mm, gear_ratio: the drive constants (see :func:`identify`).
        velocity_loop: ``"auto"`` (PI, or P when K_i is not significant), ``"p"`` or ``"pi"``.
        feedforward: also identify a velocity feed-forward.
        velocity_difference: the controller measures velocity as (x_k - x_k-N)/(N*T); default: from the data.
        current_lag_ms: the current loop's time constant [ms]; default: estimated.
        saturation: the drive signal's limit in its own units (e.g. 10 for 10 V).
        forgetting: RLS forgetting factor (1: none, the gains are constant).

    Returns:
        The Gains (rotary axes: K_p in N*m*s/rad, K_i in N*m/rad); ``gains.to_dict()`` is ``feedid gains --json``.

    Raises:
        InputError: bad options or input.
        IdentificationError: a fit too poor to trust (more than 3 % of the drive signal unexplained), or data that
            cannot determine the gains.

    Example (EMPS)::

        >>> g = feedid.gains(EMPS, channels={"position": "qm", "reference_position": "qg", "current": "vir"},
        ...                  force_constant="gtau", saturation=10)
        >>> round(g.position_gain_per_s.value, 1)
        160.2
    """
    return _raise_failure(_native.gains(trace, _options(locals(), "trace")))


def simulate(trace: TraceArgument, result: Union[Result, Mapping[str, Any], PathLike],
             gains: Union[Gains, Mapping[str, Any], PathLike, None] = None, *,
             force_constant: Union[float, str, None] = None, kt_Nm_per_A: Optional[float] = None,
             lead_mm: Optional[float] = None, gear_ratio: float = _SIMULATE["gear_ratio"],
             velocity_loop: str = _SIMULATE["velocity_loop"], feedforward: bool = _SIMULATE["feedforward"],
             velocity_difference: Optional[int] = None, current_lag_ms: Optional[float] = None,
             saturation: Optional[float] = None, forgetting: float = _SIMULATE["forgetting"],
             substeps: int = _SIMULATE["substeps"], channels: Optional[Mapping[str, str]] = None,
             units: Optional[Mapping[str, str]] = None, axis: Optional[str] = None, format: Optional[str] = None,
             sample_time_s: Optional[float] = None, skip_rows: Optional[int] = None, rated: Optional[str] = None,
             join: Optional[str] = None, join_max_shift_s: Optional[float] = None, tare: Optional[Sequence[str]] = None,
             invert: Optional[Sequence[str]] = None) -> Simulation:
    """The identified axis in closed loop on the trace's reference, compared with the machine: ``feedid simulate``.

    Args:
        trace: a Trace, or the path of a trace file (then the reading options apply, see :func:`read_trace`).
        result: the identification (a Result, its dict, or the path of ``feedid identify --json``'s document).
        gains: the controller (Gains, its dict, or a path); None: identified from this trace (options as
            :func:`gains`).
        substeps: integration steps per sample.

    Returns:
        The Simulation: ``metrics`` (relative errors [%] of position, velocity, acceleration and force, tracking and
        modelling errors [m or rad]), ``signals`` (numpy arrays), ``to_pandas()``, ``to_dict()``.

    Raises:
        InputError: bad options or input, with the command line's message: a result (or gains) of a rotary axis
            for a linear trace, or a result whose forces do not fit the trace's drive force (other units, the drive
            signal's sign flipped, another axis).
        IdentificationError: the simulation diverged or does not follow the machine, or the gains identified here
            cannot be trusted.

    Example (EMPS)::

        >>> channels = {"position": "qm", "reference_position": "qg", "current": "vir"}
        >>> result = feedid.identify(EMPS, channels=channels, force_constant="gtau", offset=True)
        >>> sim = feedid.simulate(EMPS, result, channels=channels, force_constant="gtau", saturation=10)
        >>> sim.metrics.position_relative_error_pct < 0.01
        True
    """
    options = _options(locals(), "trace", "result", "gains")
    return _raise_failure(_native.simulate(trace, result, gains, options))


def fingerprint(trace: TraceArgument, *, force_constant: Union[float, str, None] = None,
                kt_Nm_per_A: Optional[float] = None, lead_mm: Optional[float] = None,
                gear_ratio: float = _GAINS["gear_ratio"], settle_s: Optional[float] = None,
                channels: Optional[Mapping[str, str]] = None, units: Optional[Mapping[str, str]] = None,
                axis: Optional[str] = None, format: Optional[str] = None, sample_time_s: Optional[float] = None,
                skip_rows: Optional[int] = None, rated: Optional[str] = None, join: Optional[str] = None,
                join_max_shift_s: Optional[float] = None, tare: Optional[Sequence[str]] = None,
                invert: Optional[Sequence[str]] = None) -> dict:
    """The axis's mechanical fingerprint: ``feedid fingerprint --json`` as a dict.

    From the scale (role ``position``) and the motor encoder (role ``motor_position``), per direction with standard
    errors: lost motion at reversal, backlash, stiffness between motor and load, reversal error and breakaway force
    (keys ``lost_motion_m``, ``backlash_m``, ``stiffness_N_per_m``, ``reversal_error_m``, ``breakaway_N``, each also
    ``_forward``/``_reverse``; rotary: ``_rad``, ``_Nm_per_rad``, ``_Nm``). A figure the trace cannot tell is
    ``None`` and ``reasons`` says why.

    Args:
        trace: a Trace, or the path of a trace file (then the reading options apply, see :func:`read_trace`).
        force_constant, kt_Nm_per_A, lead_mm, gear_ratio: the drive constants (see :func:`identify`).
        settle_s: how long the reference must hold its speed before a sample counts [s]; default 0.05.

    Example::

        >>> doc = feedid.fingerprint("rev-synth.csv", force_constant="force_constant_N_per_A")  # doctest: +SKIP
        >>> doc["fingerprint"]["backlash_m"]["value"]  # doctest: +SKIP
        8e-06
    """
    return _native.fingerprint(trace, _options(locals(), "trace"))


def synth(drive: Union[Mapping[str, Any], PathLike, None] = None, *, rotary: bool = False, preset: Optional[str] = None,
          seed: Optional[int] = None, injection: Optional[Tuple[float, float]] = None,
          slow_passes: bool = _SYNTH["slow_passes"], reference: Any = None, out: Optional[PathLike] = None) -> Trace:
    """The trace an NC would record for a known drive, controller and test: ``feedid synth``.

    Args:
        drive: the drive file as a dict (:func:`demo_drive` gives one to edit; sections left out keep the demo
            drive's values) or the path of a drive file (JSON or TOML); None: the demo drive (M 69.1 kg,
            B 54.2 N*s/m, F_C 742.8 N, F_B 946.2 N, v_s 5 mm/s; K_v 2 (m/min)/mm, K_p 40000 N*s/m, T_n 20 ms; 1 kHz).
        rotary: the rotary demo drive (or check that ``drive`` is rotary).
        preset: ``"sinumerik"``: record as a SINUMERIK servo trace (2 ms time base, position every 4 ms).
        seed: the sensor noise's seed (default: the drive's, or 1).
        injection: a square wave (amplitude [N], frequency [Hz]) added to the controller's output.
        slow_passes: with the slow Stribeck passes (False: the paper's feedrate ladder alone).
        reference: a reference position to follow instead of the test [m], one value per sample time.
        out: also write the trace there as CSV, in the recording's units, as the command line does.

    Returns:
        The Trace in SI units, its constants holding the drive constants (``force_constant_N_per_A``) and the true
        values (``true_mass_kg``, ...).

    Example::

        >>> drive = feedid.demo_drive()
        >>> drive["axis"]["mass_kg"] = 120.0
        >>> trace = feedid.synth(drive, slow_passes=False, seed=3)
        >>> trace.constants["true_mass_kg"], trace.roles["current"]
        (120.0, 'i')
    """
    return _native.synth(_options(locals()))


def demo_drive(rotary: bool = False) -> dict:
    """The demo drive as a drive file (every key, with its value), to edit and give to :func:`synth`: what
    ``feedid synth --print-drive`` prints. Linear: ``axis.mass_kg`` [kg], ``axis.coulomb_forward_N`` [N], ...;
    ``controller``, ``drive`` (``kt_Nm_per_A``, ``lead_mm``), ``sensors``, ``recording``, ``test``, ``seed``.

    Example::

        >>> feedid.demo_drive()["axis"]["mass_kg"], feedid.demo_drive(rotary=True)["axis"]["inertia_kgm2"]
        (69.1, 2.0)
    """
    return _native.demo_drive(rotary)


def plan(*, travel_mm: Union[Tuple[float, float], str], centers_mm: Sequence[float], axis: str = _PLAN["axis"],
         stroke_mm: float = _PLAN["stroke_mm"], feeds_mm_per_min: Union[Sequence[float], str, None] = None,
         slow_feeds_mm_per_min: Union[Sequence[float], str, None] = _PLAN["slow_feeds_mm_per_min"],
         max_pass_time_s: float = _PLAN["max_pass_time_s"], cycles: int = _PLAN["cycles"],
         acceleration_m_per_s2: float = _PLAN["acceleration_m_per_s2"], jerk_m_per_s3: Optional[float] = None,
         dwell_s: float = _PLAN["dwell_s"], sample_time_s: float = _PLAN["sample_time_s"],
         max_feed_mm_per_min: Optional[float] = None,
         positioning_feed_mm_per_min: float = _PLAN["positioning_feed_mm_per_min"], start_mm: Optional[float] = None,
         mass_kg: float = _PLAN["mass_kg"], viscous_Ns_per_m: float = _PLAN["viscous_Ns_per_m"],
         coulomb_N: float = _PLAN["coulomb_N"], breakaway_N: float = _PLAN["breakaway_N"],
         stribeck_velocity_mm_per_s: float = _PLAN["stribeck_velocity_mm_per_s"],
         force_noise_N: float = _PLAN["force_noise_N"], level_error_N: float = _PLAN["level_error_N"],
         position_resolution_um: float = _PLAN["position_resolution_um"]) -> Plan:
    """Designs the axis test and predicts what its data will identify: ``feedid plan``.

    At each centre, back-and-forth strokes at every feedrate of the ladder, the slow Stribeck passes first (strokes
    shortened to ``max_pass_time_s``); every move ends at rest with a dwell.

    Args:
        travel_mm: the travel limits (min, max) [mm] (or ``"MIN:MAX"``).
        centers_mm: centres of the strokes [mm].
        axis: the axis name as the NC knows it.
        stroke_mm: stroke of the ladder passes [mm].
        feeds_mm_per_min: ladder feedrates [mm/min]; None: the paper's 1250 ... 9350.
        slow_feeds_mm_per_min: slow passes: ``"LO:HI[:N]"`` log-spaced, feedrates [mm/min], or None for none.
        max_pass_time_s, cycles, acceleration_m_per_s2, jerk_m_per_s3, dwell_s, sample_time_s, max_feed_mm_per_min,
            positioning_feed_mm_per_min, start_mm: as ``feedid plan``'s options of those names.
        mass_kg ... position_resolution_um: the nominal drive and sensors the prediction assumes.

    Returns:
        The Plan: ``part_program(dialect)`` (``"iso"``, ``"sinumerik"``, ``"linuxcnc"``), ``reference()`` (a Trace of
        the commanded position), ``prediction``, ``to_dict()`` (``feedid plan --json``).

    Raises:
        InputError: a move that leaves the travel or exceeds ``max_feed_mm_per_min``, bad options.

    Example::

        >>> p = feedid.plan(travel_mm=(-400, 400), centers_mm=[-250, 0, 250])
        >>> p.prediction["parameters"]["mass_kg"]["identifiable"]
        True
        >>> p.part_program("linuxcnc").splitlines()[0].startswith("(")
        True
    """
    return _native.plan(_options(locals()))


def _raise_failure(outcome: Any) -> Any:
    if outcome.failure is not None:
        raise IdentificationError(outcome.failure, outcome.diagnostics, outcome)
    return outcome


def __getattr__(name: str) -> Any:
    # feedid.fleet imports Dask: only when it is used
    if name == "fleet":
        import importlib

        return importlib.import_module(".fleet", __name__)
    raise AttributeError(f"module 'feedid' has no attribute '{name}'")
