"""feedid.fleet: identify many trace files at once, on a Dask cluster.

A plant's recordings (thousands of files a night) are independent of each other: :func:`identify_many` maps
:func:`feedid.identify` over them with a Dask client and returns one pandas DataFrame, a row per file. The same call
runs on a laptop (a ``LocalCluster`` of worker processes, made and closed for the call when no client is given), a
workstation or a cluster::

    from dask.distributed import Client
    import feedid.fleet

    client = Client("tcp://scheduler:8786")          # an existing Dask cluster
    frame = feedid.fleet.identify_many(paths, client, force_constant="force_constant_N_per_A")

What a cluster needs: feedid importable on every worker (the same version: ``pip install --no-build-isolation .``
into the workers' environment), and the trace files at the same paths on every worker (a shared file system); only
paths travel to the workers and rows come back. Dask's workers trim their heap eagerly by default
(``MALLOC_TRIM_THRESHOLD_=65536``), which costs identify a third more CPU; start them with
``MALLOC_TRIM_THRESHOLD_=1073741824 MALLOC_MMAP_THRESHOLD_=33554432 dask worker tcp://scheduler:8786`` (the
LocalCluster made here starts its workers without the setting). Each worker runs identify's systematic family on one
thread (``threads=1`` unless the options say otherwise): the workers already keep the cores busy. A history store (``history=``) is written by the
calling process, which reads each trace file once more to hash it (so it needs the files too).

A file that fails is a row with its status and reason, never an aborted batch: ``"failed"`` when the data cannot
identify the model (IdentificationError), ``"error"`` for bad input (InputError: unreadable file, missing channel)
or anything unexpected, including a worker that died.
"""

from __future__ import annotations

import os
from typing import Any, Callable, Iterable, List, Mapping, Optional, Union

import feedid
from ._pandas import estimate_columns

__all__ = ["identify_file", "identify_many"]

Label = Union[str, Callable[[str], str], None]

#: The columns every row has, in this order, before the parameters; then the fit, the diagnostics and run_id.
LEADING_COLUMNS = ("path", "machine", "axis", "status", "reason", "model")
TRAILING_COLUMNS = ("relative_error_pct", "condition_number", "samples_used", "diagnostics")


def _label(label: Label, path: str) -> Optional[str]:
    return label(path) if callable(label) else label


def identify_file(path: Union[str, "os.PathLike[str]"], *, machine: Optional[str] = None,
                  axis: Optional[str] = None, document: bool = False, **options: Any) -> dict:
    """The row of one file: what :func:`identify_many` runs on each worker.

    Args:
        path: the trace file.
        machine: the machine's name for the row (and the history).
        axis: the axis: read from a multi-axis file as ``feedid.identify(axis=...)`` does, and its label.
        document: also return the result document under the key ``"document"`` (for the history).
        options: the options of :func:`feedid.identify`.

    Returns:
        A dict: ``path``, ``machine``, ``axis``, ``status`` (``"ok"``, ``"partial"``, ``"failed"``, ``"error"``),
        ``reason`` (None when identified), ``model``, for each parameter ``KEY`` (its value [SI]) and ``KEY_stderr``
        (NaN where None), ``relative_error_pct``, ``condition_number``, ``samples_used`` (step 1's batch fit) and
        ``diagnostics`` (one per line).

    Example::

        >>> row = feedid.fleet.identify_file(EMPS, channels={"position": "qm", "current": "vir"},
        ...                                  force_constant="gtau", offset=True)
        >>> row["status"], round(row["mass_kg"], 2)
        ('partial', 95.01)
    """
    path = os.fspath(path)
    row: dict = {"path": path, "machine": machine, "axis": axis, "status": "error", "reason": None, "model": None}
    result = None
    try:
        if axis is not None:
            options = dict(options, axis=axis)
        result = feedid.identify(path, **{"threads": 1, **options})
    except feedid.IdentificationError as error:
        row.update(status="failed", reason=str(error))
        result = error.result
    except feedid.InputError as error:
        row["reason"] = str(error)
    except Exception as error:  # noqa: BLE001  (a row, never an aborted batch)
        row["reason"] = f"{type(error).__name__}: {error}"
    if result is None:
        row.update({column: float("nan") for column in TRAILING_COLUMNS[:-1]})
        row["diagnostics"] = ""
        return row
    if row["status"] == "error":
        row["status"] = result.status
    row["model"] = result.model
    row.update(estimate_columns({key: estimate.to_dict() for key, estimate in result.parameters.items()}))
    fit = result.step1
    row["relative_error_pct"] = fit.relative_error_pct if fit is not None else float("nan")
    row["condition_number"] = fit.condition_number if fit is not None else float("nan")
    row["samples_used"] = fit.samples_used if fit is not None else float("nan")
    row["diagnostics"] = "\n".join(result.diagnostics)
    if document:
        row["document"] = result.to_dict()
    return row


