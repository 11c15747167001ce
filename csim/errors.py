"""Exceptions that csim turns into clear messages (never tracebacks) at the CLI."""
from __future__ import annotations


class CsimError(Exception):
    """Base class of csim's expected errors."""


class CaseError(CsimError):
    """A case file (or a ``--set`` override) is invalid.

    Parameters
    ----------
    problems : list of str
        One line per problem, each naming the key path, the value and what was expected.
    """

    def __init__(self, problems: list[str]):
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


class ManifestError(CaseError):
    """A batch manifest (``csim batch``) is invalid: its keys, its expectations, or the case
    of one of its entries. ``problems`` as for :class:`CaseError`."""


class SimulationFailure(CsimError):
    """The simulation cannot go on (Newton did not converge, singular matrix, blow-up).

    Parameters
    ----------
    message : str
        What went wrong, for the user.
    kind : str, optional
        What kind of failure it is (:data:`csim.result.FAILURES`, e.g. ``"singular"``), carried
        into the result's ``failure``; ``""``: not known where it was raised (the result then
        reads it from the message, :func:`csim.result.failure_kind`).
    """

    def __init__(self, message: str, kind: str = ""):
        super().__init__(message)
        self.kind = kind


class CacheError(CsimError):
    """A cached file disagrees with what it was built from (it is removed: the next run builds it again)."""


class ResultFileError(CsimError):
    """A result file is missing, unreadable or not a csim result."""


class PartitionBreakdown(SimulationFailure):
    """The dependent coordinates cannot be solved with the current coordinate partition.

    Raised inside a right-hand-side evaluation of the minimal-coordinate method; the driver
    answers by choosing the partition again at the last accepted state and restarting.
    """
