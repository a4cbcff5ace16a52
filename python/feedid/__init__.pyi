# Type stub of the feedid package: the API of python/feedid/__init__.py and of the native module it wraps
# (python/src). Units are SI (m, s, kg, N, A; rad, kg*m^2, N*m on rotary axes) unless a name says otherwise.
import os
from typing import Any, Dict, List, Literal, Mapping, Optional, Sequence, Tuple, Union, overload

import numpy
import numpy.typing
import pandas

from . import fleet as fleet

__version__: str
ROLES: Tuple[str, ...]

PathLike = Union[str, os.PathLike[str]]
ArrayLike = numpy.typing.ArrayLike
FloatArray = numpy.ndarray  # float64, 1-D unless said otherwise

class InputError(ValueError):
    """Bad input; the message is the command line's (exit 2)."""

class IdentificationError(RuntimeError):
    """A failed analysis; the message is the command line's lines (exit 1)."""

    diagnostics: List[str]
    result: Union[Result, Gains, Simulation, None]
    def __init__(self, message: str, diagnostics: Optional[Sequence[str]] = ..., result: Any = ...) -> None: ...

class Estimate:
    """A value with its standard error [SI unit of its key]; None where the data cannot tell."""

    _fields: Tuple[str, ...]
    value: Optional[float]
    standard_error: Optional[float]
    systematic: Optional[float]
    uncertainty: Optional[float]
    def __init__(self, value: Optional[float] = ..., standard_error: Optional[float] = ...,
                 **fields: Optional[float]) -> None: ...
    @property
    def determined(self) -> bool: ...
    def to_dict(self) -> Dict[str, Optional[float]]: ...
    def __eq__(self, other: object) -> bool: ...

class Trace:
    """A recording in SI units; channels are read-only float64 views of the trace's own columns."""

    @property
    def path(self) -> str: ...
    @property
    def format(self) -> str: ...
    @property
    def samples(self) -> int: ...
    @property
    def rotary(self) -> bool: ...
    @property
    def findings(self) -> List[str]: ...
    @property
    def constants(self) -> Dict[str, float]: ...
    @property
    def sample_time_s(self) -> float: ...
    @property
    def duration_s(self) -> float: ...
    @property
    def channel_names(self) -> List[str]: ...
    @property
    def roles(self) -> Dict[str, str]: ...
    @property
    def units(self) -> Dict[str, str]: ...
    @property
    def source_units(self) -> Dict[str, str]: ...
    @property
    def native_intervals_s(self) -> Dict[str, Optional[float]]: ...
    def __len__(self) -> int: ...
    def __getitem__(self, name: str) -> FloatArray: ...
    def __contains__(self, name: str) -> bool: ...
    def role(self, role: str) -> FloatArray: ...
    def to_csv(self, path: PathLike) -> None: ...
    def to_pandas(self) -> pandas.DataFrame: ...
    @staticmethod
    def from_arrays(time: Optional[ArrayLike] = ..., position: Optional[ArrayLike] = ...,
                    current: Optional[ArrayLike] = ..., *, reference_position: Optional[ArrayLike] = ...,
                    velocity: Optional[ArrayLike] = ..., velocity_command: Optional[ArrayLike] = ...,
                    force: Optional[ArrayLike] = ..., external_force: Optional[ArrayLike] = ...,
                    injection: Optional[ArrayLike] = ..., units: Optional[Mapping[str, str]] = ...,
                    constants: Optional[Mapping[str, float]] = ..., path: str = ...,
                    sample_time_s: Optional[float] = ..., lead_mm: Optional[float] = ...,
                    gear_ratio: Optional[float] = ..., rated: Optional[str] = ...) -> Trace: ...
    @staticmethod
    def from_pandas(frame: pandas.DataFrame, channels: Optional[Mapping[str, str]] = ...,
                    units: Optional[Mapping[str, str]] = ..., *, constants: Optional[Mapping[str, float]] = ...,
                    path: str = ..., axis: Optional[str] = ..., sample_time_s: Optional[float] = ...,
                    lead_mm: Optional[float] = ..., gear_ratio: Optional[float] = ...,
                    rated: Optional[str] = ...) -> Trace: ...

TraceArgument = Union[Trace, str, os.PathLike[str]]

def read_trace(path: PathLike, channels: Optional[Mapping[str, str]] = ..., units: Optional[Mapping[str, str]] = ...,
               *, axis: Optional[str] = ..., format: Optional[str] = ..., sample_time_s: Optional[float] = ...,
               skip_rows: Optional[int] = ..., lead_mm: Optional[float] = ..., gear_ratio: Optional[float] = ...,
               rated: Optional[str] = ..., join: Optional[str] = ..., join_max_shift_s: Optional[float] = ...,
               tare: Optional[Sequence[str]] = ..., invert: Optional[Sequence[str]] = ...) -> Trace: ...

