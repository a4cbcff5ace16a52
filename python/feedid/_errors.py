"""feedid's exceptions. Their messages are the lines `feedid` on the command line prints (without ``feedid: ``)."""

from __future__ import annotations

from typing import Any, Iterable, Optional


class InputError(ValueError):
    """Bad input: a malformed file, an unknown unit or role, a missing channel, an invalid option.

    The message is one sentence naming the file, line, channel or option, as the command line prints it before it
    exits with code 2.

    Example::

        >>> import feedid
        >>> try:
        ...     feedid.identify("no-such-file.csv", force_constant=1.0)
        ... except feedid.InputError as error:
        ...     print(error)
        no-such-file.csv: no such file
    """


class IdentificationError(RuntimeError):
    """The analysis failed on valid input: the data cannot identify the model, the controller's fit is too poor to
    trust, the simulation diverged.

    ``str(error)`` is what the command line prints before it exits with code 1 (one line per diagnostic, most often
    one); ``diagnostics`` lists every diagnostic and ``result`` holds the failed result (a Result, Gains or
    Simulation; None where there is none, e.g. too few samples for the controller's gains).

    Example::

        >>> import numpy as np, feedid
        >>> t = np.arange(0, 1, 0.001)
        >>> standing = feedid.Trace.from_arrays(time=t, position=np.zeros_like(t), current=np.zeros_like(t))
        >>> try:
        ...     feedid.identify(standing, force_constant=100.0)
        ... except feedid.IdentificationError as error:
        ...     print(error)
        ...     print(error.result.status)
        trace: the position never changes in the analysis window: the axis did not move, so nothing can be identified
        failed
    """

    def __init__(self, message: str, diagnostics: Optional[Iterable[str]] = None, result: Any = None) -> None:
        super().__init__(message)
        self.diagnostics = list(diagnostics) if diagnostics is not None else [message]
        self.result = result

    def __reduce__(self):  # pickled across processes (Dask) with its diagnostics
        return (type(self), (str(self), self.diagnostics, None))
