"""The one exception type that user-facing code raises for bad input."""

from __future__ import annotations

from os import PathLike


class InputError(ValueError):
    """Bad input from a user: a file, an option or a value that cannot be used.

    The message is one line that names the source (usually a file path) and the problem,
    so the command line can print it as it is and exit with code 2.

    Parameters
    ----------
    source
        What the problem is in: a file path, an option name, or ``None``.
    problem
        What is wrong, in a few words.
    """

    def __init__(self, source: str | PathLike[str] | None, problem: str) -> None:
        self.source = None if source is None else str(source)
        self.problem = problem
        text = problem if self.source is None else f"{self.source}: {problem}"
        super().__init__(" ".join(text.split()))

    def __reduce__(self) -> tuple[type[InputError], tuple[str | None, str]]:
        """Pickle as an `InputError` of its source and problem (a worker process raises it)."""
        return InputError, (self.source, self.problem)