class TraceSummary:
    path: str
    format: str
    samples: int
    sample_time_s: float
    duration_s: float

class PreprocessReport:
    differentiation: str
    filter_order: int
    cutoff_hz: float
    decimation: int
    edge_samples: int
    velocity_source: str
    savitzky_golay_window: int
    savitzky_golay_order: int

class SelectionReport:
    total: int
    window: int
    moving: int
    step1: int
    step2: int
    passes: int
    stick_slip_passes: int
    stick_slip_samples: int
    clipped: int
    near_rest: int
    initial_split_velocity: float
    moving_threshold: float
    split_velocity: float
    notes: List[str]

class Step1Report:
    batch: Dict[str, Estimate]
    relative_error_pct: float
    condition_number: float
    samples_used: int
    residual_std: float
    r_diagonal: FloatArray
    white_noise_standard_error: Dict[str, float]
    correlation: numpy.ndarray
    keys: List[str]

class RlsReport:
    variant: str
    forgetting_factor: float
    initial_covariance: float
    final: Dict[str, float]
    averaged: Dict[str, float]
    settled: bool
    transient_end_s: float
    history_time_s: FloatArray
    history: Dict[str, FloatArray]

class LogLinearStribeck:
    breakaway: Optional[float]
    stribeck_velocity: Optional[float]
    samples_used: int
    excluded_wrong_sign: int
    excluded_below_noise: int

class NonlinearFitReport:
    method: str
    converged: bool
    relative_error_pct: float
    residual_std: float
    samples_used: int
    function_evaluations: int

class StribeckReport:
    forward: Optional[LogLinearStribeck]
    reverse: Optional[LogLinearStribeck]
    nonlinear: Optional[NonlinearFitReport]

class FrictionCurvePoints:
    speed: FloatArray
    force: FloatArray
    fitted: FloatArray

class FrictionCurveReport:
    forward: Optional[FrictionCurvePoints]
    reverse: Optional[FrictionCurvePoints]

class SystematicVariant:
    label: str
    status: str
    parameters: Dict[str, Optional[float]]

class SystematicReport:
    variants: List[SystematicVariant]

class FrictionOnlyReport:
    reason: str
    samples_used: int
    relative_error_pct: float
    residual_std: float
    rejected_samples: int

class Result:
    """An identification: parameters with standard errors, the stages' records, the result document."""

    status: Literal["ok", "partial", "failed"]
    model: Literal["symmetric", "asymmetric"]
    offset: bool
    rotary: bool
    feedid_version: str
    diagnostics: List[str]
    trace: TraceSummary
    parameters: Dict[str, Estimate]
    units: Dict[str, str]
    symbols: Dict[str, str]
    preprocessing: Optional[PreprocessReport]
    selection: Optional[SelectionReport]
    step1: Optional[Step1Report]
    rls: Optional[RlsReport]
    stribeck: Optional[StribeckReport]
    friction_curve: Optional[FrictionCurveReport]
    friction_only: Optional[FrictionOnlyReport]
    systematic: Optional[SystematicReport]
    options: Dict[str, Any]
    failure: Optional[str]
    def to_dict(self) -> Dict[str, Any]: ...
    def to_json(self, indent: int = ...) -> str: ...
    def to_pandas(self) -> pandas.DataFrame: ...
    @staticmethod
    def from_dict(document: Mapping[str, Any]) -> Result: ...

def identify(trace: TraceArgument, *, model: Optional[Literal["auto", "symmetric", "asymmetric"]] = ...,
             offset: Optional[bool] = ..., delay: Union[Literal["auto", "none"], float, None] = ...,
             stribeck: bool = ..., force_constant: Union[float, str, None] = ..., kt_Nm_per_A: Optional[float] = ...,
             lead_mm: Optional[float] = ..., gear_ratio: float = ...,
             differentiation: Literal["butterworth", "central", "savitzky-golay"] = ...,
             velocity_source: Literal["auto", "position", "velocity"] = ..., filter_order: int = ...,
             cutoff_hz: Optional[float] = ..., savitzky_golay_window: Optional[int] = ...,
             savitzky_golay_order: int = ..., decimation: Optional[int] = ..., edge_samples: Optional[int] = ...,
             from_s: Optional[float] = ..., to_s: Optional[float] = ..., split_velocity: Optional[float] = ...,
             moving_threshold: Optional[float] = ..., rls: Literal["directional", "paper"] = ...,
             forgetting_factor: float = ..., initial_covariance: float = ...,
             channels: Optional[Mapping[str, str]] = ..., units: Optional[Mapping[str, str]] = ...,
             axis: Optional[str] = ..., format: Optional[str] = ..., sample_time_s: Optional[float] = ...,
             skip_rows: Optional[int] = ..., rated: Optional[str] = ..., join: Optional[str] = ...,
             join_max_shift_s: Optional[float] = ..., tare: Optional[Sequence[str]] = ...,
             invert: Optional[Sequence[str]] = ..., systematic: bool = ..., threads: int = ...) -> Result: ...