def identify_many(paths: Iterable[Union[str, "os.PathLike[str]"]], client: Any = None, *, machine: Label = None,
                  axis: Label = None, history: Union[str, "os.PathLike[str]", None] = None,
                  workers: Optional[int] = None, **options: Any) -> "pandas.DataFrame":  # noqa: F821
    """Identifies every file with Dask and returns one row per file, in the order of ``paths``.

    Args:
        paths: the trace files.
        client: a ``dask.distributed.Client``; None: a ``LocalCluster`` of ``workers`` processes (default: one per
            core, one thread each) is started for the call and closed after it.
        machine: the machines' name, the same for every file (a str) or per file (a function of the path).
        axis: the axis, likewise; it is read from multi-axis files as ``feedid.identify(axis=...)`` does.
        history: a history store (:class:`feedid.History`'s file) to record each identified run in (not the failed
            ones), as ``feedid identify --record`` does; needs ``machine`` and ``axis``.
        workers: the size of the LocalCluster made when no client is given.
        options: the options of :func:`feedid.identify` (``force_constant=``, ``channels=``, ``model=``, ...).

    Returns:
        A pandas DataFrame, a row per file as :func:`identify_file` makes it, and with ``history`` a column
        ``run_id`` (missing, ``pandas.NA``, where not recorded; then ``reason`` says why). ``samples_used`` and
        ``run_id`` are nullable integers (``Int64``).

    Raises:
        TypeError: an option :func:`feedid.identify` does not have.
        InputError: ``history`` without ``machine`` and ``axis``.

    Example::

        >>> frame = feedid.fleet.identify_many(paths, force_constant="force_constant_N_per_A")   # doctest: +SKIP
        >>> frame[["path", "status", "mass_kg", "mass_kg_stderr"]]                            # doctest: +SKIP
    """
    import inspect

    import pandas as pd

    inspect.signature(feedid.identify).bind(None, **options)  # a misspelt option fails here, not on every worker
    paths = [os.fspath(path) for path in paths]
    if history is not None and (machine is None or axis is None):
        raise feedid.InputError("identify_many: recording in a history needs machine= and axis= (names, or "
                                "functions of the path)")
    machines = [_label(machine, path) for path in paths]
    axes = [_label(axis, path) for path in paths]
    rows = _run(paths, machines, axes, client, workers, history is not None, options)
    if history is not None:
        _record(rows, history)
    frame = pd.DataFrame(rows)
    parameters = [c for c in frame.columns if c not in LEADING_COLUMNS + TRAILING_COLUMNS + ("run_id", "document")]
    ordered = list(LEADING_COLUMNS) + parameters + list(TRAILING_COLUMNS)
    if history is not None:
        ordered.append("run_id")
    frame = frame.reindex(columns=ordered)
    for column in ("samples_used", "run_id"):  # whole numbers, missing where there is none
        if column in frame.columns:
            frame[column] = frame[column].astype("Int64")
    return frame


def _run(paths: List[str], machines: List[Optional[str]], axes: List[Optional[str]], client: Any,
         workers: Optional[int], documents: bool, options: Mapping[str, Any]) -> List[dict]:
    if not paths:
        return []
    cluster = None
    if client is None:
        client, cluster = _local_cluster(workers or os.cpu_count() or 1)
    try:
        futures = client.map(_identify_on_worker, paths, machines, axes, pure=False, documents=documents,
                             options=dict(options))
        rows = []
        for path, machine_name, axis_name, future in zip(paths, machines, axes, futures):
            try:
                rows.append(future.result())
            except Exception as error:  # noqa: BLE001  (a worker that died: a row, not an aborted batch)
                rows.append({"path": path, "machine": machine_name, "axis": axis_name, "status": "error",
                             "reason": f"{type(error).__name__}: {error}"})
        return rows
    finally:
        if cluster is not None:
            client.close()
            cluster.close()


def _local_cluster(workers: int):
    """A LocalCluster of worker processes, one thread each, and its client.

    Dask's nanny starts its workers with MALLOC_TRIM_THRESHOLD_=65536, so that they hand memory back to the system
    quickly; that also turns off glibc's adaptive mmap threshold, and then every column identify allocates (a few
    hundred kB and up) is a fresh mapping whose pages fault in: a third more CPU per file (40 demo traces: 2.7 s
    against 2.0 s). These workers live for one batch; they start without it."""
    import dask
    from dask.distributed import Client, LocalCluster

    environment = dict(dask.config.get("distributed.nanny.pre-spawn-environ", default={}))
    environment.pop("MALLOC_TRIM_THRESHOLD_", None)
    with dask.config.set({"distributed.nanny.pre-spawn-environ": environment}):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0")
    return Client(cluster), cluster


def _identify_on_worker(path: str, machine: Optional[str], axis: Optional[str], *, documents: bool,
                        options: Mapping[str, Any]) -> dict:
    return identify_file(path, machine=machine, axis=axis, document=documents, **options)


def _record(rows: List[dict], history: Union[str, "os.PathLike[str]"]) -> None:
    with feedid.History(history) as store:
        for row in rows:
            document = row.pop("document", None)
            row["run_id"] = None
            if document is None or row["status"] not in ("ok", "partial"):
                continue
            try:
                row["run_id"], _ = store.record(document, machine=row["machine"], axis=row["axis"],
                                                trace=row["path"])
            except feedid.InputError as error:
                row["reason"] = f"not recorded: {error}"
