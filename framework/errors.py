"""The one error type for bad input: it names the file, the key and the problem."""


class InputError(ValueError):
    """Bad user input. `str(err)` is the one line the CLI prints before exiting with status 2."""

    def __init__(self, file, key, problem):
        self.file, self.key, self.problem = str(file), str(key), str(problem)
        super().__init__(f"{self.file}: {self.key}: {self.problem}")