class Gains:
    """Identified controller gains (K_v [1/s], K_p [N*s/m or N*m*s/rad], K_i [N/m or N*m/rad])."""

    status: Literal["ok", "failed"]
    position_gain_per_s: Estimate
    velocity_gain: Estimate
    velocity_integral_gain: Estimate
    velocity_feedforward: Estimate
    reset_time_s: Estimate
    method: str
    velocity_difference_samples: int
    reference_delay_samples: int
    drive_delay_samples: int
    current_lag_s: float
    setpoint_delay_s: Estimate
    relative_error_pct: float
    systematic_error_pct: float
    samples_used: int
    injection_subtracted: bool
    diagnostics: List[str]
    failure: Optional[str]
    def to_dict(self) -> Dict[str, Any]: ...

def gains(trace: TraceArgument, *, force_constant: Union[float, str, None] = ..., kt_Nm_per_A: Optional[float] = ...,
          lead_mm: Optional[float] = ..., gear_ratio: float = ..., velocity_loop: Literal["auto", "p", "pi"] = ...,
          feedforward: bool = ..., velocity_difference: Optional[int] = ..., current_lag_ms: Optional[float] = ...,
          saturation: Optional[float] = ..., forgetting: float = ..., channels: Optional[Mapping[str, str]] = ...,
          units: Optional[Mapping[str, str]] = ..., axis: Optional[str] = ..., format: Optional[str] = ...,
          sample_time_s: Optional[float] = ..., skip_rows: Optional[int] = ..., rated: Optional[str] = ...,
          join: Optional[str] = ..., join_max_shift_s: Optional[float] = ...,
          tare: Optional[Sequence[str]] = ..., invert: Optional[Sequence[str]] = ...) -> Gains: ...

class ValidationMetrics:
    position_relative_error_pct: float
    velocity_relative_error_pct: float
    acceleration_relative_error_pct: float
    force_relative_error_pct: float
    tracking_error_mae_model: float
    tracking_error_mae_machine: float
    modelling_error_mae: float
    tracking_error_max_model: float
    tracking_error_max_machine: float
    modelling_error_max: float

class Simulation:
    status: Literal["ok", "failed"]
    metrics: ValidationMetrics
    injected: bool
    diagnostics: List[str]
    failure: Optional[str]
    signals: Dict[str, FloatArray]
    def to_dict(self) -> Dict[str, Any]: ...
    def to_pandas(self) -> pandas.DataFrame: ...

def simulate(trace: TraceArgument, result: Union[Result, Mapping[str, Any], PathLike],
             gains: Union[Gains, Mapping[str, Any], PathLike, None] = ..., *,
             force_constant: Union[float, str, None] = ..., kt_Nm_per_A: Optional[float] = ...,
             lead_mm: Optional[float] = ..., gear_ratio: float = ..., velocity_loop: Literal["auto", "p", "pi"] = ...,
             feedforward: bool = ..., velocity_difference: Optional[int] = ..., current_lag_ms: Optional[float] = ...,
             saturation: Optional[float] = ..., forgetting: float = ..., substeps: int = ...,
             channels: Optional[Mapping[str, str]] = ..., units: Optional[Mapping[str, str]] = ...,
             axis: Optional[str] = ..., format: Optional[str] = ..., sample_time_s: Optional[float] = ...,
             skip_rows: Optional[int] = ..., rated: Optional[str] = ..., join: Optional[str] = ...,
             join_max_shift_s: Optional[float] = ..., tare: Optional[Sequence[str]] = ...,
             invert: Optional[Sequence[str]] = ...) -> Simulation: ...

def fingerprint(trace: TraceArgument, *, force_constant: Union[float, str, None] = ...,
                kt_Nm_per_A: Optional[float] = ..., lead_mm: Optional[float] = ..., gear_ratio: float = ...,
                settle_s: Optional[float] = ..., channels: Optional[Mapping[str, str]] = ...,
                units: Optional[Mapping[str, str]] = ..., axis: Optional[str] = ..., format: Optional[str] = ...,
                sample_time_s: Optional[float] = ..., skip_rows: Optional[int] = ..., rated: Optional[str] = ...,
                join: Optional[str] = ..., join_max_shift_s: Optional[float] = ...,
                tare: Optional[Sequence[str]] = ..., invert: Optional[Sequence[str]] = ...) -> dict: ...


