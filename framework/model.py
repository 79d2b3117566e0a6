"""The plugin interface every collision model implements."""
from __future__ import annotations

import abc

from .outcome import Outcome
from .scene import Scene


class CollisionModel(abc.ABC):
    """A collision model knows physics only: it takes a Scene and returns an Outcome.

    The constructor takes only the model's options (the keys of its config table), as in scikit-learn.
    `simulate` never raises for a physically failed run: it returns an Outcome with outcome_ok False.
    """

    name: str = ""

    def __init__(self, **options):
        if options:
            raise TypeError(f"model {self.name!r} takes no option {', '.join(sorted(options))}")

    @abc.abstractmethod
    def simulate(self, scene: Scene) -> Outcome:
        ...

    def simulate_batch(self, scenes: list[Scene]) -> list[Outcome]:
        """Simulate many scenes; models override this to vectorise or parallelise."""
        return [self.simulate(s) for s in scenes]

    def get_options(self) -> dict:
        return {}
