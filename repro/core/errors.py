"""Bad input is reported as one line naming the parameter and what is allowed (exit status 2); a
worker process that dies under a sweep, as one line saying so (exit status 1)."""


class UsageError(ValueError):
    """A parameter has a value the suite does not accept.

    ``str(err)`` is the whole one-line message; the CLI prints it and exits with status 2 before any
    result file is touched. It pickles as its three parts, so that a refusal raised in a worker
    process (joblib, Dask) reaches the user as the same line.
    """

    def __init__(self, param: str, allowed: str, got: object = None):
        self.param = param
        self.allowed = allowed
        self.got = got
        shown = "" if got is None else f", got {got!r}"
        super().__init__(f"{param}: must be {allowed}{shown}")

    def __reduce__(self) -> tuple:
        # the default pickles ``args`` (the message alone), which __init__ cannot take back
        return (type(self), (self.param, self.allowed, self.got))


def require(condition: bool, param: str, allowed: str, got: object = None) -> None:
    """Raise :class:`UsageError` unless ``condition`` holds."""
    if not condition:
        raise UsageError(param, allowed, got)


def refuse_unused(*options: tuple[str, object, bool, str]) -> None:
    """Refuse (UsageError naming it) each option given that the command's other choices leave
    unused, so that a command line never says more than what runs: each of ``options`` is
    (option, value (None where not given), whether it is used, when it is: "with --policy mlp")."""
    for option, value, used, when in options:
        require(value is None or used, option, f"given only {when}", value)


class WorkerDied(RuntimeError):
    """A worker process (joblib's, or a Dask cluster's) died while it ran a task: the system killed
    it (for want of memory, or a signal) or it crashed. ``str(err)`` is the whole one-line
    message; the CLI prints it and exits with status 1."""
