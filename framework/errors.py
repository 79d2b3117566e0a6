"""The one error type for bad input: it names the file, the key and the problem."""


def _one_line(text) -> str:
    """Line breaks and other control characters (from a key or value in the file) shown escaped."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))


# exit status of the command line: 2 bad input (InputError), 3 a simulation failed, 4 a search or posterior
# that finished without a feasible solution (no candidate explains the evidence)
EXIT_INPUT, EXIT_FAILED, EXIT_NO_FEASIBLE = 2, 3, 4


class InputError(ValueError):
    """Bad user input. `str(err)` is the one line the CLI prints before exiting with status 2."""

    def __init__(self, file, key, problem):
        self.file, self.key, self.problem = _one_line(file), _one_line(key), _one_line(problem)
        super().__init__(f"{self.file}: {self.key}: {self.problem}")