def synth(drive: Union[Mapping[str, Any], PathLike, None] = ..., *, rotary: bool = ...,
          preset: Optional[Literal["sinumerik"]] = ..., seed: Optional[int] = ...,
          injection: Optional[Tuple[float, float]] = ..., slow_passes: bool = ..., reference: Optional[ArrayLike] = ...,
          out: Optional[PathLike] = ...) -> Trace: ...
def demo_drive(rotary: bool = ...) -> Dict[str, Any]: ...

class Plan:
    duration_s: float
    blocks: int
    notes: List[str]
    passes: List[Dict[str, Any]]
    prediction: Dict[str, Any]
    def part_program(self, dialect: Literal["iso", "sinumerik", "linuxcnc"] = ...) -> str: ...
    def reference(self) -> Trace: ...
    def to_dict(self) -> Dict[str, Any]: ...

def plan(*, travel_mm: Union[Tuple[float, float], str], centers_mm: Sequence[float], axis: str = ...,
         stroke_mm: float = ..., feeds_mm_per_min: Union[Sequence[float], str, None] = ...,
         slow_feeds_mm_per_min: Union[Sequence[float], str, None] = ..., max_pass_time_s: float = ...,
         cycles: int = ..., acceleration_m_per_s2: float = ..., jerk_m_per_s3: Optional[float] = ...,
         dwell_s: float = ..., sample_time_s: float = ..., max_feed_mm_per_min: Optional[float] = ...,
         positioning_feed_mm_per_min: float = ..., start_mm: Optional[float] = ..., mass_kg: float = ...,
         viscous_Ns_per_m: float = ..., coulomb_N: float = ..., breakaway_N: float = ...,
         stribeck_velocity_mm_per_s: float = ..., force_noise_N: float = ..., level_error_N: float = ...,
         position_resolution_um: float = ...) -> Plan: ...

class Rls:
    """Recursive least squares for 1 to 8 parameters: y = phi' theta + noise."""

    def __init__(self, n: int, forgetting_factor: float = ..., initial_covariance: float = ...,
                 variant: Literal["directional", "exponential", "paper"] = ...,
                 initial_estimate: Optional[ArrayLike] = ...) -> None: ...
    @property
    def n(self) -> int: ...
    def update(self, phi: ArrayLike, y: float) -> Literal["updated", "no_excitation", "non_finite"]: ...
    @overload
    def update_many(self, Phi: ArrayLike, Y: ArrayLike, *, history: Literal[False] = ...) -> None: ...
    @overload
    def update_many(self, Phi: ArrayLike, Y: ArrayLike, *, history: Literal[True]) -> numpy.ndarray: ...
    @property
    def estimate(self) -> FloatArray: ...
    @property
    def covariance(self) -> numpy.ndarray: ...
    @property
    def updates(self) -> int: ...
    @property
    def wound_up(self) -> bool: ...
    @property
    def forgetting_factor(self) -> float: ...
    @property
    def initial_covariance(self) -> float: ...
    @property
    def variant(self) -> Literal["directional", "exponential"]: ...
    @property
    def last_counts(self) -> Dict[str, int]: ...
    def reset(self, initial_estimate: Optional[ArrayLike] = ...) -> None: ...

class History:
    """The parameter history (one SQLite file or a postgresql:// database), as feedid history uses it."""

    def __init__(self, path: PathLike, *, read_only: bool = ...) -> None: ...
    def record(self, result: Union[Result, Mapping[str, Any], PathLike], *, machine: str, axis: str,
               trace: Optional[PathLike] = ..., location: str = ...,
               recorded_at: Optional[str] = ...) -> Tuple[int, bool]: ...
    def runs(self, *, machine: str = ..., axis: str = ..., location: str = ...) -> List[Dict[str, Any]]: ...
    def to_pandas(self, *, machine: str = ..., axis: str = ..., location: str = ...) -> pandas.DataFrame: ...
    def trends(self, *, machine: str = ..., axis: str = ..., baseline_runs: int = ..., cusum_k: float = ...,
               cusum_h: float = ..., baseline_from: Optional[int] = ...) -> List[Dict[str, Any]]: ...
    def check(self, *, machine: str = ..., axis: str = ..., baseline_runs: int = ..., cusum_k: float = ...,
              cusum_h: float = ..., baseline_from: Optional[int] = ...) -> List[str]: ...
    def pin(self, run_id: int) -> None: ...
    @property
    def schema_version(self) -> int: ...
    @property
    def path(self) -> str: ...
    @property
    def closed(self) -> bool: ...
    def close(self) -> None: ...
    def __enter__(self) -> History: ...
    def __exit__(self, *exc: Any) -> None: ...
